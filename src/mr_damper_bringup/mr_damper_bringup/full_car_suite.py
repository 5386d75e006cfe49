"""
The full-car run of ``mr-damper-suite --config full-car``: configuration, progress, summary.

Four rig / identifier pairs run in the namespaces ``fl``, ``fr``, ``rl``, ``rr`` (as
``--corners fl,fr,rl,rr`` does, :func:`mr_damper_bringup.config.corner_configs`) and one
``full_car_node`` in the root namespace subscribes the four identified models and controls the
7-DOF car. The summary's ``full_car`` section (:func:`full_car_summary`) takes the node's final
status (``/diagnostics``) and its body log (``full_car_body.npz``), and compares the body's
ISO 2631-1 figures with the same car on the same road at the safe current, simulated offline
here with :func:`quarter_car_sim.simulate.full_car.simulate_full_car`.

With ``--external-controller`` the law runs in the vehicle computer's controller,
``vehicle_controller_node`` (root namespace; its four models from the corners' live
identifiers), brought up by ``lifecycle_manager``, and ``full_car_node`` is the plant only
(``controller: external``): one ``vehicle/state`` per control cycle (its true state) out, one
``vehicle/command`` (four currents) back, as on a vehicle (docs/vehicle.md) without the
sensors and the bus. The summary then takes the corners' parameter counts from the controller
and their modes from the car (the commands it applied).

With ``--preview`` (issue 36, docs/preview.md) the run is external and the controller runs
``preview-look-ahead`` (LQ road preview) on the frames ``full_car_node`` publishes on
``full_car/road_preview`` from its road through the look-ahead sensor model (``road_preview:
true``; the sensor's errors are the car node's ``preview_*`` and ``speed_error`` parameters);
the summary's ``full_car.preview`` holds the law's, the map's, the input's and the sensor's
counters (steps previewed, fallbacks by reason, frames lost).
"""
from pathlib import Path

import numpy as np

from mr_damper_common.health import finite_or_none

from .config import IDENT, node_params, QC, RIG, set_param

#: The full-car node's section name, console script and status key.
FULL_CAR = 'full_car_node'
FULL_CAR_NODE = {FULL_CAR: 'full_car_node'}
#: The external controller's section names (= node names, status keys): the vehicle
#: controller and the lifecycle manager that brings it up; with their console scripts.
FULL_CAR_CTRL, FULL_CAR_MANAGER = 'vehicle_controller', 'lifecycle_manager'
FULL_CAR_CTRL_NODES = {FULL_CAR_CTRL: 'vehicle_controller_node',
                       FULL_CAR_MANAGER: 'lifecycle_manager'}
#: Car parameters the controller node takes over with ``--external-controller``.
FULL_CAR_CTRL_PARAMS = ('controller', 'safe_current_a', 'param_timeout_s', 'i_min_a',
                        'i_max_a', 'min_current_span_a', 'hold_on_reject',
                        'diagnostics_period_s')
#: The live preview law of ``--preview``.
PREVIEW_LAW = 'preview-look-ahead'
#: The body log the node writes at its end.
BODY_LOG = 'full_car_body.npz'
#: The four corner namespaces.
FULL_CAR_CORNERS = ('fl', 'fr', 'rl', 'rr')


def full_car_configs(cfg, out, duration_s, external=False, preview=False):
    """
    Split a full-car run's parameters: one dict per corner (rig + identifier), one for the car.

    Parameters
    ----------
    cfg : dict
        The run's parameters (:func:`mr_damper_bringup.config.resolve_config` of
        ``config/suite_full_car.yaml``).
    out : path
        Output folder.
    duration_s : float
        Run time [s, wall clock] (0 = until stopped: a 600 s road, then held flat): the car's
        road and body log are made long enough.
    external : bool
        Run the law in ``vehicle_controller_node`` (its own section, the car's law and
        supervisor settings unless set there; every corner's model live, the control cycle the
        car's ``cycle_s``) brought up by ``lifecycle_manager``; the car becomes the plant
        (``controller: external``).
    preview : bool
        Run the LQ preview law live (implies ``external``): the car publishes its look-ahead
        frames (``road_preview: true``), the controller runs :data:`PREVIEW_LAW`.

    Returns
    -------
    corners : dict
        corner -> parameter dict of its rig and identifier (namespaced sections).
    car : dict
        The car node's parameter dict (``/**`` and ``full_car_node``; with ``external`` also
        ``vehicle_controller`` and ``lifecycle_manager``).

    """
    from .config import corner_configs
    stacks = {k: v for k, v in cfg.items() if k in ('/**', RIG, IDENT)}
    corners = corner_configs(stacks, FULL_CAR_CORNERS, out)
    car = {k: v for k, v in cfg.items() if k in ('/**', FULL_CAR)}
    if external or preview or external_full_car(car):
        car.update({k: v for k, v in cfg.items() if k in FULL_CAR_CTRL_NODES})
    if preview:
        set_param(car, FULL_CAR_CTRL, 'controller', PREVIEW_LAW)
        set_param(car, FULL_CAR, 'road_preview', True)
    if external or preview or external_full_car(car):
        law = node_params(car, FULL_CAR)
        own = car.setdefault(FULL_CAR_CTRL, {}).setdefault('ros__parameters', {})
        for name in FULL_CAR_CTRL_PARAMS:
            if name in law and not (name == 'controller' and external_full_car(car)):
                own.setdefault(name, law[name])
        set_param(car, FULL_CAR, 'controller', 'external')
        own['model_files'] = [''] * len(FULL_CAR_CORNERS)      # the live identifiers
        own.setdefault('cycle_s', float(node_params(car, FULL_CAR).get('cycle_s', 0.002)))
        manager = car.setdefault(FULL_CAR_MANAGER, {}).setdefault('ros__parameters', {})
        manager['node_names'] = [FULL_CAR_CTRL]
    set_param(car, FULL_CAR, 'log_file', str(Path(out) / BODY_LOG))
    qc_speed = node_params(cfg, QC).get('real_time_factor')   # set by --rate-factor
    if qc_speed is not None:
        set_param(car, FULL_CAR, 'real_time_factor', float(qc_speed))
    params = node_params(car, FULL_CAR)
    rtf = float(params.get('real_time_factor', 1.0)) or 20.0
    need = float(duration_s) * rtf + 30.0 if duration_s else 600.0
    if float(params.get('road_duration_s', 300.0)) < need:
        set_param(car, FULL_CAR, 'road_duration_s', min(need, 3600.0))
    set_param(car, FULL_CAR, 'log_max_s', min(need, 3600.0))
    return corners, car


def external_full_car(car_cfg):
    """Return True when the full car's law runs in the controller node."""
    law = str(node_params(car_cfg, FULL_CAR).get('controller', ''))
    return law.strip().lower() == 'external'


def start_full_car(car_cfg, out):
    """Write the car node's parameter file into ``out``; return its command-line arguments."""
    import yaml
    path = Path(out) / 'suite_params_full_car.yaml'
    path.write_text(yaml.safe_dump(car_cfg, sort_keys=False))
    return ['--ros-args', '--params-file', str(path)]


def _finite(value):
    # a number that is finite (NaN = never; the diagnostics' JSON may also carry None)
    return isinstance(value, (int, float)) and finite_or_none(value) is not None


def full_car_progress_line(monitor, elapsed):
    """Return a progress line: per corner samples, valid sets, mode; corners on models; car t."""
    status = monitor.snapshot()[0]
    st = status.get(FULL_CAR) or {}
    car = st.get('corners') or {}           # external: the modes of the commands applied
    parts = []
    for c in FULL_CAR_CORNERS:
        ident = status.get(f'{c}/identifier') or {}
        parts.append(f'{c}: {ident.get("samples_received", 0)} samples, '
                     f'{ident.get("windows_valid", 0)} valid, car '
                     f'{(car.get(c) or {}).get("mode", "?")}')
    # corners whose law has commanded on a model (first_normal_t_sim finite; never reverts)
    on_models = sum(_finite((car.get(c) or {}).get('first_normal_t_sim'))
                    for c in FULL_CAR_CORNERS)
    parts.append(f'on models {on_models}/{len(FULL_CAR_CORNERS)}')
    law = ((status.get(FULL_CAR_CTRL) or {}).get('preview') or {}).get('law')
    if law:
        parts.append(f'preview {law.get("previewed_steps", 0)} steps, fallback '
                     f'{law.get("fallback_steps", 0)}')
    t_sim = st.get('t_sim')
    parts.append(f'car t {t_sim:.2f} s' if isinstance(t_sim, (int, float)) else 'car t ?')
    return f'[{elapsed:6.1f} s] ' + ' | '.join(parts)


def passive_body(car_params, t_end, dt, current=None):
    """
    Simulate the car at its safe current (or ``current``) on the node's road and plants, offline.

    Parameters
    ----------
    car_params : dict
        The full-car node's parameters (road, speed_m_s, road_seed, road_duration_s, plant,
        truth_file, safe_current_a, settle_s, rate_hz).
    t_end : float
        Last recorded time [s].
    dt : float
        Control period [s].
    current : float, optional
        Coil current of all four dampers [A] (default: the node's ``safe_current_a``).

    Returns
    -------
    t : ndarray (n,)
    acc : ndarray (n, 3)
        Body heave, pitch and roll accelerations.

    """
    from mr_damper_model.io.params_file import load_plant
    from quarter_car_sim.plant.two_track_road import make_two_track_road
    from quarter_car_sim.simulate.full_car import simulate_full_car
    from semi_active_control.runtime.full_car_controller_core import FullCarController
    from semi_active_control.laws.registry import make_full_car_law
    from semi_active_control.car.full_car import PASSENGER_CAR
    from quarter_car_sim.simulate.full_car import OFFLINE_TIMEOUT_S
    g = car_params.get
    safe = float(g('safe_current_a', 0.5) if current is None else current)
    road = make_two_track_road(g('road', 'iso8608-C'), PASSENGER_CAR,
                               speed_m_s=float(g('speed_m_s', 20.0)),
                               duration_s=float(g('road_duration_s', 300.0)), dt=dt,
                               rng=int(g('road_seed', 1)))
    plants = [load_plant(g('plant', 'spencer'), g('truth_file', '')) for _ in range(4)]
    ctrl = FullCarController(make_full_car_law(f'passive@{safe:g}A', PASSENGER_CAR),
                             timeout_s=OFFLINE_TIMEOUT_S, safe_current_a=safe,
                             i_min_a=PASSENGER_CAR.i_min, i_max_a=PASSENGER_CAR.i_max)
    res = simulate_full_car(PASSENGER_CAR, road, None, plants, dt=dt,
                            settle_s=float(g('settle_s', 0.5)), controller=ctrl,
                            duration_s=t_end)
    return res.t, res.acc[:, :3]


def _iso(t, acc):
    from quarter_car_sim.metrics.full_car import iso2631_seat
    if len(t) < 2:
        return None
    m = iso2631_seat(t, acc[:, 0], acc[:, 1], acc[:, 2])
    m['duration_s'] = float(t[-1] - t[0])
    return m


def full_car_summary(monitor, corners_summary, car_cfg, out, *, plots=True):
    """
    Return the summary's ``full_car`` section (and write ``body_modes.png`` with ``plots``).

    Parameters
    ----------
    monitor : mr_damper_bringup.monitor_node.Monitor
        The launcher's monitor (last statuses).
    corners_summary : dict
        :func:`mr_damper_bringup.launcher.corner_summary` of the four corners (identifier
        counts, samples lost).
    car_cfg : dict
        The car node's parameter dict (:func:`full_car_configs`).
    out : path
        Output folder (``full_car_body.npz`` is read from there).
    plots : bool
        Also plot the body accelerations against passive.

    Returns
    -------
    dict
        ``corners`` {corner: ``windows_valid``, ``samples_lost``, ``params_accepted``,
        ``params_rejected``, ``failsafe_s``, ``first_normal_t_sim``, ``mode``},
        ``controller``, ``steps``, ``iso2631`` (the node's figures of the whole run, body
        centre), ``live`` / ``passive`` / ``passive_0a`` (ISO 2631-1 of the body log, of the
        safe current and of 0 A, the softest setting, offline, on the window after all four
        corners were first normal, ``window_s``), ``passive_current_a``, ``plot``.

    """
    out = Path(out)
    statuses = monitor.snapshot()[0]
    st = statuses.get(FULL_CAR) or {}
    car_corners = st.get('corners') or {}
    ctrl = statuses.get(FULL_CAR_CTRL) if external_full_car(car_cfg) else None
    # the models (parameter counts) are the controller's when external; the modes, the
    # first normal step and the time in fail-safe the car's (the commands it applied)
    models = (ctrl.get('corners') or {}) if ctrl is not None else car_corners
    section = {'controller': st.get('controller'), 'steps': st.get('steps'),
               'corners_normal': st.get('corners_normal'), 'iso2631': st.get('iso2631'),
               'dropped': st.get('dropped'), 'corners': {}}
    if ctrl is not None:
        section['controller'] = ctrl.get('controller')
        section['external_controller'] = {
            'states_answered': ctrl.get('states_answered'), 'commands': ctrl.get('commands'),
            'states': ctrl.get('states'), 'all_safe': ctrl.get('all_safe'),
            'deadline_misses': (ctrl.get('deadline') or {}).get('deadline_misses'),
            'dropped': ctrl.get('dropped'), 'car_states': st.get('vehicle_states'),
            'car_commands': st.get('commands'),
            'car_lockstep_timeouts': st.get('lockstep_timeouts'),
            'car_command_timeouts': {c: (car_corners.get(c) or {}).get('command_timeouts')
                                     for c in FULL_CAR_CORNERS}}
        if ctrl.get('preview') is not None:
            section['preview'] = dict(ctrl['preview'], sensor=st.get('road_preview'))
    for c in FULL_CAR_CORNERS:
        d = car_corners.get(c) or {}
        m = models.get(c) or {}
        ident = corners_summary.get(c) or {}
        section['corners'][c] = {
            'windows_valid': ident.get('windows_valid'),
            'samples_lost': ident.get('samples_lost'),
            'params_accepted': m.get('params_accepted'),
            'params_rejected': m.get('params_rejected'),
            'failsafe_s': d.get('failsafe_s'),
            'first_normal_t_sim': d.get('first_normal_t_sim'), 'mode': d.get('mode')}
    path = out / BODY_LOG
    if not path.is_file():
        section['note'] = f'no {BODY_LOG}: no live / passive comparison'
        return section
    with np.load(path) as z:
        t, acc = z['t'], z['acc']
    if len(t) < 10:
        section['note'] = f'{BODY_LOG} holds {len(t)} samples: no comparison'
        return section
    params = node_params(car_cfg, FULL_CAR)
    dt = 1.0 / float(params.get('rate_hz', 1000.0))
    t_p, acc_p = passive_body(params, float(t[-1]), dt)
    firsts = [section['corners'][c]['first_normal_t_sim'] for c in FULL_CAR_CORNERS]
    firsts = [f for f in firsts if _finite(f)]
    t0 = max(max(firsts), 0.0) if len(firsts) == 4 else 0.0
    live_w, pas_w = t >= t0, t_p >= t0
    t_0a, acc_0a = passive_body(params, float(t[-1]), dt, current=0.0)
    soft_w = t_0a >= t0
    section.update(window_s=[t0, float(t[-1])], live=_iso(t[live_w], acc[live_w]),
                   passive=_iso(t_p[pas_w], acc_p[pas_w]),
                   passive_0a=_iso(t_0a[soft_w], acc_0a[soft_w]),
                   passive_current_a=float(params.get('safe_current_a', 0.5)))
    if len(firsts) < 4:
        section['note'] = 'not every corner left fail-safe: the whole run is compared'
    if plots:
        from .plots import plot_body_modes
        section['plot'] = str(plot_body_modes(out / 'body_modes.png', t, acc, t_p, acc_p,
                                              st.get('controller') or 'live', t0))
    return section
