"""
Health rules of the quarter-car node and the semi-active controller node (ROS-free).

The nodes publish the result on ``/diagnostics``
(:class:`mr_damper_common.health.Health` -> ``diagnostic_msgs/DiagnosticStatus``). The values
are the node's status (mode and why, fail-safe time and entries, parameters accepted and
rejected by reason, parameter age, current, saturation, loop timing, drops, ...) plus the
running ride metrics (``ride_metrics``) of the car; the level and message say what is wrong:

- OK: running in normal mode;
- WARN: fail-safe, with why (no parameters yet, stale, refused and the reason, no command yet,
  command timeout); the control loop late (pacer re-anchored, or lateness p99 above
  ``lateness_warn_ms``); samples dropped, states refused, state stamps re-based (a vehicle
  clock jump), lock-step timeouts or rig-link faults
  (``plant:=rig``: stale or missing measurements, wait timeouts, bad samples) since the previous
  check;
- ERROR: the control thread died or stopped; the command (car, ``controller:=external``) or
  state (controller node) input refused at every check for ``persistent_checks`` checks in a
  row with nothing usable in between.

"Since the previous check" compares counters between calls, so the rules are stateful: one
:class:`CarHealth` / :class:`ControllerHealth` per node, called once per diagnostics period.
"""
from mr_damper_common.health import dropped_since, ERROR, OK, Rising, WARN, worst

#: Why the supervisor or the command input is in fail-safe, for a human.
FAILSAFE_MESSAGES = {
    'no_parameters_yet': 'no identified parameters yet',
    'stale': 'identified parameters stale (older than param_timeout_s)',
    'no_command_yet': 'no current command yet',
    'command_timeout': 'no current command for command_timeout_s',
    'state_non_finite': 'vehicle state refused (a field the law reads is not finite)',
    'state_out_of_order': 'vehicle state refused (stamp older than the newest taken)',
    'state_future_stamp': 'vehicle state refused (stamped beyond max_future_s ahead of the '
                          'node clock)',
}


def failsafe_message(reason, detail=''):
    """
    Return the one-line WARN message of fail-safe for ``reason``.

    Parameters
    ----------
    reason : str
        The supervisor's or command input's reason (``quarter_car_sim.failsafe.REASONS``,
        ``no_command_yet``, ``command_timeout``).
    detail : str
        Detail of the last refusal (shown for refusals).

    Returns
    -------
    str

    """
    if reason in FAILSAFE_MESSAGES:
        text = FAILSAFE_MESSAGES[reason]
    else:
        text = f'parameters refused ({reason})' + (f': {detail}' if detail else '')
    return f'fail-safe: {text}'


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


class ControllerHealth:
    """
    Health of the semi-active controller node from its status (see the module docstring).

    Parameters
    ----------
    persistent_checks : int
        ERROR when every state received was refused for this many checks in a row.

    """

    def __init__(self, persistent_checks=3):
        self.persistent_checks = int(persistent_checks)
        self._rising = Rising()
        self._refused_checks = 0

    def __call__(self, status):
        """Return the :class:`~mr_damper_common.health.Health` of one check (``status()``)."""
        problems = []
        if status.get('mode') == 'failsafe':
            problems.append((WARN, failsafe_message(status.get('reason', '?'),
                                                    status.get('last_reject_detail', ''))))
        refused = {k: self._rising.rise(f'state_rejected.{k}', v)
                   for k, v in (status.get('state_rejected') or {}).items()}
        n_refused = sum(refused.values())
        answered = self._rising.rise('commands', status.get('commands', 0)) - n_refused
        if n_refused and answered <= 0:
            self._refused_checks += 1
        elif answered > 0:
            self._refused_checks = 0
        if self._refused_checks >= self.persistent_checks:
            problems.append((ERROR, f'vehicle states refused persistently '
                                    f'({self._refused_checks} checks without a usable state)'))
        elif n_refused:
            problems.append((WARN, 'states refused since the last check: ' + ', '.join(
                f'{v} {k}' for k, v in refused.items() if v)))
        rebased = self._rising.rise('stamp_rebases', status.get('stamp_rebases', 0))
        if rebased:
            problems.append((WARN, f'vehicle clock jumped: state stamps re-based {rebased} '
                                   'time(s) since the last check'))
        problems.append(dropped_since(self._rising, status.get('dropped')))
        return worst([p for p in problems if p], status)


__all__ = ['CarHealth', 'ControllerHealth', 'failsafe_message', 'FAILSAFE_MESSAGES', 'OK']
