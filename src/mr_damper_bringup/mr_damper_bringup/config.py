"""
The suite's configuration: the parameter YAMLs, the nodes they configure, one run's parameters.

The shipped configurations are ``config/suite_<sim|replay|hil|can>.yaml`` of this package (one
ROS 2 parameter file for every node: keys are the node names, ``/**`` is shared).
:func:`resolve_config` turns a command line (:mod:`mr_damper_bringup.launcher`) into the single
parameter dict of a run; :func:`node_params` is what one node sees of it.
"""
import math
from pathlib import Path
import random

import yaml

PACKAGE = 'mr_damper_bringup'
#: the source tree (editable install, the repository's layout)
REPO = Path(__file__).resolve().parents[3]


def _config_dir():
    """Return the folder of the shipped YAMLs: the source tree's, else the installed share."""
    here = Path(__file__).resolve().parents[1] / 'config'
    if here.is_dir():
        return here
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory(PACKAGE)) / 'config'


CONFIG_DIR = _config_dir()
#: node name (the YAML key) -> console script (the ``ros2 run`` executable), in start order
NODES = {'mr_damper_rig': 'rig_node', 'mr_damper_identifier': 'identifier_node',
         'quarter_car_node': 'quarter_car_node'}
RIG, IDENT, QC = NODES
#: the recorder (``mr-damper-record``: every topic into ``OUT/suite.mcap``), started first
RECORDER = 'mr_damper_record'
RECORDER_NODE = {RECORDER: 'mr-damper-record'}
#: the stand-alone controller node (started with ``--external-controller``)
CTRL = 'semi_active_controller'
CONTROLLER_NODE = {CTRL: 'semi_active_controller_node'}
#: the state estimator node (``--sensing vehicle``: the car publishes its sensors, the estimator
#: publishes the car state the controller node reads)
EST = 'state_estimator'
ESTIMATOR_NODE = {EST: 'state_estimator_node'}
#: car parameters the estimator takes over (control rate, fail-safe current, model timeout,
#: coil range, the car it assumes and the design road)
ESTIMATOR_PARAMS = ('rate_hz', 'safe_current_a', 'param_timeout_s', 'i_min_a', 'i_max_a', 'm_s',
                    'm_u', 'k_s', 'k_t', 'road_class', 'speed_m_s')
#: ``--config can``: the simulated damper driver (started first) and the CAN bridge (second)
CAN_DRIVER = 'can_driver_sim'
CAN_BRIDGE = 'can_bridge'
CAN_NODES = {CAN_DRIVER: 'can_driver_sim', CAN_BRIDGE: 'can_bridge_node'}
#: the bus of a CAN run: ``udp_loopback`` group and port ``CAN_PORT_BASE + domain id`` (one bus
#: per suite run, as one domain per run)
CAN_GROUP = '239.74.163.2'
CAN_PORT_BASE = 43300
#: the bridge's frame log of a CAN run, next to the recording
CAN_LOG = 'can.blf'
#: remaps of a CAN run: the car takes the driver's measured current as its command
CAN_REMAPS = {QC: ('mr_damper/current_command:=mr_damper/measured_current',)}
#: domain IDs drawn for a run without ``--domain-id`` (as the launcher draws them)
DOMAIN_IDS = (20, 220)
#: car parameters the controller node takes over when the law moves out of the car (``rate_hz``:
#: the control period of a filter inside the law, e.g. clipped-optimal-wk's Wk filter)
CONTROLLER_PARAMS = ('controller', 'controller_options', 'safe_current_a', 'param_timeout_s',
                     'min_current_span_a', 'hold_on_reject', 'i_min_a', 'i_max_a', 'rate_hz')
#: the measured damper data shipped in the repository (gzip-compressed DAQ CSVs)
QUIROZ_DIR = REPO / 'data' / 'quiroz_mr_damper'
DEFAULT_REPLAY = tuple(QUIROZ_DIR / f'quiroz_sine_10mm1Hz_{c}A_preproc.csv.gz'
                       for c in ('0', '0p25', '0p5', '0p75', '1p0'))


class SuiteError(Exception):
    """A bad command line or configuration (exit status 2)."""


def _parse_value(text):
    """Parse a --set value with YAML rules (1.0 float, 1 int, true bool, else string)."""
    value = yaml.safe_load(text)
    return text if value is None else value


def load_config(config='sim', params=None):
    """
    Load the suite parameter YAML.

    Parameters
    ----------
    config : {'sim', 'replay', 'hil', 'can', 'full-car'}
        Which shipped configuration (``config/suite_<config>.yaml`` of this package, ``-``
        read as ``_``).
    params : path, optional
        A parameter YAML of your own instead (same layout).

    Returns
    -------
    dict
        ``{node_name_or_/**: {'ros__parameters': {...}}}``.

    """
    path = Path(params) if params else CONFIG_DIR / f'suite_{config.replace("-", "_")}.yaml'
    try:
        cfg = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise SuiteError(f'cannot read parameter file {path}: {exc}') from None
    if not isinstance(cfg, dict):
        raise SuiteError(f'{path}: not a ROS 2 parameter file (top level is not a mapping)')
    for node in NODES:
        cfg.setdefault(node, {}).setdefault('ros__parameters', {})
    return cfg


def node_params(cfg, node):
    """Return the merged parameters a node sees (``/**`` section, then its own)."""
    merged = dict(cfg.get('/**', {}).get('ros__parameters', {}))
    merged.update(cfg.get(node, {}).get('ros__parameters', {}))
    return merged


def set_param(cfg, node, name, value):
    """Set ``node``'s parameter ``name`` (a node name or ``/**``) in the config dict."""
    cfg.setdefault(node, {}).setdefault('ros__parameters', {})[name] = value


def concatenate_csv(files, out_path):
    """Concatenate DAQ CSV files (header t,x,v,f,i) into one with continuous time."""
    from mr_damper_model.io.data import DamperData, read_csv, write_csv
    data = DamperData.concatenate([read_csv(f) for f in files], restamp=True)
    write_csv(out_path, data)
    return out_path


def resolve_config(args, out):
    """Build the single parameter dict of this run from the command line; write nothing."""
    cfg = load_config(args.config, args.params)
    qc = QC
    if args.rate_factor is not None:
        set_param(cfg, RIG, 'rate_factor', float(args.rate_factor))
        set_param(cfg, qc, 'real_time_factor', float(args.rate_factor))
    set_param(cfg, qc, 'log_file', str(out / 'quarter_car_log'))
    # the identifier saves its last good parameters here (and restarts from them); a new run
    # starts without them so that the time to the first valid model is measured honestly
    ident_file = out / 'identifier_params.json'
    if ident_file.exists():
        ident_file.unlink()
    set_param(cfg, IDENT, 'params_file', str(ident_file))
    # a run that outlasts the car's road drives it again (ISO 8608 roads repeat seamlessly):
    # memory stays one road length however long the run (held flat otherwise)
    factor = node_params(cfg, qc).get('real_time_factor', 1.0) or 20.0
    need = float(args.duration) * float(factor) + 10.0 if args.duration else math.inf
    if node_params(cfg, qc).get('road_duration_s', 300.0) < need:
        set_param(cfg, qc, 'road_repeat', True)
    if args.config == 'replay' or args.file:
        from mr_damper_model.io.data import is_csv
        files = [Path(f) for f in (args.file or DEFAULT_REPLAY)]
        for f in files:
            if not f.exists():
                raise SuiteError(f'--file {f}: no such file or directory')
        if len(files) > 1:
            for f in files:
                if not is_csv(f):
                    raise SuiteError(f'--file {f}: several files can only be CSV files')
            path = concatenate_csv(files, out / 'replay_input.csv')
            mode = 'csv'
        else:
            path = files[0]
            mode = 'csv' if is_csv(path) else 'bag'
        set_param(cfg, RIG, 'mode', mode)
        set_param(cfg, RIG, 'file', str(path.resolve()))
    for item in args.set or ():
        try:
            key, text = item.split('=', 1)
            node, name = key.rsplit('.', 1)
        except ValueError:
            raise SuiteError(f'--set {item!r}: expected NODE.PARAM=VALUE') from None
        set_param(cfg, node, name, _parse_value(text))
    if getattr(args, 'external_controller', False) or external_controller(cfg):
        use_external_controller(cfg)
    if args.config == 'can' or can_config(cfg):
        use_can(cfg, args, out)
    if getattr(args, 'sensing', 'ideal') == 'vehicle' or sensing_vehicle(cfg):
        use_vehicle_sensing(cfg)
    return cfg


def sensing_vehicle(cfg):
    """Return True when the law runs on estimated states (car ``sensing: vehicle``)."""
    return str(node_params(cfg, QC).get('sensing', '')).strip().lower() == 'vehicle'


def use_vehicle_sensing(cfg):
    """
    Run the law on the state estimated from the car's sensors (``--sensing vehicle``).

    The law moves into the controller node (:func:`use_external_controller`); the car publishes
    its sensors and its true state on ``quarter_car/true_state``; the estimator (its own
    section, the car's rate, fail-safe current, timeout, coil range and car parameters unless
    set there; stepped by the readings at their stamps, ``clock: readings``) publishes
    ``quarter_car/car_state`` for the controller. The car runs in lock-step with that chain
    unless ``lockstep`` is set (``--set quarter_car_node.lockstep=false``: real time): each
    step waits for the command answering its readings, so the estimator takes every reading
    and publishes an estimate for every car step (on a small shared machine the three 1 kHz
    Python nodes cannot keep real time; the summary gives the ratio of simulated to wall time).
    """
    use_external_controller(cfg)
    set_param(cfg, QC, 'sensing', 'vehicle')
    car = node_params(cfg, QC)
    if 'lockstep' not in car:
        set_param(cfg, QC, 'lockstep', True)
    own = cfg.setdefault(EST, {}).setdefault('ros__parameters', {})
    for name in ESTIMATOR_PARAMS:
        if name in car:
            own.setdefault(name, car[name])
    own.setdefault('clock', 'readings')


def external_controller(cfg):
    """Return True when the car's law runs in the controller node (``controller: external``)."""
    return str(node_params(cfg, QC).get('controller', '')).strip().lower() == 'external'


def use_external_controller(cfg):
    """Move the car's law into the controller node's section; the car becomes the plant."""
    car = node_params(cfg, QC)
    own = cfg.setdefault(CTRL, {}).setdefault('ros__parameters', {})
    for name in CONTROLLER_PARAMS:
        if name in car and not (name == 'controller' and external_controller(cfg)):
            own.setdefault(name, car[name])
    set_param(cfg, QC, 'controller', 'external')


def suite_nodes(cfg):
    """
    Return the nodes to start, in order.

    The controller before the car when external; with CAN (:func:`can_config`) the simulated
    driver and the bridge before all of them (the stop goes the other way round,
    :meth:`mr_damper_bringup.processes.Suite.stop`).
    """
    first = dict(CAN_NODES) if can_config(cfg) else {}
    if not external_controller(cfg):
        return {**first, **NODES}
    est = dict(ESTIMATOR_NODE) if sensing_vehicle(cfg) else {}
    return {**first, RIG: NODES[RIG], IDENT: NODES[IDENT], **est, **CONTROLLER_NODE,
            QC: NODES[QC]}


def can_config(cfg):
    """Return True when the run goes through the CAN bridge (a ``can_bridge`` section)."""
    return CAN_BRIDGE in cfg


def use_can(cfg, args, out):
    """
    Wire a run through CAN: controller -> bridge -> bus -> simulated driver -> car.

    The controller runs as its own node (:func:`use_external_controller`) and publishes
    ``mr_damper/current_command``, which the bridge sends as frames; the car applies the
    driver's measured current (``mr_damper/measured_current``, remapped by
    :func:`node_arguments`). Bridge and driver share one ``udp_loopback`` bus per run (port
    ``CAN_PORT_BASE`` + the domain ID, drawn here when ``--domain-id`` was not given), the
    bridge's fail-safe current is the car's, and the bridge logs every frame into
    ``OUT/can.blf``.

    Raises
    ------
    SuiteError
        With ``--corners`` (the CAN run has one corner, fl, in the root namespace).

    """
    if getattr(args, 'corners', None):
        raise SuiteError('--config can runs one corner (fl); --corners is not supported')
    if getattr(args, 'domain_id', None) is None:
        args.domain_id = random.randint(*DOMAIN_IDS)
    cfg.setdefault(CAN_BRIDGE, {}).setdefault('ros__parameters', {})
    use_external_controller(cfg)
    bus = {'interface': node_params(cfg, CAN_BRIDGE).get('interface', 'udp_loopback'),
           'channel': f'{CAN_GROUP}:{CAN_PORT_BASE + int(args.domain_id)}', 'corners': 'fl'}
    for node in CAN_NODES:
        for name, value in bus.items():
            set_param(cfg, node, name, value)
    set_param(cfg, CAN_DRIVER, 'sensor_source', 'car_state')
    set_param(cfg, CAN_BRIDGE, 'safe_current_a',
              float(node_params(cfg, QC).get('safe_current_a', 0.5)))
    set_param(cfg, CAN_BRIDGE, 'log_file', str(Path(out) / CAN_LOG))


def node_arguments(cfg, params_file):
    """
    Return the command lines of the nodes that need more than the parameter file.

    Returns
    -------
    dict
        node name -> arguments (``--ros-args --params-file FILE -r FROM:=TO ...``) of the nodes
        with remaps (a CAN run: the car, :data:`CAN_REMAPS`); the others get the default of
        :class:`mr_damper_bringup.processes.Suite`.

    """
    remaps = CAN_REMAPS if can_config(cfg) else {}
    return {node: ['--ros-args', '--params-file', str(params_file),
                   *[a for rule in rules for a in ('-r', rule)]]
            for node, rules in remaps.items()}


def recorder_arguments(cfg):
    """Return the recorder's extra options (``--can``: the bus topics; ``--sensing``)."""
    sensing = ['--sensing'] if sensing_vehicle(cfg) else []
    return (['--can'] if can_config(cfg) else []) + sensing


#: Car corners the launcher can run side by side, each under its namespace.
CORNERS = ('fl', 'fr', 'rl', 'rr')


def corner_configs(cfg, corners, out):
    """
    Split one run's parameters into one parameter dict per car corner (namespace).

    Each corner runs its own rig, identifier and car under ``/<corner>`` (topics
    ``/<corner>/mr_damper/...``); its sections are keyed by the fully qualified node names
    (``/fl/mr_damper_rig``), and what must differ between corners does: the rig's noise seed,
    the car's road seed (left and right wheels see different roads), the identifier's parameter
    file and the car's log file.

    Parameters
    ----------
    cfg : dict
        The run's parameters (:func:`resolve_config`).
    corners : sequence of str
        Corner names, a subset of :data:`CORNERS`, no repeats.
    out : path
        Output folder (per-corner files go there).

    Returns
    -------
    dict
        corner -> parameter dict (``{'/**': ..., '/fl/mr_damper_rig': ...}``).

    Raises
    ------
    SuiteError
        For an unknown or repeated corner.

    """
    corners = list(corners)
    bad = [c for c in corners if c not in CORNERS]
    if bad or len(set(corners)) != len(corners) or not corners:
        raise SuiteError(f'--corners {",".join(corners)}: use distinct names of '
                         f'{", ".join(CORNERS)}')
    out = Path(out)
    result = {}
    for k, corner in enumerate(corners):
        own = {'/**': {'ros__parameters': dict(cfg.get('/**', {}).get('ros__parameters', {}))}}
        for node in cfg:
            if node == '/**':
                continue
            params = dict(cfg[node].get('ros__parameters', {}))
            if node == RIG:
                params['seed'] = int(params.get('seed', 1)) + k
            elif node == IDENT:
                params['params_file'] = str(out / f'identifier_params_{corner}.json')
            elif node == QC:
                params['road_seed'] = int(params.get('road_seed', 1)) + k
                params['log_file'] = str(out / f'quarter_car_log_{corner}')
            own[f'/{corner}/{node}'] = {'ros__parameters': params}
        result[corner] = own
    return result
