"""
Whether and when a run reached control: the ``control`` section of every configuration's summary.

One section with the same keys whatever ran the law (the quarter car's own supervisor, the
external controller node, each corner of the full car, built in or external), so that a matrix of
configurations (``bench/bench_configs.py``) compares like with like:

- ``first_valid_set_s``: when every identifier had published a valid set;
- ``first_normal_s``: when every law unit (the quarter car, or each corner) had commanded on a
  model; ``first_normal_t_sim`` the same in car time where the law's node reports it;
- ``failsafe_fraction``: the share of the car's time after that spent in fail-safe (the safe
  current: no valid, fresh model, or, with an external controller, no command in time);
- ``real_time_factor``: car time over recording time while the road ran;
- ``samples_lost`` and ``ride`` (live against passive at the safe current and at 0 A: the
  Wk-weighted RMS body acceleration of the quarter car, the ISO 2631-1 total value ``a_v`` of the
  full car), taken from the summary's other sections.

Times are seconds since the recording began (the recorder is the first node up) at which the
nodes' ``/diagnostics`` (one status per ``diagnostics_period_s``, 1 s by default) first said so,
by the statuses' stamps (the nodes' wall clock): their resolution is one status period. Where the
car time of the first normal step is known (the quarter car's step log, the full car's corners),
it is placed on the car's clock (its statuses' car time against their stamps) instead. A quarter
car's built-in law is judged exactly from its step log (first normal step, fail-safe fraction).
:class:`ControlWatch` is fed every decoded status by
:func:`mr_damper_bringup.report.recording.read_recording`.
"""
import math

import numpy as np

#: the summary keys of the rows a configuration matrix prints (``bench/bench_configs.py``)
CONTROL_KEYS = ('first_valid_set_s', 'first_normal_s', 'first_normal_t_sim', 'failsafe_fraction',
                'samples_lost', 'real_time_factor', 'ride')


#: car time / stamp pairs kept per car (one a second; thinned out beyond)
MAX_CLOCK_POINTS = 4096
#: receive-time spacing [s] of the car states taken as clock points (a 1 kHz topic: only one a
#: second is decoded for the clock)
STATE_CLOCK_PERIOD_S = 1.0


def _finite(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


class _Law:
    """One law unit's record: first normal status, counts then and at the end."""

    __slots__ = ('first_rx', 'first_t_sim', 'counts_first', 'counts_last', 'car_first')

    def __init__(self):
        self.first_rx = None
        self.first_t_sim = math.nan
        self.counts_first = self.counts_last = None      # (commands, normal commands)
        self.car_first = None       # the plant's (t_sim, safe-current time [s]) by then


class ControlWatch:
    """
    First times of control from the nodes' statuses, in the order the recording holds them.

    Law units: ``''`` (the quarter car of the root namespace), ``'fl'`` ... (a quarter car in a
    namespace, or a corner of the full car). Identifier units: the identifier's namespace.
    """

    def __init__(self):
        self.first_valid = {}      # identifier unit -> receive time [s] of its first valid set
        self.identifiers = set()
        self.laws = {}             # law unit -> _Law
        self.car_clock = {}        # law unit -> [(t, t_sim), ...] of its car on the road
        self.state_clock = {}      # the same from its car states (stamp: car time) at receive
        self._car_side = {}        # law unit -> (t_sim, command-timeout time [s]) of the plant
        self.built_in = set()      # law units that are a quarter car with its own law

    def _law(self, unit):
        return self.laws.setdefault(unit, _Law())

    def _normal(self, unit, t_rx, first_t_sim, counts):
        law = self._law(unit)
        normal = _finite(first_t_sim) or (counts is not None and counts[1] > 0)
        if law.first_rx is None and normal:
            law.first_rx = t_rx
            law.first_t_sim = first_t_sim if _finite(first_t_sim) else math.nan
            law.counts_first = counts
            law.car_first = self._car_side.get(unit)
        if law.first_rx is not None:
            law.counts_last = counts

    def _clock(self, unit, t_rx, t_sim, clock=None):
        if _finite(t_sim) and t_sim > 0:
            points = (self.car_clock if clock is None else clock).setdefault(unit, [])
            # a restarted car's road starts at 0 again: the clock goes on past the old one only
            if not points or t_sim > points[-1][1]:
                points.append((t_rx, float(t_sim)))
                if len(points) > MAX_CLOCK_POINTS:      # one a second: thin out a long run
                    del points[1:-1:2]

    def wants_car_state(self, unit, t_rx):
        """Whether a car state of ``unit`` received at ``t_rx`` [s] is due as a clock point."""
        points = self.state_clock.get(unit)
        return not points or t_rx - points[-1][0] >= STATE_CLOCK_PERIOD_S

    def car_state(self, unit, t_rx, t_sim):
        """
        Take one car state of ``unit``: its stamp ``t_sim`` (car time [s]) received at ``t_rx``.

        The car's clock from its states is used where the recording holds fewer than two of the
        car's statuses on the road (seen on a loaded machine: a 6 s run's recording had every
        state of the car and none of its statuses, which the launcher's monitor got).
        """
        self._clock(unit, t_rx, t_sim, self.state_clock)

    def _points(self, unit):
        """Return the car's clock points: from its statuses, else (fewer than two) its states."""
        points = self.car_clock.get(unit) or []
        if len(points) >= 2 and points[-1][0] > points[0][0]:
            return points
        return self.state_clock.get(unit) or points

    def update(self, statuses, t_rx):
        """
        Take the statuses of one ``/diagnostics`` message.

        Parameters
        ----------
        statuses : dict
            Node short name (``'quarter_car'``, ``'fl/identifier'``, ...) -> status dict
            (:func:`mr_damper_bringup.topics.decode_status`).
        t_rx : float
            Time of the message [s]: its stamp (the sending node's wall clock) or its receive
            time, a clock shared by the whole recording.

        """
        for node, d in statuses.items():
            ns, _, short = node.rpartition('/')
            if short == 'identifier':
                self.identifiers.add(ns)
                if (d.get('windows_valid') or 0) > 0:
                    self.first_valid.setdefault(ns, t_rx)
            elif short == 'quarter_car':
                self._clock(ns, t_rx, d.get('t_sim'))
                if d.get('controller') == 'external':
                    self._car_side[ns] = (d.get('t_sim'), d.get('failsafe_s'))
                else:
                    self.built_in.add(ns)
                    self._normal(ns, t_rx, d.get('first_normal_t_sim'), None)
            elif short == 'controller':
                self._normal(ns, t_rx, math.nan,
                             (d.get('commands') or 0, d.get('commands_normal') or 0))
            elif short == 'full_car_node':
                self._full_car(d, t_rx)

    def _full_car(self, d, t_rx):
        # each corner a law unit on the car's clock; with an external controller the car's
        # corners carry the modes of the commands it applied (normal_steps, first normal step)
        corners = d.get('corners') or {}
        for c, cd in corners.items():
            self._clock(c, t_rx, d.get('t_sim'))
            self._normal(c, t_rx, cd.get('first_normal_t_sim'),
                         (d.get('steps') or 0, cd.get('normal_steps') or 0))

    # ------------------------------------------------------------------ figures
    def real_time_factor(self, unit=None):
        """Car time over wall time between the car's first and last status on the road."""
        for key in sorted(set(self.car_clock) | set(self.state_clock)):
            points = self._points(key)
            (rx0, t0), (rx1, t1) = points[0], points[-1]
            if (unit is None or key == unit) and rx1 > rx0:
                return (t1 - t0) / (rx1 - rx0)
        return None

    def law_first_t_sim(self, unit):
        """
        Car time [s] of ``unit``'s first step on a model, or None (never).

        The law's own report where it has one; else (an external quarter-car controller) the
        car's time at its first normal status, on the car's clock (to one status period).
        """
        law = self.laws.get(unit)
        if law is None or law.first_rx is None:
            return None
        if _finite(law.first_t_sim):
            return law.first_t_sim
        points = self._points(unit)
        if not points:
            return None
        return float(np.interp(law.first_rx, [p[0] for p in points], [p[1] for p in points]))

    def wall_at(self, unit, t_sim):
        """
        Return when [s, the statuses' clock] ``unit``'s car reached car time ``t_sim``, or None.

        Interpolated between the car's statuses (car time and stamp); past the last one,
        extrapolated at the real-time factor (a recorder that fell behind may lack the last
        statuses of a run): the car's own, or, when its statuses are too few for one (a single
        status recorded on a loaded machine), the run's (every car of a run runs at one rate).
        """
        points = self._points(unit)
        if not points or not _finite(t_sim):
            return None
        rx = np.array([p[0] for p in points])
        ts = np.array([p[1] for p in points])
        if t_sim <= ts[-1]:
            return float(np.interp(t_sim, ts, rx))
        rtf = self.real_time_factor(unit) or self.real_time_factor()
        return None if not rtf else float(rx[-1] + (t_sim - ts[-1]) / rtf)

    def unit_failsafe_fraction(self, unit):
        """
        Share of car time in fail-safe after ``unit``'s first normal status, or None.

        The law's commands on a model against all its commands since then, times the share of
        car time the plant had a fresh command (an external controller's plant drives on the
        safe current after a command timeout), from the plant's last status before the law's
        first normal one to its last.
        """
        law = self.laws.get(unit)
        if law is None or law.first_rx is None or law.counts_first is None:
            return None
        (c0, n0), (c1, n1) = law.counts_first, law.counts_last
        if c1 <= c0:
            return None
        normal = (n1 - n0) / (c1 - c0)
        car_last = self._car_side.get(unit)
        if law.car_first is not None and car_last is not None:
            (t0, s0), (t1, s1) = law.car_first, car_last
            if _finite(t0) and _finite(t1) and t1 > t0 and _finite(s0) and _finite(s1):
                # the plant drove on the safe current without a fresh command this share
                normal *= max(0.0, 1.0 - (s1 - s0) / (t1 - t0))
        return 1.0 - normal


def quarter_car_log_figures(log):
    """
    Return ``(first normal step [s, car time], fail-safe fraction after it)`` from the car's log.

    The log's ``mode`` column (1 normal, 0 fail-safe) of every control step; (None, None)
    when the car never commanded on a model.
    """
    from mr_damper_bringup.report import recording
    first, n_after, n_safe = None, 0, 0
    for c in log.chunks(recording.CHUNK_ROWS, ('t', 'mode')):
        normal = c['mode'] > 0.5
        if first is None:
            if not normal.any():
                continue
            k = int(np.argmax(normal))
            first = float(c['t'][k])
            normal = normal[k:]
        n_after += normal.size
        n_safe += int(np.count_nonzero(~normal))
    if first is None:
        return None, None
    return first, n_safe / n_after


def control_summary(watch, start_epoch_s, summary, *, logs=None):
    """
    Return the ``control`` section (module docstring) of a run's summary.

    Parameters
    ----------
    watch : ControlWatch
        Fed with the recording's statuses (receive epoch times [s]).
    start_epoch_s : float or None
        Receive time of the recording's first message [s].
    summary : dict
        The summary so far: ``messages_lost`` and ``ride`` (a quarter car), or ``corners`` and
        ``full_car`` (car corners, the full car).
    logs : dict or None
        Law unit (``''`` the root namespace's quarter car, ``'fl'`` ...) -> that quarter car's
        step log (``mode``, ``t``): a built-in law is judged exactly from it.

    Returns
    -------
    dict
        ``first_valid_set_s``, ``first_normal_s``, ``first_normal_t_sim``,
        ``failsafe_fraction``, ``samples_lost``, ``real_time_factor``, ``ride`` and ``units``
        (per law unit: ``first_normal_s``, ``first_normal_t_sim``, ``failsafe_fraction``;
        per identifier: ``first_valid_set_s``); None where a run never got there.

    """
    start = start_epoch_s if start_epoch_s is not None else 0.0

    def since(t):
        return None if t is None else float(t - start)

    units = {}
    for unit in sorted(watch.identifiers):
        units.setdefault(unit or 'car', {})['first_valid_set_s'] = since(
            watch.first_valid.get(unit))
    for unit, law in sorted(watch.laws.items()):
        u = units.setdefault(unit or 'car', {})
        u.update(first_normal_s=since(law.first_rx),
                 first_normal_t_sim=watch.law_first_t_sim(unit),
                 failsafe_fraction=watch.unit_failsafe_fraction(unit))
    unheard = []
    for unit, log in (logs or {}).items():
        # the log's mode is the law's only where the car runs it (with an external controller
        # it says whether commands came). A car of which the recording holds no status at all
        # (its /diagnostics writer matched late or never on a loaded machine, while the
        # launcher's monitor got its statuses): its log is all there is of its control
        if log is not None and log.rows > 1 and (unit in watch.built_in
                                                 or unit not in watch.laws):
            first, fraction = quarter_car_log_figures(log)
            units.setdefault(unit or 'car', {}).update(
                first_normal_t_sim=first, failsafe_fraction=fraction)
            if unit not in watch.laws:
                unheard.append(unit)
                units[unit or 'car'].setdefault('first_normal_s', None)
    for unit in [*watch.laws, *unheard]:
        # the car time of the first normal step, where known, on the car's clock (its statuses,
        # or its states): exact, and also when the recording lacks the statuses after it
        u = units[unit or 'car']
        at = watch.wall_at(unit, u.get('first_normal_t_sim'))
        if at is not None:
            u['first_normal_s'] = since(at)

    def last(key, group):
        values = [u.get(key) for u in units.values() if key in u]
        if not values or any(v is None for v in values):
            return None
        return max(values) if group == 'max' else float(np.mean(values))

    return {'first_valid_set_s': last('first_valid_set_s', 'max'),
            'first_normal_s': last('first_normal_s', 'max'),
            'first_normal_t_sim': last('first_normal_t_sim', 'max'),
            'failsafe_fraction': last('failsafe_fraction', 'mean'),
            'samples_lost': _samples_lost(summary),
            'real_time_factor': watch.real_time_factor(),
            'ride': _ride(summary), 'units': units,
            'note': 'times: seconds since the recording began, at the resolution of the '
                    'nodes\' statuses (diagnostics_period_s)'}


def _samples_lost(summary):
    if summary.get('corners'):
        lost = [d.get('samples_lost') for d in summary['corners'].values()]
        return None if any(v is None for v in lost) else int(sum(lost))
    return summary.get('messages_lost')


def _ride(summary):
    """Live against passive at the safe current and at 0 A (Wk or a_v), or None."""
    full = summary.get('full_car')
    if full is not None:
        def a_v(key):
            return (full.get(key) or {}).get('a_v')
        return {'metric': 'a_v', 'live': a_v('live'), 'passive': a_v('passive'),
                'passive_0a': a_v('passive_0a'), 'window_s': full.get('window_s'),
                'passive_current_a': full.get('passive_current_a')}
    ride = summary.get('ride') or {}
    if not ride.get('skyhook'):
        return None

    def wk(key):
        return (ride.get(key) or {}).get('rms_body_accel_wk')
    return {'metric': 'wk', 'live': wk('skyhook'), 'passive': wk('passive'),
            'passive_0a': wk('passive_0a'), 'window_s': ride.get('window_s'),
            'passive_current_a': ride.get('passive_current_a')}


def format_control(c):
    """Return the one line of the printed summary on reaching control."""
    def sec(x):
        return 'never' if x is None else f'{x:.1f} s'
    ride = c.get('ride') or {}
    line = (f'control: first valid set {sec(c.get("first_valid_set_s"))}, first normal step '
            f'{sec(c.get("first_normal_s"))} (recording time), fail-safe after it '
            + ('-' if c.get('failsafe_fraction') is None
               else f'{100 * c["failsafe_fraction"]:.1f} %')
            + f', samples lost {c.get("samples_lost")}, real-time factor '
            + ('-' if c.get('real_time_factor') is None else f'{c["real_time_factor"]:.3f}'))
    if ride.get('live') is not None and ride.get('passive') is not None:
        line += (f'; {ride["metric"]} live {ride["live"]:.4f} vs passive '
                 f'{ride["passive"]:.4f} at {ride.get("passive_current_a")} A')
        if ride.get('passive_0a') is not None:
            line += f', {ride["passive_0a"]:.4f} at 0 A'
    return line


def control_from_recording(out, summary, corners=()):
    """
    Return the ``control`` section of a run with car corners or the full car (the launcher's).

    Reads the statuses of the run's recording (``OUT/suite.mcap`` and its parts) and each
    corner's quarter-car log (``quarter_car_log_<corner>``) where there is one.
    """
    from pathlib import Path
    import tempfile

    from mr_damper_bringup.recorder import recording_parts
    from mr_damper_bringup.report.recording import read_recording, RECORDING
    from mr_damper_common.recording.columnlog import ColumnReader, exists
    out = Path(out)
    parts = [f for _, f in recording_parts(out / RECORDING)]
    with tempfile.TemporaryDirectory(prefix='.control_', dir=out) as work:
        rec = read_recording(parts, work, clock_corners=corners)
    logs = {c: ColumnReader(out / f'quarter_car_log_{c}') for c in corners
            if exists(out / f'quarter_car_log_{c}')}
    return control_summary(rec['control'], rec.get('start_epoch_s'), summary, logs=logs)
