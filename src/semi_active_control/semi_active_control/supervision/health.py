"""
Health rules of the semi-active controller node, and the fail-safe messages (ROS-free).

The node publishes the result on ``/diagnostics``
(:class:`mr_damper_common.health.Health` -> ``diagnostic_msgs/DiagnosticStatus``). The values
are the node's status (mode and why, fail-safe time and entries, parameters accepted and
rejected by reason, parameter age, current, saturation, drops, ...); the level and message say
what is wrong:

- OK: running in normal mode;
- WARN: fail-safe, with why (no parameters yet, stale, refused and the reason, a state
  refused); messages dropped, states refused, state stamps re-based (a vehicle clock jump)
  since the previous check;
- ERROR: the state input refused at every check for ``persistent_checks`` checks in a row with
  nothing usable in between.

"Since the previous check" compares counters between calls, so the rules are stateful: one
:class:`ControllerHealth` per node, called once per diagnostics period. The simulated car's
rules (:class:`quarter_car_sim.runtime.car_health.CarHealth`) share :func:`failsafe_message`.
"""
from mr_damper_common.health import dropped_since, ERROR, OK, Rising, WARN, worst

#: Why the supervisor or the command input is in fail-safe, for a human.
FAILSAFE_MESSAGES = {
    'no_parameters_yet': 'no identified parameters yet',
    'stale': 'identified parameters stale (older than param_timeout_s)',
    'stale_on_arrival': 'identified parameters received already older than param_timeout_s '
                        '(by their stamp)',
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
        The supervisor's or command input's reason
        (``semi_active_control.supervision.failsafe.REASONS``, ``no_command_yet``,
        ``command_timeout``).
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


__all__ = ['ControllerHealth', 'failsafe_message', 'FAILSAFE_MESSAGES', 'OK']
