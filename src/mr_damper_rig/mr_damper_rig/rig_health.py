"""
Health of the rig node from its status values (no ROS): what ``/diagnostics`` reports.

:class:`RigHealth` is called once per diagnostics period with the rig's status values (the
keys below) and compares them with those of the previous call, so a counter that rose since
then raises a warning once and the level goes back to OK when it stops rising:

- ERROR ``publishing stalled``: samples are due but none went out since the previous status
  (the measurement writer refuses them and its replacement has not matched its readers);
- WARN ``writer replaced``: ``writer_resets`` rose (a reader stopped acknowledging);
- WARN ``dropped``: a count in ``dropped`` rose (failed publish, lost commands);
- WARN ``current commands clamped/refused``, ``displacement commands clamped/refused``;
- WARN ``commander silent``: the displacement commands stopped and the rig holds the last one
  or returns to neutral (``stale_samples`` rose);
- WARN ``no count from the consumer`` (``rate_factor`` 0 started without any
  ``samples_received``: one sample per tick);
- OK otherwise, with ``waiting for subscribers``, ``running`` or ``done`` as the message.

Status values read (missing ones are skipped): ``started``, ``done``, ``samples_published``,
``backlog_samples``, ``subscribers``, ``wait_for_subscribers``, ``writer_resets``, ``dropped``
(dict), ``commands`` (dict of current-command outcomes), ``displacement_commands`` (dict),
``rate_factor``, ``flow`` (dict with ``received``).
"""
from mr_damper_common.commands import OUTCOMES
from mr_damper_common.health import dropped_since, ERROR, OK, Rising, WARN, worst

_CLAMPED = tuple(o for o in OUTCOMES if o != 'accepted')


class RigHealth:
    """
    The rig's health from one status to the next (keeps the previous counters).

    Call it with the status values; it returns a
    :class:`~mr_damper_common.health.Health` carrying those values.
    """

    def __init__(self):
        self._rising = Rising()
        self._first = True

    def __call__(self, values):
        """Return the :class:`~mr_damper_common.health.Health` of ``values`` (dict)."""
        first, self._first = self._first, False
        rise = self._rising.rise
        problems = []
        started, done = bool(values.get('started')), bool(values.get('done'))
        published = int(values.get('samples_published') or 0)
        if (rise('samples_published', published) == 0 and started and not done and not first
                and int(values.get('backlog_samples') or 0) > 0):
            problems.append((ERROR, f'publishing stalled: {values["backlog_samples"]} samples '
                                    'due, none published since the last status'))
        resets = rise('writer_resets', values.get('writer_resets'))
        if resets > 0:
            problems.append((WARN, f'measurement writer replaced {resets} time(s): a reader '
                                   f'stopped acknowledging ({values["writer_resets"]} in all)'))
        problems.append(dropped_since(self._rising, values.get('dropped'), 'dropped'))
        for key, what in (('commands', 'current'), ('displacement_commands', 'displacement')):
            now = values.get(key) or {}
            bad = {k: rise(f'{key}.{k}', now.get(k)) for k in _CLAMPED}
            bad = {k: n for k, n in bad.items() if n > 0}
            if bad:
                problems.append((WARN, f'{what} commands ' + ', '.join(
                    f'{k.replace("_", " ")}: {n}' for k, n in bad.items())))
        stale = rise('displacement_commands.stale_samples',
                     (values.get('displacement_commands') or {}).get('stale_samples'))
        if stale > 0:
            problems.append((WARN, f'commander silent: {stale} samples held or returning to '
                                   'neutral'))
        flow = values.get('flow')
        if started and not done and flow is not None and flow.get('received') is None:
            problems.append((WARN, 'no count from the consumer on samples_received: one sample '
                                   'per tick'))
        health = worst([p for p in problems if p], values)
        if health.level == OK:
            if done:
                health.message = f'done: {published} samples published'
            elif not started:
                health.message = (f'waiting for subscribers ({values.get("subscribers", 0)} of '
                                  f'{values.get("wait_for_subscribers", 0)})')
            else:
                health.message = 'running'
        return health
