"""
What the controller nodes and the car nodes share: supervisor parameters, offering a set.

The car nodes of the simulator (``quarter_car_node``, ``full_car_node``) run the same
supervised law as the vehicle's controller nodes when their law is built in, with the same
parameters; this module declares them once (:data:`SUPERVISED_LAW_PARAMETERS`,
:data:`CORNER_SUPERVISOR_PARAMETERS`) and offers a received parameter message to a supervisor
(:func:`offer_parameters`), so no node module imports another.
"""
from mr_damper_common import messages
from mr_damper_common.node_utils import Param

#: Parameters of the supervised law, shared with the quarter car's built-in controller.
SUPERVISED_LAW_PARAMETERS = (
    Param('controller_options', '{}', 'JSON keyword options (gains) of the controller, e.g. '
          '{"c_sky": 3000.0}; a change rebuilds the law (refused: the old one stays)',
          dynamic=True),
    Param('safe_current_a', 0.5, 'Coil current in fail-safe [A]', 0.0, 10.0, dynamic=True),
    Param('param_timeout_s', 1.0, 'Identified parameters older than this are stale [s, node '
          'clock]', 0.01, 3600.0, dynamic=True),
    Param('i_min_a', 0.0, 'Coil current minimum [A]', 0.0, 10.0),
    Param('i_max_a', 2.0, 'Coil current maximum [A]', 0.0, 10.0),
    Param('min_current_span_a', 1.0, 'Refuse models identified over a narrower current range '
          '[A]', 0.0, 10.0, dynamic=True),
    Param('hold_on_reject', False, 'Keep the model in use when a later message is refused '
          '(until stale)', dynamic=True),
)

#: Settings of each corner's fail-safe supervisor, shared with ``full_car_node``'s built-in law.
CORNER_SUPERVISOR_PARAMETERS = (
    Param('safe_current_a', 0.5, 'Coil current of a corner in fail-safe [A]', 0.0, 10.0),
    Param('param_timeout_s', 1.0, 'A corner\'s identified parameters older than this are '
          'stale [s, node clock]', 0.01, 3600.0),
    Param('i_min_a', 0.0, 'Coil current minimum [A]', 0.0, 10.0),
    Param('i_max_a', 2.0, 'Coil current maximum [A]', 0.0, 10.0),
    Param('min_current_span_a', 1.0, 'Refuse models identified over a narrower current range '
          '[A]', 0.0, 10.0),
    Param('hold_on_reject', False, 'Keep a corner\'s model when a later message is refused '
          '(until stale)'),
)


def offer_parameters(supervisor, msg, now, logger):
    """
    Offer a ``KwokParameters`` message received at ``now`` [s, node clock] to ``supervisor``.

    Decoded by :func:`mr_damper_common.messages.identified_set_from_msg` and offered
    (:meth:`~semi_active_control.supervision.failsafe.ModelSupervisor.offer_decoded`: a message the
    decoder refuses is refused by the decoder's reason when the supervisor knows it,
    ``'bad_i_ref'``, else as ``'undecodable'``); refusals are logged (throttled). The caller holds
    the supervisor's lock if it has one. Returns the ``Verdict``.
    """
    verdict = supervisor.offer_decoded(messages.identified_set_from_msg, msg, now)
    if not verdict.accepted:
        logger.warning(f'parameters refused ({verdict.reason}): {verdict.detail}',
                       throttle_duration_sec=1.0)
    return verdict
