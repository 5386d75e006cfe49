"""
The vehicle run of ``mr-damper-suite --config vehicle``: configuration, progress, summary.

On one side of a loopback CAN bus the simulated car: ``full_car_node`` as the plant
(``controller: can``: its sensor cluster and four damper drivers on the bus). On the other the
vehicle computer, each node its own managed process: ``vehicle_bridge_node``,
``vehicle_estimator_node``, ``vehicle_controller_node``, brought up in that order by
``lifecycle_manager`` (docs/vehicle.md). Each corner's true damper is its shipped end-of-line
record (``semi_active_control/config/models``), which the controller also loads as its model;
with ``--live-identification`` four rig / identifier stacks (namespaces ``fl`` .. ``rr``, each
rig's damper the corner's record) give the controller its models instead.

The summary's ``vehicle`` section (:func:`vehicle_summary`) comes from the nodes' final statuses
and the car's body log: control cycles and how many were answered within their period
(bus to bus, at the bridge), the controller's deadline misses, the drivers' command timeouts
after the vehicle computer took control, sensor frame to command frame latency, frames and
messages lost, and the body's ISO 2631-1 a_v against the same car at the safe current
(``a_v_passive``) and the same law on the true states in lock-step (``a_v_lockstep``), both
simulated offline on the same road and dampers over the same window.
"""
import copy
from pathlib import Path

import numpy as np

from mr_damper_common.health import finite_or_none

from .config import CAN_GROUP, CAN_PORT_BASE, IDENT, node_params, REPO, RIG, set_param
from .full_car_suite import BODY_LOG, FULL_CAR, FULL_CAR_CORNERS

#: The vehicle computer's nodes (YAML section = node name).
BRIDGE, ESTIMATOR, CONTROLLER, MANAGER = ('vehicle_bridge', 'vehicle_estimator',
                                          'vehicle_controller', 'lifecycle_manager')
#: The vehicle computer in one control loop (``vehicle_computer_node``).
COMPUTER = 'vehicle_computer'
#: The vehicle computer's layouts: ``loop`` (one process: the bus, the estimator and the
#: controller in one control path) and ``nodes`` (three processes, a topic between each).
LAYOUTS = ('loop', 'nodes')
#: Per layout, the chain's nodes in the manager's order.
CHAINS = {'loop': (COMPUTER,), 'nodes': (BRIDGE, ESTIMATOR, CONTROLLER)}
#: Stop order, in two groups (every node of the first has exited before the second is
#: signalled): the manager (it would bring nodes back) and the car (the plant: the run's
#: measurement ends with it); then the vehicle computer: the controller (its end: the safe
#: command), the estimator, the bridge (its end: the safe frame, then the bus closes), or the
#: loop node where the three are (the names of the other layout are not running). With the
#: computer stopped first, the car's four drivers each counted one command timeout at every
#: stop (the computer's end) as a failure after the activation.
STOP_ORDER = ((MANAGER, FULL_CAR), (COMPUTER, CONTROLLER, ESTIMATOR, BRIDGE))


def vehicle_nodes(layout='loop'):
    """Return the run's nodes of ``layout`` (YAML section = node name -> console script)."""
    if layout not in LAYOUTS:
        raise ValueError(f'the vehicle layout must be one of {LAYOUTS}, got {layout!r}')
    return {FULL_CAR: 'full_car_node', **{n: f'{n}_node' for n in CHAINS[layout]},
            MANAGER: 'lifecycle_manager'}


#: The shipped end-of-line records of the four dampers.
MODELS_DIR = REPO / 'src' / 'semi_active_control' / 'config' / 'models'


def model_files(folder=MODELS_DIR):
    """Return the four corners' record files (``fl, fr, rl, rr``)."""
    return [str(Path(folder) / f'{c}.json') for c in FULL_CAR_CORNERS]


def vehicle_configs(cfg, out, duration_s, domain_id, live_identification=False, preview=False,
                    layout='loop'):
    """
    Split a vehicle run's parameters: the corners' stacks (live only) and the rest.

    Parameters
    ----------
    cfg : dict
        The run's parameters (``config/suite_vehicle.yaml`` after ``--set``).
    out : path
        Output folder.
    duration_s : float
        Run time [s] (the car's road and body log are made long enough).
    domain_id : int
        The run's domain (the bus port is ``CAN_PORT_BASE`` + it).
    live_identification : bool
        Four rig / identifier stacks give the models instead of the files.
    preview : bool
        The controller runs the LQ road-preview law (``preview-look-ahead``) on the look-ahead
        frames the car publishes (``road_preview: true``), stamped on the vehicle's clock.
    layout : str
        ``loop``: ``vehicle_computer`` gets the bridge's, the estimator's and the controller's
        sections merged (its own section, if any, on top); ``nodes``: the three nodes. The
        lifecycle manager gets the layout's chain.

    Returns
    -------
    corners : dict
        corner -> its rig / identifier parameter dict (empty without live identification).
    vehicle : dict
        The car's and the vehicle computer's parameter dict.

    """
    from .config import corner_configs
    files = model_files()
    channel = f'{CAN_GROUP}:{CAN_PORT_BASE + int(domain_id)}'
    vehicle = {k: v for k, v in cfg.items() if k not in (RIG, IDENT)}
    car = node_params(vehicle, FULL_CAR)
    if not any(car.get('truth_files') or ()):
        set_param(vehicle, FULL_CAR, 'truth_files', list(files))
    set_param(vehicle, FULL_CAR, 'can_channel', channel)
    set_param(vehicle, BRIDGE, 'channel', channel)
    set_param(vehicle, FULL_CAR, 'log_file', str(Path(out) / BODY_LOG))
    rtf = float(node_params(vehicle, FULL_CAR).get('real_time_factor', 1.0)) or 20.0
    need = float(duration_s) * rtf + 30.0 if duration_s else 600.0
    set_param(vehicle, FULL_CAR, 'road_duration_s', min(max(need, 60.0), 3600.0))
    set_param(vehicle, FULL_CAR, 'log_max_s', min(need, 3600.0))
    if preview:
        from .full_car_suite import PREVIEW_LAW
        set_param(vehicle, FULL_CAR, 'road_preview', True)
        set_param(vehicle, CONTROLLER, 'controller', PREVIEW_LAW)
    ctrl = node_params(vehicle, CONTROLLER)
    if not live_identification and not any(ctrl.get('model_files') or ()):
        set_param(vehicle, CONTROLLER, 'model_files', list(files))
    corners = {}
    if live_identification:
        set_param(vehicle, CONTROLLER, 'model_files', [''] * 4)
        stacks = {k: v for k, v in cfg.items() if k in ('/**', RIG, IDENT)}
        corners = corner_configs(stacks, FULL_CAR_CORNERS, out)
        truths = list(node_params(vehicle, FULL_CAR)['truth_files'])
        for corner, truth in zip(FULL_CAR_CORNERS, truths):
            set_param(corners[corner], f'/{corner}/{RIG}', 'truth_file', truth)
    vehicle_nodes(layout)                       # a known layout
    if layout == 'loop':
        merged = {}
        for name in (CONTROLLER, ESTIMATOR, BRIDGE, COMPUTER):      # the bus's cycle wins
            merged.update(node_params(vehicle, name))
        for key, value in merged.items():       # copies: the YAML for rcl has no aliases
            set_param(vehicle, COMPUTER, key, copy.deepcopy(value))
    set_param(vehicle, MANAGER, 'node_names', list(CHAINS[layout]))
    return corners, vehicle


def start_vehicle(vehicle_cfg, out):
    """Write the vehicle's parameter file into ``out``; return its command-line arguments."""
    import yaml
    path = Path(out) / 'suite_params_vehicle.yaml'
    path.write_text(yaml.safe_dump(vehicle_cfg, sort_keys=False))
    return ['--ros-args', '--params-file', str(path)]


def chain_summary(manager):
    """Return the lifecycle manager's counts with ``first_up_s`` and ``ups`` (None: no status)."""
    counts = manager.get('counts')
    if counts is None:
        return None
    return {**counts, 'first_up_s': manager.get('first_up_s'), 'ups': manager.get('ups')}


def chain_statuses(st):
    """
    Return the bridge's, the estimator's and the controller's last status dicts (``{}``: none).

    ``st`` maps node -> status (the monitor's snapshot); the loop node's status holds the
    three as ``bridge``, ``estimator`` and ``controller``.
    """
    computer = st.get(COMPUTER)
    if computer:
        return tuple(computer.get(part) or {} for part in ('bridge', 'estimator', 'controller'))
    return st.get(BRIDGE) or {}, st.get(ESTIMATOR) or {}, st.get(CONTROLLER) or {}


def vehicle_progress_line(monitor, elapsed):
    """Return a progress line: the chain's states, cycles answered, car time."""
    st = monitor.snapshot()[0]
    chain = (st.get(MANAGER) or {}).get('state') or {}
    bridge, _, ctrl = chain_statuses(st)
    car = st.get(FULL_CAR) or {}
    cycles = bridge.get('cycles') or {}
    nodes = [n for n in (COMPUTER, BRIDGE, ESTIMATOR, CONTROLLER) if n in chain] or [BRIDGE]
    parts = ['chain ' + ','.join(f'{n.split("_")[1]} {chain.get(n, "?")}' for n in nodes),
             f'cycles {cycles.get("cycles_active", 0)} answered {cycles.get("answered", 0)} '
             f'on time {cycles.get("answered_in_time", 0)}',
             f'misses {(ctrl.get("deadline") or {}).get("deadline_misses", 0)}',
             f'corners normal {ctrl.get("corners_normal", "?")}']
    t_sim = car.get('t_sim')
    parts.append(f'car t {t_sim:.2f} s' if isinstance(t_sim, (int, float)) else 'car t ?')
    return f'[{elapsed:6.1f} s] ' + ' | '.join(parts)


def _offline_law(law, car_params, ctrl_params, road, dt):
    """
    Return the controller's ``law`` for an offline run on ``road``.

    The live preview law (``preview-look-ahead``) is fed offline by the car's look-ahead sensor
    model with the car node's settings (its parameter defaults where the run set none); any
    other law is its name.
    """
    from semi_active_control.runtime.live_preview import LIVE_PREVIEW_LAWS
    if str(law).strip().lower() not in LIVE_PREVIEW_LAWS:
        return law
    from quarter_car_sim.nodes.full_car_node import PARAMETERS
    from quarter_car_sim.plant.preview_sensor import PreviewFeed, SpeedSignal
    from quarter_car_sim.runtime.look_ahead import simulated_look_ahead
    from semi_active_control.car.full_car import PASSENGER_CAR
    from semi_active_control.laws.full_car_preview import (FedFullCarLaw,
                                                           make_full_car_preview_law)
    settings = {spec.name: spec.default for spec in PARAMETERS} | dict(car_params)
    sensor = simulated_look_ahead(settings, road)
    live = make_full_car_preview_law(
        PASSENGER_CAR, source='look-ahead',
        horizon_s=float((ctrl_params or {}).get('preview_horizon_s', 0.3)), dt=dt, name=law)
    return FedFullCarLaw(live, PreviewFeed(live.road, road, sensor.sensor.spec,
                                           SpeedSignal(float(settings['speed_error'])),
                                           rng=int(settings['preview_seed'])))


def _simulate_body(car_params, law, damper_files, t_end, dt, ctrl_params=None):
    """Simulate the body accelerations offline: ``law`` on the true states, the node's road."""
    from mr_damper_model.io.params_file import load_plant
    from quarter_car_sim.plant.two_track_road import make_two_track_road
    from quarter_car_sim.simulate.full_car import simulate_full_car
    from semi_active_control.car.full_car import PASSENGER_CAR
    g = car_params.get
    road = make_two_track_road(g('road', 'iso8608-C'), PASSENGER_CAR,
                               speed_m_s=float(g('speed_m_s', 20.0)),
                               duration_s=float(g('road_duration_s', 300.0)), dt=dt,
                               rng=int(g('road_seed', 1)))
    truths = g('truth_files') or [''] * 4
    plants = [load_plant(g('plant', 'spencer'), f or g('truth_file', '')) for f in truths]
    law = _offline_law(law, car_params, ctrl_params, road, dt)
    res = simulate_full_car(PASSENGER_CAR, road, law, plants, damper_files, dt=dt,
                            settle_s=float(g('settle_s', 0.5)), duration_s=t_end)
    return res.t, res.acc[:, :3]


def _a_v(t, acc):
    from quarter_car_sim.metrics.full_car import body_a_v
    return body_a_v(t, acc) if len(t) >= 10 else None


def vehicle_summary(monitor, vehicle_cfg, out, *, offline=True):
    """
    Return the summary's ``vehicle`` section.

    Parameters
    ----------
    monitor : mr_damper_bringup.monitor_node.Monitor
        The launcher's monitor (the nodes' last statuses).
    vehicle_cfg : dict
        The vehicle's parameter dict (:func:`vehicle_configs`).
    out : path
        Output folder (``full_car_body.npz`` is read from there).
    offline : bool
        Also simulate ``a_v_passive`` and ``a_v_lockstep`` (tens of seconds per minute of road).

    Returns
    -------
    dict
        ``control_cycles`` (sensor cycles the bridge received while active, the newest
        left out while in flight), ``answered_fraction`` (answered bus to bus within the cycle),
        ``unanswered``, ``deadline_misses`` (the controller's, with ``lateness``),
        ``driver_command_timeouts`` (after the vehicle computer took control, all drivers),
        ``sensor_to_command_s`` (``p50``, ``p99``, ``max`` [s]), ``reader_cpu_per_cycle_s``
        (the bridge's bus reader thread's CPU time per sensor cycle: ``p50``, ``p99``, ``max``,
        ``mean`` [s]; in the ``loop`` layout the whole control loop), ``frames_lost`` (bus frames
        the counters show missing: sensor and status frames at the bridge, command frames at
        the drivers), ``messages_lost`` (estimator and controller inputs, from sequence
        numbers), ``all_safe`` (controller commands with every corner safe, by reason),
        ``chain`` (the lifecycle manager's counts, with ``first_up_s``: from its start to the
        first time the whole chain was active, and ``ups``: times it came up), ``window_s``,
        ``a_v``, ``a_v_passive``, ``a_v_lockstep``, ``a_v_vs_lockstep`` (ratio - 1); with
        ``--preview``, ``preview`` (the controller's preview counters and the car's look-ahead
        sensor's); in the
        ``loop`` layout ``execution_s`` (the loop's execution times per stage:
        ``estimate``, ``control``, ``send``, each ``n``, ``p50_s``, ``p99_s``, ``max_s``),
        ``reception_s`` (the same of each cycle's bus time to the loop's start),
        ``cycles_queued`` (cycles whose frame came while the loop was on the one before) and
        ``loop_misses`` (the deadline supervision's misses of the loop's cycles, by cause:
        ``bunched``, ``queued``, ``reached_late``, ``slow``; :class:`~semi_active_control.
        runtime.VehicleLoop`).

    """
    st = monitor.snapshot()[0]
    bridge, est, ctrl = chain_statuses(st)
    car = st.get(FULL_CAR) or {}
    can = car.get('can') or {}
    cycles = bridge.get('cycles') or {}
    latency = bridge.get('latency') or {}
    deadline = ctrl.get('deadline') or {}
    timeouts = can.get('driver_timeouts_after_normal')
    drivers = can.get('corners') or {}
    section = {
        'control_cycles': bridge.get('control_cycles'),
        'answered_fraction': bridge.get('answered_fraction'),
        'answered_in_time': cycles.get('answered_in_time'),
        'unanswered': bridge.get('unanswered'),
        'deadline_misses': deadline.get('deadline_misses'),
        'deadline': {k: deadline.get(k) for k in ('cycles', 'lateness', 'entries',
                                                  'failsafe_s')},
        'driver_command_timeouts': (sum(timeouts.values()) if isinstance(timeouts, dict)
                                    else None),
        'driver_command_timeouts_by_corner': timeouts,
        'sensor_to_command_s': {'p50': latency.get('p50_s'), 'p99': latency.get('p99_s'),
                                'max': latency.get('max_s'), 'n': latency.get('n')},
        'reader_cpu_per_cycle_s': {k: (bridge.get('reader_cpu_s') or {}).get(f'{k}_s')
                                   for k in ('p50', 'p99', 'max', 'mean')},
        'frames_lost': {'sensor_and_status_frames': bridge.get('frames_lost'),
                        'command_frames': max((d.get('frames_missed') or 0
                                               for d in drivers.values()), default=None)},
        'messages_lost': {'chassis_sensors': (est.get('cycles') or {}).get('lost'),
                          'states': (ctrl.get('states') or {}).get('lost')},
        'all_safe': ctrl.get('all_safe'),
        'estimator': {k: est.get(k) for k in ('valid', 'faults', 'invalid_steps',
                                              'sensor_fault_entries', 'restarts')},
        'chain': chain_summary(st.get(MANAGER) or {}),
        't_normal': can.get('t_normal')}
    loop = (st.get(COMPUTER) or {}).get('loop') or {}
    if loop.get('execution_s'):
        def short(h):
            return {k: (h or {}).get(k) for k in ('n', 'p50_s', 'p99_s', 'max_s')}
        section['execution_s'] = {stage: short(h) for stage, h in loop['execution_s'].items()}
        section['reception_s'] = short(loop.get('reception_s'))
        section['cycles_queued'] = loop.get('cycles_queued')
        section['loop_misses'] = loop.get('misses')
    if ctrl.get('preview') is not None:        # --preview: the law's, map's, input's counters
        section['preview'] = dict(ctrl['preview'], sensor=car.get('road_preview'))
    section['frames_lost']['total'] = sum(v for v in section['frames_lost'].values()
                                          if isinstance(v, int))
    path = Path(out) / BODY_LOG
    if not path.is_file():
        section['note'] = f'no {BODY_LOG}: no a_v'
        return finite_or_none(section)
    with np.load(path) as z:
        t, acc = z['t'], z['acc']
    t0 = can.get('t_normal')
    t0 = float(t0) if isinstance(t0, (int, float)) and t0 == t0 else None
    if t0 is not None and len(t) and t[-1] <= t0 + 1.0:
        # the law had every corner only in the run's last second: too little ride to weigh
        section['note'] = 'every driver had a law command at once only in the last second'
        t0 = None
    if t0 is None:
        # the law never had every corner: the whole recorded ride (t >= 0) is compared
        section.setdefault('note', 'every driver never had a law command at once: whole run '
                                   'compared')
        t0 = 0.0
        if section['driver_command_timeouts'] is None:
            section['driver_command_timeouts'] = sum(d.get('command_timeouts') or 0
                                                     for d in drivers.values())
    if len(t) < 10 or t[-1] <= t0 + 1.0:
        section['note'] = f'{len(t)} body samples after t = {t0:g} s: no a_v'
        return finite_or_none(section)
    w = t >= t0
    section.update(window_s=[t0, float(t[-1])], a_v=_a_v(t[w], acc[w]))
    if offline:
        params = node_params(vehicle_cfg, FULL_CAR)
        ctrl_p = node_params(vehicle_cfg, CONTROLLER)
        dt = 1.0 / float(params.get('rate_hz', 1000.0))
        safe = float(ctrl_p.get('safe_current_a', 0.5))
        files = ctrl_p.get('model_files') or model_files()
        files = [f or m for f, m in zip(files, model_files())]
        for key, law in (('a_v_passive', f'passive@{safe:g}A'),
                         ('a_v_lockstep', ctrl_p.get('controller', 'modal-skyhook'))):
            t_o, acc_o = _simulate_body(params, law, files, float(t[-1]), dt, ctrl_p)
            wo = t_o >= t0
            section[key] = _a_v(t_o[wo], acc_o[wo])
        if section.get('a_v') and section.get('a_v_lockstep'):
            section['a_v_vs_lockstep'] = section['a_v'] / section['a_v_lockstep'] - 1.0
    return finite_or_none(section)
