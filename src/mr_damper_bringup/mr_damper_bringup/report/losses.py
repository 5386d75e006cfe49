"""Messages lost in a run, node restarts and what they cost, the CAN link."""
import numpy as np

from mr_damper_bringup.report import recording
from mr_damper_bringup.report.recording import _first, _received_between
from mr_damper_common.recording.columnlog import open_log


def messages_summary(rec, qc_status, last_count=None):
    """
    Measurements lost on their way to the identifier.

    The recorder (``mr-damper-record``) takes the same stream; the samples in its stamp span
    (received plus stamp gaps) are what the rig published in that span (the rig waits for both
    subscribers before its first sample and stops before the identifier), so the identifier
    lost ``span - samples_received``. Gaps at the recorder itself are listed but are not losses
    of the suite (the recorder is a monitor, not part of the loop).

    ``last_count`` is the identifier's count in the last status the launcher's monitor took (its
    last life), where there is one: the recording may lack the last of the identifier's counts
    (a recorder starved at the stop missed them while the launcher saw the stream drained); the
    higher of the two is the identifier's.

    Returns
    -------
    (int, dict)
        Total lost and the breakdown.

    """
    st = rec.get('status', {})
    rig = st.get('rig', {}) or {}
    ident = st.get('identifier', {}) or {}
    br = {'measurement_gaps_at_recorder': int(rec.get('measurement_gaps', 0)),
          'measurements_received_by_recorder': int(rec.get('measurements_received', 0))}
    published = _first(rig, ('samples_published', 'published'))
    received = _first(ident, ('samples_received', 'received'))
    if isinstance(last_count, (int, float)) and not isinstance(last_count, bool):
        received = max(received or 0, int(last_count))
    lives = rec.get('identifier_lives') or []
    if lives:
        # a restarted identifier counts from 0: add up its lives; the last life's count is the
        # newer of its last status and its last samples_received message (10 Hz)
        received = (sum(life['last_count'] for life in lives[:-1])
                    + max(lives[-1]['last_count'], received or 0))
    if len(lives) > 1:
        br['identifier_lives'] = len(lives)
    if published is not None:
        br['measurements_published_by_rig_last_status'] = published
    lost_ident = None
    if received is not None:
        br['measurements_received_by_identifier'] = received
        # samples in the recorded stamp span = what the rig published in it (the rig waits for
        # both subscribers before its first sample, and stops first at shutdown)
        span = br['measurements_received_by_recorder'] + br['measurement_gaps_at_recorder']
        if span:
            lost_ident = max(0, int(span - received))
            br['measurements_lost_to_identifier'] = lost_ident
    if lost_ident is None:
        # no identifier counters: the launcher's own copy of the stream is the best evidence
        br['note'] = 'identifier status missing: messages_lost counts the recorder gaps'
        return br['measurement_gaps_at_recorder'], br
    return lost_ident, br


def restart_figures(supervision, rec, meas):
    """
    Return what each restart of a node cost, from the recording.

    Each restart's window runs from its node's death to the next death of any node (or the end
    of the recording): ``failsafe_s`` is the time the car state said fail-safe in it,
    ``no_car_state_s`` the time without any car state (the car or the recorder was down),
    ``car_normal_at_end`` whether the car was back to normal at its end.
    ``measurements_lost``: the samples the rig published in the window (recorded, or missing
    between recorded stamps) that no life of the identifier counted (``samples_received``),
    the window starting at the identifier's last count before the death (what a killed
    identifier took after its last count is lost with it).

    Parameters
    ----------
    supervision : dict
        The launcher's record (``restarts.json``): ``restarts`` (entries of
        ``supervisor.Supervisor.restarts``), ``gave_up``, ``policy``.
    rec : dict
        :func:`read_recording` (``car_modes``, ``identifier_lives``, ``gap_events``,
        ``end_epoch_s``).
    meas : column log
        The recorded measurements (``recv_epoch_s``).

    Returns
    -------
    list of dict
        One per restart: its record plus the figures above.

    """
    restarts = [dict(r) for r in supervision.get('restarts') or ()]
    deaths = sorted(r['death_epoch_s'] for r in restarts if r.get('death_epoch_s') is not None)
    end = rec.get('end_epoch_s')
    runs = rec.get('car_modes') or []
    lives = rec.get('identifier_lives') or []
    counted = sorted(t for life in lives for t, _ in life['counts'])
    windows = []
    for r in restarts:
        a = r.get('death_epoch_s')
        if a is None or end is None:
            continue
        later = [d for d in deaths if d > a]
        b = max(min(later) if later else end, a)
        fs = sum(max(0.0, min(b, hi) - max(a, lo)) for lo, hi, mode in runs if mode)
        seen = sum(max(0.0, min(b, hi) - max(a, lo)) for lo, hi, _ in runs)
        last = [mode for lo, hi, mode in runs if lo < b and hi > a]
        r.update(failsafe_s=fs, no_car_state_s=max(b - a - seen, 0.0),
                 car_normal_at_end=(not last[-1]) if last else None, window_s=b - a)
        before = [t for t in counted if t <= a]
        if before:
            lo = before[-1]
            missing = sum(n for t, n in rec.get('gap_events') or () if lo < t <= b)
            windows.append((r, lo, b, missing - _received_between(lives, lo, b)))
    if windows:
        n = [0] * len(windows)
        for c in open_log(meas).chunks(recording.CHUNK_ROWS, ('recv_epoch_s',)):
            t = c['recv_epoch_s']
            for k, (_, lo, hi, _) in enumerate(windows):
                n[k] += int(np.count_nonzero((t > lo) & (t <= hi)))
        for k, (r, _, _, rest) in enumerate(windows):
            r['measurements_lost'] = max(0, n[k] + int(rest))
    return restarts


def attribute_losses(breakdown, restarts):
    """
    Split the measurements lost to the identifier between the restarts of nodes and the rest.

    Each restart keeps its estimate (:func:`restart_figures`), capped so that the restarts
    together never claim more than ``measurements_lost_to_identifier``; the remainder is
    ``measurements_lost_not_at_restarts``. Updates both in place.
    """
    total = breakdown.get('measurements_lost_to_identifier')
    if total is None:
        return
    left = int(total)
    for r in restarts:
        if r.get('measurements_lost') is not None:
            r['measurements_lost'] = min(int(r['measurements_lost']), left)
            left -= r['measurements_lost']
    if any(r.get('measurements_lost') is not None for r in restarts):
        breakdown['measurements_lost_at_restarts'] = int(total) - left
        breakdown['measurements_lost_not_at_restarts'] = left


def can_summary(status, corner='fl'):
    """
    Commands over CAN (``--config can``): frames the bridge sent vs frames the driver received.

    Parameters
    ----------
    status : dict
        The last status of each node (``read_recording(...)['status']``): ``can_bridge`` and
        ``can_driver_sim`` (each node's final status, published as it stops; the driver stops
        after the bridge).
    corner : str
        The bridged corner.

    Returns
    -------
    dict or None
        ``frames_sent`` (bridge, all command frames incl. keep-alive re-sends), ``received``
        (driver, valid command frames), ``lost`` (their difference), ``counter_jumps``,
        ``frames_missed``, ``bad_checksum`` (driver), ``commands`` (bridge: ROS commands
        taken), ``resent``, ``failsafe_entries``, ``failsafe_s``, ``bridge_faults`` (the
        bridge's fault counters that are not zero), ``zero_lost`` (frames_sent == received and
        no counter jump); None when neither node reported.

    """
    bridge = status.get('can_bridge')
    driver = status.get('can_driver_sim')
    if bridge is None and driver is None:
        return None
    br = ((bridge or {}).get('corners') or {}).get(corner) or {}
    drv = ((driver or {}).get('corners') or {}).get(corner) or {}
    sent, received = br.get('frames_sent'), drv.get('received')
    out = {'corner': corner, 'frames_sent': sent, 'received': received,
           'lost': (sent - received if isinstance(sent, (int, float))
                    and isinstance(received, (int, float)) else None),
           'counter_jumps': drv.get('counter_jumps'), 'frames_missed': drv.get('frames_missed'),
           'bad_checksum': drv.get('bad_checksum'), 'commands': br.get('commands'),
           'resent': br.get('resent'), 'failsafe_entries': br.get('failsafe_entries'),
           'failsafe_s': br.get('failsafe_s'), 'bridge_mode': br.get('mode'),
           'bridge_reason': br.get('reason'),
           'bridge_faults': {k: v for k, v in ((bridge or {}).get('faults') or {}).items()
                             if v},
           'bridge_dropped': (bridge or {}).get('dropped') or {}}
    out['zero_lost'] = out['lost'] == 0 and out['counter_jumps'] == 0
    return out


def restart_lines(s):
    """Return the summary lines on the recording's completeness and the restarts of nodes."""
    lines = []
    rec = s.get('recording') or {}
    if rec.get('complete') is False:
        lines.append(f'recording INCOMPLETE: {rec.get("note")}')
        parts = rec.get('parts') or ()
        t0 = parts[0].get('first_log_time_s') if parts else None
        for p in parts:
            if not p['complete'] and p.get('last_log_time_s') is not None and t0 is not None:
                lines.append(f'  {p["file"]}: truncated after {p["messages"]} messages, the '
                             f'last {p["last_log_time_s"] - t0:.1f} s after the recording\'s '
                             'start')
    restarts = s.get('restarts') or []
    if restarts:
        lines.append(f'restarts: {len(restarts)} ' + '(' + ', '.join(
            f'{n} {c}' for n, c in (s.get('restart_counts') or {}).items()) + ')')
    for r in restarts:
        how = r.get('signal') or f'exit {r.get("exit_code")}'
        what = 'died'
        if r.get('reason') == 'hung':
            what = 'hung'
            how = f'no status for {r.get("silent_s", float("nan")):.1f} s, killed'
        line = f'  {r["node"]} {what} at {r["death_s"]:.1f} s ({how}), '
        line += ('not restarted before the end' if r.get('restart_s') is None
                 else f'restarted at {r["restart_s"]:.1f} s')
        if r.get('failsafe_s') is not None:
            line += (f'; car in fail-safe {r["failsafe_s"]:.1f} s of the '
                     f'{r["window_s"]:.1f} s after it, without state {r["no_car_state_s"]:.1f} s')
        if r.get('measurements_lost') is not None:
            line += f'; {r["measurements_lost"]} measurements lost to the identifier'
        lines.append(line)
    gave = s.get('gave_up')
    if gave:
        lines.append(f'gave up: {gave["node"]} died {gave["deaths_in_window"]} times within '
                     f'{gave["restart_window_s"]:g} s (last at {gave["death_s"]:.1f} s)')
    return lines
