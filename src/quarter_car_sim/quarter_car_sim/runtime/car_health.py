"""
Health rules of the quarter-car node (ROS-free): the simulated car's ``/diagnostics``.

The node publishes the result on ``/diagnostics``
(:class:`mr_damper_common.health.Health` -> ``diagnostic_msgs/DiagnosticStatus``). The values
are the node's status (mode and why, fail-safe time and entries, parameters accepted and
rejected by reason, parameter age, current, saturation, loop timing, drops, ...) plus the
running ride metrics (``ride_metrics``) of the car; the level and message say what is wrong:

- OK: running in normal mode;
- WARN: fail-safe, with why (:func:`semi_active_control.supervision.health.failsafe_message`:
  no parameters yet, stale, refused and the reason, no command yet, command timeout); the
  control loop late (pacer re-anchored, or lateness p99 above ``lateness_warn_ms``); samples
  dropped, lock-step timeouts or rig-link faults (``plant:=rig``: stale or missing
  measurements, wait timeouts, bad samples) since the previous check;
- ERROR: the control thread died or stopped; the command input (``controller:=external``)
  refused at every check for ``persistent_checks`` checks in a row with nothing usable in
  between.

"Since the previous check" compares counters between calls, so the rules are stateful: one
:class:`CarHealth` per node, called once per diagnostics period.
"""
from mr_damper_common.health import dropped_since, ERROR, Rising, WARN, worst
from semi_active_control.supervision.health import failsafe_message


class CarHealth:
    """
    Health of the quarter-car node from its status (see the module docstring).

    Parameters
    ----------
    lateness_warn_ms : float
        WARN when the control loop's lateness p99 exceeds this [ms, wall clock].
    persistent_checks : int
        ERROR when every command received was refused for this many checks in a row.

    """

    def __init__(self, lateness_warn_ms=5.0, persistent_checks=3):
        self.lateness_warn_ms = float(lateness_warn_ms)
        self.persistent_checks = int(persistent_checks)
        self._rising = Rising()
        self._refused_checks = 0

    def __call__(self, status, metrics=None, *, failed=None, alive=True):
        """
        Return the :class:`~mr_damper_common.health.Health` of one check.

        Parameters
        ----------
        status : dict
            The node's status (``QuarterCarNode.status()``).
        metrics : dict, optional
            Running ride metrics (``values['ride_metrics']``).
        failed : str or None
            Why the control thread died (None: it did not).
        alive : bool
            Whether the control thread runs.

        """
        values = dict(status)
        if metrics is not None:
            values['ride_metrics'] = dict(metrics)
        problems = []
        if failed:
            problems.append((ERROR, f'control thread died: {failed}'))
        elif not alive:
            problems.append((ERROR, 'control thread stopped'))
        problems.append(self._commands(status))
        if status.get('mode') == 'failsafe':
            problems.append((WARN, failsafe_message(status.get('reason', '?'),
                                                    status.get('last_reject_detail', ''))))
        loop = status.get('loop') or {}
        late = self._rising.rise('late_reanchors', status.get('late_reanchors', 0))
        p99 = (loop.get('lateness') or {}).get('p99_ms')
        if late:
            problems.append((WARN, f'control loop overloaded: schedule re-anchored {late} '
                                   'time(s) since the last check'))
        elif p99 is not None and p99 > self.lateness_warn_ms:
            problems.append((WARN, f'control loop late: lateness p99 {p99:.2f} ms > '
                                   f'{self.lateness_warn_ms:g} ms'))
        n = self._rising.rise('lockstep_timeouts', status.get('lockstep_timeouts', 0))
        if n:
            problems.append((WARN, f'{n} lock-step timeout(s) since the last check'))
        problems.append(self._rig_link(status.get('hil')))
        problems.append(dropped_since(self._rising, status.get('dropped')))
        return worst([p for p in problems if p], values)

    def _rig_link(self, hil):
        """``plant:=rig``: faults of the rig link (stale, missing, bad samples) since the last."""
        counts = (hil or {}).get('counts') or {}
        n = {k: self._rising.rise(f'hil.{k}', v) for k, v in sorted(counts.items())
             if k != 'measurements'}
        n = {k: v for k, v in n.items() if v}
        if not n:
            return None
        return (WARN, 'rig link since the last check: '
                + ', '.join(f'{v} {k}' for k, v in n.items()))

    def _commands(self, status):
        counts = status.get('commands')
        if not isinstance(counts, dict):          # built-in controller: no command input
            return None
        refused = sum(self._rising.rise(f'commands.{k}', v) for k, v in counts.items()
                      if k.startswith('refused'))
        applied = sum(self._rising.rise(f'commands.{k}', v) for k, v in counts.items()
                      if not k.startswith('refused'))
        if refused and not applied:
            self._refused_checks += 1
        elif applied:
            self._refused_checks = 0
        if self._refused_checks >= self.persistent_checks:
            return (ERROR, f'current commands refused persistently ({self._refused_checks} '
                           'checks without a usable command)')
        if refused:
            return (WARN, f'{refused} current command(s) refused since the last check')
        return None
