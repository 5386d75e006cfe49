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
from semi_active_control.estimation.sensor_specs import accelerometer_spec, G0
from semi_active_control.supervision.deadline import RECOVER_CYCLES
from semi_active_control.supervision.failsafe import COIL_SETTINGS as COIL

#: Parameters of the supervised law, shared with the quarter car's built-in controller.
SUPERVISED_LAW_PARAMETERS = (
    Param('controller_options', '{}', 'JSON keyword options (gains) of the controller, e.g. '
          '{"c_sky": 3000.0}; a change rebuilds the law (refused: the old one stays)',
          dynamic=True),
    Param('safe_current_a', COIL['safe_current_a'], 'Coil current in fail-safe [A]', 0.0, 10.0,
          dynamic=True),
    Param('param_timeout_s', 1.0, 'Identified parameters older than this are stale, aged from '
          'their stamp (from receipt when it is on another clock) [s, node clock]', 0.01,
          3600.0, dynamic=True),
    Param('i_min_a', COIL['i_min_a'], 'Coil current minimum [A]', 0.0, 10.0),
    Param('i_max_a', COIL['i_max_a'], 'Coil current maximum [A]', 0.0, 10.0),
    Param('min_current_span_a', COIL['min_current_span_a'], 'Refuse models identified over a '
          'narrower current range [A]', 0.0, 10.0, dynamic=True),
    Param('hold_on_reject', False, 'Keep the model in use when a later message is refused '
          '(until stale)', dynamic=True),
)

#: Settings of each corner's fail-safe supervisor, shared with ``full_car_node``'s built-in law.
CORNER_SUPERVISOR_PARAMETERS = (
    Param('safe_current_a', COIL['safe_current_a'], 'Coil current of a corner in fail-safe [A]',
          0.0, 10.0),
    Param('param_timeout_s', 1.0, 'A corner\'s identified parameters older than this are '
          'stale, aged from their stamp (from receipt when it is on another clock) [s, node '
          'clock]', 0.01, 3600.0),
    Param('i_min_a', COIL['i_min_a'], 'Coil current minimum [A]', 0.0, 10.0),
    Param('i_max_a', COIL['i_max_a'], 'Coil current maximum [A]', 0.0, 10.0),
    Param('min_current_span_a', COIL['min_current_span_a'], 'Refuse models identified over a '
          'narrower current range [A]', 0.0, 10.0),
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


#: The vehicle estimator's filter (``vehicle_estimator_node`` and ``vehicle_computer_node``).
VEHICLE_ESTIMATOR_PARAMETERS = (
    Param('cycle_s', 0.002, 'Sensor cycle, the filter\'s period [s]', 1e-4, 1.0),
    Param('accel_noise_density', 250e-6 * G0, 'Accelerometer noise density [m/s^2/sqrt(Hz)] '
          '(ADXL313: 250 ug/sqrt(Hz))', 1e-7, 1.0),
    Param('travel_noise_density', 2.2e-6, 'Ride height sensor noise density [m/sqrt(Hz)]',
          1e-9, 1e-2),
    Param('road_class', 'C', 'ISO 8608 class of the design road (process noise)'),
    Param('speed_m_s', 20.0, 'Design speed [m/s] (process noise)', 0.1, 100.0),
    Param('dropout_s', 0.02, 'No reading of a sensor for this long: left out [s]', 1e-3, 10.0),
    Param('stuck_accel_s', 0.05, 'The same accelerometer reading this long: stuck [s]', 1e-3,
          10.0),
    Param('stuck_travel_s', 0.25, 'The same position reading this long: stuck [s]', 1e-3, 10.0),
    Param('accel_bias_std', accelerometer_spec().bias_std, 'Accelerometer turn-on bias the '
          'filter starts with, one standard deviation [m/s^2] (ADXL313: 15 mg; 0: calibrated '
          'away)', 0.0, 10.0),
)

#: The vehicle controller's law, models, supervisors and deadlines (``vehicle_controller_node``
#: and ``vehicle_computer_node``).
VEHICLE_CONTROLLER_PARAMETERS = (
    Param('controller', 'modal-skyhook', 'Full-car law: modal-skyhook, '
          'full-car-clipped-optimal(-wk), per-corner-<law> (e.g. per-corner-skyhook), '
          'passive@<I>A or preview-look-ahead (full-car-clipped-optimal-wk with LQ preview on '
          'full_car/road_preview)'),
    Param('cycle_s', 0.002, 'Control cycle: the sensor cycle, each answer\'s deadline [s]',
          1e-4, 1.0),
    Param('model_files', ['', '', '', ''], 'Per corner (fl, fr, rl, rr) the damper\'s '
          'parameter file (end-of-line record: mr-damper-identify --batch --params-dir), or '
          '"" for the live identifier on <c>/mr_damper/kwok_parameters'),
) + CORNER_SUPERVISOR_PARAMETERS + (
    Param('deadline_s', 0.0, 'Each answer\'s deadline after its state\'s stamp [s] (0: one '
          'cycle)', 0.0, 10.0),
    Param('max_consecutive_misses', 5, 'Cycles in a row answered after their deadline that put '
          'every corner on the safe current (deadline_misses)', 1, 100000),
    Param('recover_cycles', RECOVER_CYCLES, 'Cycles in a row on time that end deadline_misses',
          1, 100000),
    Param('sensor_timeout_s', 0.02, 'No state for this long: every corner on the safe current '
          '(sensor_timeout) [s]', 1e-3, 60.0),
    Param('check_period_s', 0.01, 'Period of the sensor timeout check and of the safe '
          'commands while it lasts [s] (inside the drivers\' command timeout)', 1e-3, 1.0),
    Param('preview_horizon_s', 0.3, 'Preview law: horizon of the feedforward on the road ahead '
          '[s]', 0.0, 2.0),
    Param('preview_timeout_s', 0.25, 'Preview law: without a frame taken for this long the law '
          'runs without preview [s, state stamps]', 0.001, 60.0),
    Param('preview_max_age_s', 0.1, 'Preview law: a frame older than this when its cycle comes '
          'is stale (refused) [s]', 0.001, 60.0),
)


def make_vehicle_estimator(p):
    """
    Design the vehicle estimator's filter from a node's parameters (``p``: name -> value).

    :data:`VEHICLE_ESTIMATOR_PARAMETERS` on the passenger car; the design (``control.dlqe``)
    takes seconds on a small computer, so a node calls this before it is up, never in a
    transition (its heartbeat would stop that long).
    """
    from semi_active_control.car.full_car import PASSENGER_CAR
    from semi_active_control.estimation import EstimatorSettings, VehicleEstimatorCore
    return VehicleEstimatorCore(PASSENGER_CAR, EstimatorSettings(
        cycle_s=p['cycle_s'], accel_noise_density=p['accel_noise_density'],
        travel_noise_density=p['travel_noise_density'], road_class=p['road_class'],
        speed_m_s=p['speed_m_s'], dropout_s=p['dropout_s'],
        stuck_accel_s=p['stuck_accel_s'], stuck_travel_s=p['stuck_travel_s'],
        accel_bias_std=p['accel_bias_std']))


def make_vehicle_controller(p):
    """
    Build the vehicle controller's core from a node's parameters (``p``: name -> value).

    :data:`VEHICLE_CONTROLLER_PARAMETERS`: the law (the road-preview law with its topic input
    for ``preview-look-ahead``), each corner's model source under its supervisor, the deadline
    supervision. Raises ValueError for a law or setting that cannot be built. The models are
    loaded by the core's ``configure``.
    """
    from semi_active_control.car.full_car import PASSENGER_CAR
    from semi_active_control.runtime import LIVE_PREVIEW_LAWS, LivePreview, VehicleControllerCore
    from semi_active_control.supervision import CornerModels
    models = CornerModels(p['model_files'], timeout_s=p['param_timeout_s'],
                          safe_current_a=p['safe_current_a'], i_min_a=p['i_min_a'],
                          i_max_a=p['i_max_a'], min_current_span_a=p['min_current_span_a'],
                          hold_on_reject=p['hold_on_reject'])
    preview = None
    if p['controller'].strip().lower() in LIVE_PREVIEW_LAWS:
        preview = LivePreview(PASSENGER_CAR, p['controller'], dt=p['cycle_s'],
                              horizon_s=p['preview_horizon_s'],
                              preview_timeout_s=p['preview_timeout_s'],
                              preview_max_age_s=p['preview_max_age_s'])
    return VehicleControllerCore(
        PASSENGER_CAR, p['controller'], models, cycle_s=p['cycle_s'],
        max_consecutive_misses=p['max_consecutive_misses'], recover_cycles=p['recover_cycles'],
        input_timeout_s=p['sensor_timeout_s'], deadline_s=p['deadline_s'] or None,
        preview=preview)


def log_model_verdicts(logger, verdicts):
    """Log each corner's model file verdict (``{corner: Verdict}`` of the core's configure)."""
    for corner, verdict in verdicts.items():
        # (one severity per call site: rclpy refuses a line that logs at two)
        if verdict.accepted:
            logger.info(f'{corner}: model file ok')
        else:
            logger.warning(f'{corner}: model file refused ({verdict.reason}): '
                           f'{verdict.detail}; the corner stays on its safe current')


def vehicle_controller_problems(st):
    """
    Return the ``(level, text)`` problems of a vehicle controller's status dict (``/diagnostics``).

    ``st`` is :meth:`VehicleControllerCore.status` with ``lifecycle`` (the node's state label);
    empty when every corner is on the law.
    """
    from mr_damper_common.health import ERROR, WARN
    if 'corners' not in st:
        return [(WARN, f'{st["lifecycle"]}: not configured')]
    if not st['active']:
        return [(WARN, f'{st["lifecycle"]}: every corner on the safe current')]
    reason = st['deadline']['reason']
    if reason:
        return [(ERROR, f'every corner on the safe current: {reason}')]
    safe = [c for c, d in st['corners'].items() if d.get('mode') != 'normal']
    if safe:
        return [(WARN, 'fail-safe at ' + ', '.join(
            f'{c} ({st["corners"][c].get("reason")})' for c in safe))]
    return []


def identified_set_or_error(msg):
    """Return a ``KwokParameters`` message's identified set, or the ValueError decoding it."""
    try:
        return messages.identified_set_from_msg(msg)
    except ValueError as exc:
        return exc


def log_refused_parameters(logger, corner, verdict):
    """Log a corner's refused set (throttled); nothing for None or an accepted one."""
    if verdict is not None and not verdict.accepted:
        logger.warning(f'{corner}: parameters refused ({verdict.reason}): {verdict.detail}',
                       throttle_duration_sec=1.0)


def road_preview_or_error(msg, logger):
    """Return a ``RoadPreview`` message's fields, or the MessageError decoding it (logged)."""
    try:
        return messages.road_preview_fields(msg)
    except messages.MessageError as exc:
        logger.warning(f'road preview refused: {exc}', throttle_duration_sec=1.0)
        return exc
