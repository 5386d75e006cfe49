"""
``mr-damper-suite``: run the whole MR damper suite here, where ``ros2 launch`` does not exist.

Starts ``mr-damper-record`` (every topic into ``OUT/suite.mcap``) and the console scripts
``rig_node``, ``identifier_node`` and ``quarter_car_node`` of the venv with ONE parameter YAML
(``--ros-args --params-file FILE``), on loopback-only discovery
(:mod:`mr_damper_bringup.network`) and a domain ID of its own; prints progress from
the nodes' statuses, forwards Ctrl-C (SIGINT) to the children, shuts everything down in order
once the recording holds a status of every running node (car, rig, then the identifier once it
has drained the stream, the recorder last). At the end
it computes ``summary.json`` and plots into ``--out`` from the recording
(:mod:`mr_damper_bringup.report`).

A node that dies is restarted (:mod:`mr_damper_bringup.supervisor`) after a back-off that
starts at ``--restart-backoff-s`` and doubles with each further death of that node within
``--restart-window-s`` (at most ``--restart-backoff-max-s``); a node that dies more than
``--max-restarts`` times within the window ends the run (exit 1). Every restart is printed, kept
in ``restarts.json`` and listed in the summary with what it cost; a restarted recorder writes a
new part (``suite.1.mcap``, ...) and the report reads them all. ``pids.json`` holds the process
id of each node's latest start.

A node whose status (``/diagnostics``, about 1 Hz) stops for ``--hang-timeout-s`` (15 s; at
least three of its status periods) while its process, or its spin thread (its main thread,
whose executor publishes the status), is idle (frozen, e.g. a deadlock in the middleware; an
executor starved by a thread of its own), or for 40 times that while it keeps using CPU, is
hung: it is SIGKILLed and restarted like a dead node, with the reason ``hung`` in
``restarts.json`` (:class:`~mr_damper_bringup.supervisor.HangWatch`). A node is watched from
its first status after each start, never during its start-up.

The nodes die with the launcher: SIGTERM from the kernel when it dies, SIGKILL after 10 s from a
small watcher for those that ignore it (:mod:`mr_damper_bringup.processes`, ``reaper``). One
suite per ROS domain on this machine: a launcher whose ``--domain-id`` another suite here uses
(any of its processes still running) exits 2; without ``--domain-id`` it draws a free one.

DDS binds to loopback only: the nodes get ``FASTDDS_DEFAULT_PROFILES_FILE`` of
``config/fastdds_loopback.xml`` (UDPv4 on 127.0.0.1 and shared memory), unless the environment
already names a profile file or ``--dds-profile`` names another (or ``none``); those run with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (:mod:`mr_damper_bringup.network`).

Usage::

    .venv/bin/mr-damper-suite [--duration 30] [--out suite_out]

Slightly over the project's ~600 lines: the command line (every option with its help) and the
run's one sequence (start, watch, stop in order, report) read best in one place; supervision,
processes, network and report live in their own modules.
        [--config sim|replay|hil|can|full-car] [--file PATH ...]
        [--real-time | --faster | --rate-factor F]
        [--domain-id N] [--set NODE.PARAM=VALUE ...] [--no-plots] [--quiet]
        [--external-controller] [--sensing ideal|vehicle] [--corners fl,fr,rl,rr]
        [--max-restarts 3] [--restart-window-s 60] [--restart-backoff-s 0.5]
        [--restart-backoff-max-s 8] [--hang-timeout-s 15] [--dds-profile FILE|none]

``--external-controller`` (or ``quarter_car_node.controller: external`` in the YAML / --set)
also starts ``semi_active_controller_node`` (YAML key ``semi_active_controller``): the car is
then the plant only and its law runs in the controller node (docs/controller-node.md).

``--sensing vehicle`` also starts ``state_estimator_node`` (YAML key ``state_estimator``) before
the controller: the car publishes its modelled sensors and its true state on
``quarter_car/true_state``, the controller runs on the estimate (docs/sensing.md).

``--corners fl,fr`` runs one rig + identifier + car per car corner, each under its namespace
(``/fl/mr_damper/measurement``, status ``fl/mr_damper_identifier``, ...; :func:`~mr_damper_bringup.
config.corner_configs`), recorded into the one ``suite.mcap``; the summary then lists each
corner's figures from its nodes' diagnostics (no plots).

``--config full-car`` runs four rig + identifier pairs in ``fl``, ``fr``, ``rl``, ``rr`` and one
``full_car_node`` (the 7-DOF car on the four identified models, :mod:`mr_damper_bringup.
full_car_suite`); the summary adds a ``full_car`` section and ``body_modes.png``. With
``--external-controller`` the full car's law runs in the vehicle computer's
``vehicle_controller_node`` (brought up by ``lifecycle_manager``; one ``vehicle/state`` per
control cycle in, one ``vehicle/command`` out) and the car is the plant only; ``--preview``
runs the LQ road-preview law there on the look-ahead frames the car publishes
(docs/preview.md).

Exit status: 0 clean run (restarted nodes included), 1 a node died too often (or failed to shut
down, or no summary could be made), 2 bad command line / config.
"""
import argparse
import json
import os
from pathlib import Path
import random
import signal
import sys
import time

import yaml

from mr_damper_common.health import finite_or_none
from mr_damper_common.stop_flag import Interrupts

from .config import (corner_configs, CTRL, DOMAIN_IDS, IDENT, node_arguments, node_params, QC,
                     RECORDER, RECORDER_NODE, recorder_arguments, REPO, resolve_config, RIG,
                     suite_nodes, SuiteError)
from .full_car_suite import (BODY_LOG, FULL_CAR, FULL_CAR_CTRL_NODES, FULL_CAR_NODE,
                             external_full_car, full_car_configs,
                             full_car_progress_line, full_car_summary, start_full_car)
from .network import apply as apply_dds, dds_environment, PROFILE_VAR, RANGE_VAR
from .processes import CLEAN_EXIT, DomainLock, ProcessStats, Suite, wait_while_progressing
from .vehicle_suite import (LAYOUTS as VEHICLE_LAYOUTS, start_vehicle,
                            STOP_ORDER as VEHICLE_STOP_ORDER, vehicle_configs, vehicle_nodes,
                            vehicle_progress_line, vehicle_summary)
from .recorder import part_path, remove_recording
from .report import RECORDING
from .supervisor import HANG_TIMEOUT_S, hang_timeout, HangWatch, RestartPolicy, Supervisor

PROG = 'mr-damper-suite'
#: at the stop, the wait for the recording to hold every running node's status: given up when
#: the recorder's counts stand still this long [s], or after the guard [s] (hang guards)
STALL_S = 3.0
RECORDED_GUARD_S = 30.0


def progress_line(monitor, elapsed):
    """Return one progress line from the latest statuses (:class:`monitor_node.Monitor`)."""
    status, _, params, n_params, n_valid, metrics = monitor.snapshot()
    n_meas = (status.get('recorder') or {}).get('measurements', 0)
    ident = f'identifier {n_params} updates ({n_valid} valid)'
    if params is not None:
        ident += f', nrmse {params.get("nrmse_percent", float("nan")):.1f} %'
    car = 'quarter car: no status yet'
    qc = status.get('quarter_car') or {}
    if qc:
        car = (f'quarter car {qc.get("mode", "?")}'
               f'{" (" + str(qc.get("reason")) + ")" if qc.get("mode") == "failsafe" else ""}'
               f', t_sim {_num(qc.get("t_sim")):.1f} s'
               f', fail-safe {_num(qc.get("failsafe_s")):.1f} s'
               f', i {_num(qc.get("current_a")):.2f} A')
        wk = (metrics or {}).get('rms_body_accel_wk')
        if wk is not None:
            car += f', Wk {wk:.3f} m/s^2'
    ctrl = status.get('controller') or {}
    if ctrl:
        # the law runs in the controller node: its mode says whether it has a model (the car's
        # says only whether commands come), its count whether it commanded on one (a model
        # accepted before any car state arrived, as on a starved machine, commands nothing)
        car += (f' | controller {ctrl.get("mode", "?")}'
                + (f' ({ctrl.get("reason")})' if ctrl.get('mode') == 'failsafe' else '')
                + f', {int(ctrl.get("commands_normal") or 0)} commands on a model')
    return f'[{elapsed:6.1f} s] recorded {n_meas} samples | {ident} | {car}'


def _num(value):
    return float('nan') if value is None else float(value)


def identifier_drained(monitor, exact=True):
    """
    Return ``(done, progress)``: has the identifier taken every sample the recorder took.

    ``done`` once the recorder's measurement count stopped moving (its last two statuses agree)
    and the identifier's ``samples_received`` reached it; ``progress`` is both counts (None
    before the first statuses), so the wait goes on while either still moves. With ``exact``
    False (the identifier or the recorder was restarted: their counts started anew at different
    times and cannot be compared), ``done`` once both counts stopped moving.
    """
    status, history, *_ = monitor.snapshot()
    got = (status.get('identifier') or {}).get('samples_received')
    recs = [h.get('measurements') for h in history.get('recorder', ())]
    seen = recs[-1] if recs else None
    ok = isinstance(got, (int, float)) and isinstance(seen, (int, float))
    stable = len(recs) == 2 and recs[0] == recs[1]
    if not exact:
        ids = [h.get('samples_received') for h in history.get('identifier', ())]
        return ok and stable and len(ids) == 2 and ids[0] == ids[1], (got, seen)
    return ok and stable and got >= seen, (got, seen)


def corners_drained(monitor, corners):
    """
    Return ``(done, progress)`` for car corners (counts per namespace).

    ``done``: every corner's identifier took every sample the recorder took from that corner's
    rig, see :func:`identifier_drained`.
    """
    status, history, *_ = monitor.snapshot()
    recs = [h.get('measurements_by_namespace') or {} for h in history.get('recorder', ())]
    got = {c: (status.get(f'{c}/identifier') or {}).get('samples_received') for c in corners}
    seen = recs[-1] if recs else {}
    stable = len(recs) == 2 and recs[0] == recs[1]
    done = stable and all(isinstance(got[c], (int, float)) and got[c] >= seen.get(c, 0)
                          for c in corners)
    return done, (tuple(got.values()), tuple(sorted(seen.items())))


def corner_progress_line(monitor, elapsed, corners):
    """Return one progress line per run: each corner's samples, model and car mode."""
    status = monitor.snapshot()[0]
    parts = []
    for c in corners:
        ident = status.get(f'{c}/identifier') or {}
        qc = status.get(f'{c}/quarter_car') or {}
        parts.append(f'{c}: {ident.get("samples_received", 0)} samples, '
                     f'{ident.get("windows_valid", 0)} valid, car {qc.get("mode", "?")}')
    return f'[{elapsed:6.1f} s] ' + ' | '.join(parts)


def corner_summary(monitor, corners):
    """
    Return each corner's figures from the last diagnostics of its identifier and car.

    The counts of samples (recorded, received, lost: every life of the recorder and of the
    identifier) come from the recording afterwards (:func:`mr_damper_bringup.report.corners.
    add_corner_losses`); here ``samples_received`` is the identifier's last status only.
    """
    status = monitor.snapshot()[0]
    out = {}
    for c in corners:
        ident = status.get(f'{c}/identifier') or {}
        qc = status.get(f'{c}/quarter_car') or {}
        out[c] = {
            'samples_received': ident.get('samples_received'),
            'windows_valid': ident.get('windows_valid'),
            'last_nrmse_percent': ident.get('last_nrmse_percent'),
            'car_mode': qc.get('mode'), 'failsafe_s': qc.get('failsafe_s'),
            'params_accepted': qc.get('params_accepted'),
            'rms_body_accel_wk': (qc.get('ride_metrics') or {}).get('rms_body_accel_wk')}
    return out


def status_name(name):
    """Return the ``/diagnostics`` status name of suite node ``name`` (``fl.x`` -> ``fl/x``)."""
    return name.replace('.', '/')


def statuses_recorded(monitor, names):
    """
    Return ``(done, progress)``: does the recording hold a status of every node that sent one.

    ``names``: the suite nodes still running. ``done`` once each of them whose status reached
    the monitor also has one in the recording (the recorder's ``statuses``): a node started
    late on a loaded machine can be heard by the monitor seconds before the recorder has
    matched its publisher, and a stop then would leave it out of the recording. ``progress``
    is the recorder's counts, which move while it records.
    """
    beats, _ = monitor.heartbeats()
    status, *_ = monitor.snapshot()
    recorded = (status.get('recorder') or {}).get('statuses') or {}
    heard = {status_name(n) for n in names} & set(beats)
    return heard <= set(recorded), tuple(sorted(recorded.items()))


def feed_heartbeats(watch, monitor, names):
    """Give ``watch`` the monitor's heartbeats of the nodes ``names`` and its own progress."""
    beats, spun = monitor.heartbeats()
    if spun is not None:
        watch.listening(spun)
    for name in names:
        t = beats.get(status_name(name))
        if t is not None:
            watch.beat(name, t)


def supervise(suite, supervisor, recording, watch=None, monitor=None):
    """
    Restart the dead and hung nodes of ``suite`` as ``supervisor`` decides; False ends the run.

    A death is printed with the end of the node's log; a node whose heartbeat ``watch`` (fed
    from ``monitor``) calls hung is SIGKILLed (its process group) and counts as a death with
    the reason ``hung``; a restart is done once its back-off is over. A restarted recorder gets
    the next part of ``recording`` (never an earlier file).
    """
    now = time.monotonic()
    deaths = [(name, rc, 'died', None) for name, rc in suite.poll().items()
              if not supervisor.pending(name)]
    if watch is not None:
        for name in {d[0] for d in deaths} | suite.finished:
            watch.forget(name)
        feed_heartbeats(watch, monitor, suite.nodes)
        for name, silent, share, spin in watch.hung():
            watch.forget(name)
            if not suite.alive(name) or supervisor.pending(name):
                continue
            cpu = 'CPU unknown' if share is None else f'{100 * share:.1f} % CPU meanwhile'
            if spin is not None:
                cpu += f', its spin thread {100 * spin:.1f} %'
            print(f'{PROG}: {name} hung: no status for {silent:.1f} s ({cpu}; timeout '
                  f'{watch.timeouts.get(name, 0.0):g} s); killing it (SIGKILL); last lines of '
                  f'its log:\n{suite.log_tail(name)}', file=sys.stderr)
            rc = suite.kill(name, signal.SIGKILL)
            deaths.append((name, rc if rc is not None else -signal.SIGKILL, 'hung',
                           (silent, share, spin)))
    for name, rc, reason, hang in deaths:
        if reason == 'died':
            print(f'{PROG}: {name} died (exit {rc}); last lines of its log:\n'
                  f'{suite.log_tail(name)}', file=sys.stderr)
        silent, share, spin = hang or (None, None, None)
        if not supervisor.died(name, rc, now, epoch_s=time.time(), reason=reason,
                               silent_s=silent, cpu_share=share, spin_cpu_share=spin):
            gave = supervisor.gave_up
            what = 'died' if reason == 'died' else 'died or hung'
            print(f'{PROG}: {name} {what} {gave["deaths_in_window"]} times within '
                  f'{gave["restart_window_s"]:g} s: stopping the run', file=sys.stderr)
            return False
        print(f'{PROG}: restarting {name} in {supervisor.restarts[-1]["backoff_s"]:g} s',
              file=sys.stderr, flush=True)
    for name in supervisor.due(now):
        if name == RECORDER:
            args = [str(a) for a in suite.args[name]]
            k = 1 + sum(1 for r in supervisor.restarts
                        if r['node'] == name and r['restart_s'] is not None)
            args[args.index('--out') + 1] = str(part_path(recording, k))
            suite.args[name] = args
        if watch is not None:
            watch.started(name, time.monotonic())
        suite.start(name)
        r = supervisor.restarted(name, time.monotonic(), epoch_s=time.time())
        print(f'{PROG}: restarted {name} (restart {r["count"]}, pid {suite.pid(name)})',
              file=sys.stderr, flush=True)
    return True


def hang_timeouts(names, timeout_s, cfg, corners=None, car_cfg=None):
    """
    Return each node's heartbeat timeout [s] (:func:`~mr_damper_bringup.supervisor.hang_timeout`).

    ``timeout_s`` (``--hang-timeout-s``), or three periods of the node's own status
    (``diagnostics_period_s`` in its parameters: ``cfg``, its corner's in ``corners``, the
    full car's ``car_cfg``) if that is longer.
    """
    out = {}
    for name in names:
        corner, _, base = name.rpartition('.')
        src = ((corners or {}).get(corner) if corner
               else car_cfg if car_cfg is not None and base in (FULL_CAR, *FULL_CAR_CTRL_NODES)
               else cfg)
        params = node_params(src or {}, base)
        if corner:          # a corner's file keys its sections by the fully qualified name
            params.update(node_params(src or {}, f'/{corner}/{base}'))
        period = params.get('diagnostics_period_s')
        try:
            period = float(period) if period is not None else None
        except (TypeError, ValueError):
            period = None
        out[name] = hang_timeout(timeout_s, period)
    return out


def take_domain(requested=None, folder=None):
    """
    Return ``(domain_id, lock)``: the ROS domain of this run and its :class:`DomainLock`, held.

    Parameters
    ----------
    requested : int, optional
        ``--domain-id``: this one or an error. None: a random free one in
        :data:`~mr_damper_bringup.config.DOMAIN_IDS`.
    folder : path, optional
        Folder of the lock files (tests).

    Raises
    ------
    SuiteError
        When another suite on this machine uses the requested domain (or every one drawn).

    """
    if requested is not None:
        lock = DomainLock(requested, folder)
        if not lock.acquire():
            raise SuiteError(
                f'ROS_DOMAIN_ID {requested} is in use by another mr-damper-suite on this '
                f'machine (launcher pid {lock.holder()}, or nodes it left running): its nodes '
                'would share this run\'s topics and two controllers could command one damper; '
                'stop it or choose another --domain-id')
        return int(requested), lock
    ids = list(range(DOMAIN_IDS[0], DOMAIN_IDS[1] + 1))
    random.shuffle(ids)
    for domain_id in ids:
        lock = DomainLock(domain_id, folder)
        if lock.acquire():
            return domain_id, lock
    raise SuiteError(f'every ROS domain in {DOMAIN_IDS[0]}..{DOMAIN_IDS[1]} is in use by a '
                     'suite on this machine')


def parse_args(argv):
    """Parse the launcher's command line."""
    p = argparse.ArgumentParser(
        prog=PROG, description=__doc__.split('\n\n')[0].strip(),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--duration', type=float, default=30.0,
                   help='run time [s, wall clock] (default 30; 0 = until Ctrl-C)')
    p.add_argument('--out', default=str(REPO / 'runs' / 'suite'),
                   help='output folder (default runs/suite in the repository)')
    p.add_argument('--config', choices=('sim', 'replay', 'hil', 'can', 'full-car', 'vehicle'),
                   default='sim',
                   help='sim: virtual rig; replay: a CSV or bag replayed into the identifier; '
                        'hil: the rig follows the car (hardware in the loop, docs/hil.md); '
                        'can: sim with the damper current through a CAN bridge and a simulated '
                        'driver (docs/can.md); full-car: four rig / identifier pairs (fl, fr, '
                        'rl, rr) and the 7-DOF full_car_node (docs/full-car.md); vehicle: the '
                        'vehicle computer (bridge, estimator, controller) against the car on a '
                        'CAN bus (docs/vehicle.md)')
    p.add_argument('--live-identification', action='store_true',
                   help='vehicle: the models from four rig / identifier stacks instead of the '
                        'shipped end-of-line records')
    p.add_argument('--vehicle-layout', choices=VEHICLE_LAYOUTS, default='loop',
                   help='vehicle: the vehicle computer as one control loop in one process '
                        '(vehicle_computer_node, default) or as three nodes with a topic '
                        'between each (vehicle_bridge_node, vehicle_estimator_node, '
                        'vehicle_controller_node; docs/vehicle.md)')
    p.add_argument('--file', action='append',
                   help='replay input: a CSV (t,x,v,f,i) or rosbag2 folder; repeat for several '
                        'CSVs, concatenated (default: the Quiroz 10 mm 1 Hz set, 0..1 A)')
    p.add_argument('--params',
                   help='your own parameter YAML instead of config/suite_<config>.yaml')
    speed = p.add_mutually_exclusive_group()
    speed.add_argument('--real-time', dest='rate_factor', action='store_const', const=1.0,
                       help='rig and quarter car in real time (default of the YAML)')
    speed.add_argument('--faster', dest='rate_factor', action='store_const', const=2.0,
                       help='rig and quarter car at twice real time')
    speed.add_argument('--rate-factor', dest='rate_factor', type=float,
                       help='rig replay and quarter-car speed relative to real time')
    p.add_argument('--domain-id', type=int,
                   help='ROS_DOMAIN_ID of this run (default: random in 20..220)')
    p.add_argument('--set', action='append', metavar='NODE.PARAM=VALUE',
                   help='override one parameter (NODE is mr_damper_rig, mr_damper_identifier, '
                        'quarter_car_node or /**), YAML-typed: 1.0 is a float, 1 an int')
    p.add_argument('--bin-dir', help='folder of the node console scripts (default: the venv)')
    p.add_argument('--progress-s', type=float, default=5.0, help='progress line period [s]')
    p.add_argument('--external-controller', action='store_true',
                   help='run the car\'s law in semi_active_controller_node (full-car: '
                        'vehicle_controller_node on the car\'s vehicle/state); the car is the '
                        'plant only (controller:=external)')
    p.add_argument('--preview', action='store_true',
                   help='full-car / vehicle: the LQ road-preview law live '
                        '(preview-look-ahead in vehicle_controller_node; full-car: implies '
                        '--external-controller) on the look-ahead frames full_car_node '
                        'publishes (docs/preview.md)')
    p.add_argument('--sensing', choices=('ideal', 'vehicle'), default='ideal',
                   help='vehicle: the law runs on the state estimated from the car\'s modelled '
                        'sensors (state_estimator_node + semi_active_controller_node, '
                        'docs/sensing.md); ideal: on the true state')
    p.add_argument('--corners', type=lambda s: [c.strip() for c in s.split(',') if c.strip()],
                   help='run one rig + identifier + car per car corner, each in its namespace '
                        '(comma-separated subset of fl,fr,rl,rr)')
    for flag, kind, text in (
            ('--max-restarts', int, 'restarts of one node allowed within --restart-window-s; '
                                    'the next death ends the run (0: a death ends the run)'),
            ('--restart-window-s', float, 'window over which a node\'s deaths are counted [s]'),
            ('--restart-backoff-s', float, 'wait before restarting a dead node [s], doubled for '
                                           'each further death within the window'),
            ('--restart-backoff-max-s', float, 'longest wait before a restart [s]')):
        field = flag[2:].replace('-', '_').replace('restart_backoff', 'backoff')
        p.add_argument(flag, type=kind, default=getattr(RestartPolicy, field),
                       help=f'{text} (default %(default)s)')
    p.add_argument('--hang-timeout-s', type=float, default=HANG_TIMEOUT_S,
                   help='a node whose /diagnostics status stops this long [s] (at least three '
                        'of its status periods) while it is idle (its process or its spin '
                        'thread under 2 %% of a core), or 40 times as long while it '
                        'uses CPU, is hung: SIGKILLed and restarted, counted with the reason '
                        '"hung"; watched from its first status (0: no hang watch; default '
                        '%(default)s)')
    p.add_argument('--dds-profile', metavar='FILE|none',
                   help='Fast DDS XML profile of every node (default: $FASTDDS_DEFAULT_PROFILES_'
                        'FILE if set, else config/fastdds_loopback.xml: every DDS socket on '
                        '127.0.0.1); none: rmw\'s own transports; any profile but the shipped '
                        'one runs with LOCALHOST discovery')
    p.add_argument('--no-plots', action='store_true', help='summary.json only')
    p.add_argument('--quiet', action='store_true', help='no progress lines')
    args = p.parse_args(argv)
    if args.duration < 0:
        p.error('--duration must be >= 0')
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        p.error('--domain-id must be in 0..232')
    if args.preview and args.config not in ('full-car', 'vehicle'):
        p.error('--preview needs --config full-car or --config vehicle')
    if args.rate_factor is not None and not args.rate_factor > 0:
        p.error('--rate-factor must be > 0')
    if not args.hang_timeout_s >= 0:
        p.error('--hang-timeout-s must be >= 0')
    try:
        args.restart_policy = RestartPolicy(args.max_restarts, args.restart_window_s,
                                            args.restart_backoff_s, args.restart_backoff_max_s)
    except ValueError as exc:
        p.error(str(exc).replace('`', ''))
    return args


#: The files of ``--out`` a run writes, removed when it starts (:func:`clear_run_outputs`).
RUN_OUTPUTS = ('summary.json', 'process_stats.json', 'restarts.json', 'pids.json', BODY_LOG)


def clear_run_outputs(out):
    """
    Remove what an earlier run wrote into ``out`` that this one writes too.

    The recording (every part) and :data:`RUN_OUTPUTS`: a run that ends before it writes
    its own (a node that cannot start, a failed summary) leaves none, so no reader (a bench,
    the summary's body log) takes an earlier run's for it.
    """
    remove_recording(Path(out) / RECORDING)
    for name in RUN_OUTPUTS:
        (Path(out) / name).unlink(missing_ok=True)


def main(argv=None):
    """
    Run the suite; return the exit status.

    The domain's lock is let go of on every way out (the suite's processes keep their copies):
    a caller in the same process, as a test, may start another suite on that domain after an
    error (a test that ran ``main`` to a configuration error kept its drawn domain locked, and
    a CI run's later suites, drawn onto the same one, were refused).
    """
    held = []
    try:
        return _run(argv, held)
    finally:
        for lock in held:
            lock.release()


def _run(argv, held):
    """Run the suite (:func:`main`); append the domain's lock to ``held`` once taken."""
    args = parse_args(argv)
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    try:
        # first: a second launcher on a domain in use must not touch the running suite's files
        domain_id, lock = take_domain(args.domain_id)
        held.append(lock)
        args.domain_id = domain_id          # the CAN bus port of --config can follows it
        dds = dds_environment(args.dds_profile)
        cfg = resolve_config(args, out)
        corners = corner_configs(cfg, args.corners, out) if args.corners else {}
        full_car = args.config == 'full-car'
        if full_car:
            corners, car_cfg = full_car_configs(cfg, out, args.duration,
                                                external=args.external_controller,
                                                preview=args.preview)
        vehicle = args.config == 'vehicle'
        if vehicle:
            corners, car_cfg = vehicle_configs(cfg, out, args.duration, args.domain_id,
                                               args.live_identification,
                                               preview=args.preview,
                                               layout=args.vehicle_layout)
    except (SuiteError, ValueError) as exc:     # ValueError: DataError of a bad replay CSV
        print(f'{PROG}: {exc}', file=sys.stderr)
        return 2
    params_file = out / 'suite_params.yaml'
    params_file.write_text(yaml.safe_dump(cfg, sort_keys=False))
    recording = out / RECORDING
    clear_run_outputs(out)
    # the monitor node of this process must use the same discovery settings as the children
    apply_dds(dds)
    os.environ['ROS_DOMAIN_ID'] = str(domain_id)
    os.environ.setdefault('ROS_LOG_DIR', str(out / 'ros_log'))
    record_args = ['--out', recording, '--suite-config', params_file, *recorder_arguments(cfg)]
    if corners or vehicle:
        # the full car starts before the corners: on its safe currents until their models come
        # (with --external-controller the full car's controller before the car)
        ext_car = full_car and external_full_car(car_cfg)
        nodes = {**RECORDER_NODE, **(FULL_CAR_CTRL_NODES if ext_car else {}),
                 **(FULL_CAR_NODE if full_car else {}),
                 **(vehicle_nodes(args.vehicle_layout) if vehicle else {})}
        node_args = {}
        for corner, corner_cfg in corners.items():
            corner_file = out / f'suite_params_{corner}.yaml'
            corner_file.write_text(yaml.safe_dump(corner_cfg, sort_keys=False))
            record_args += ['--namespace', corner]
            for name, exe in suite_nodes(cfg).items():
                if (full_car or vehicle) and name not in (RIG, IDENT):
                    continue
                nodes[f'{corner}.{name}'] = exe
                node_args[f'{corner}.{name}'] = ['--ros-args', '-r', f'__ns:=/{corner}',
                                                 '--params-file', corner_file]
        node_args[RECORDER] = record_args
        if full_car:
            node_args[FULL_CAR] = start_full_car(car_cfg, out)
            if ext_car:
                node_args.update(dict.fromkeys(FULL_CAR_CTRL_NODES, node_args[FULL_CAR]))
        if vehicle:
            node_args.update(dict.fromkeys(vehicle_nodes(args.vehicle_layout),
                                           start_vehicle(car_cfg, out)))
        suite = Suite(params_file, out, domain_id, args.bin_dir, nodes, args=node_args,
                      keep_fds=(lock.fd,), dds=dds)
    else:
        suite = Suite(params_file, out, domain_id, args.bin_dir,
                      {**RECORDER_NODE, **suite_nodes(cfg)},
                      args={RECORDER: record_args, **node_arguments(cfg, params_file)},
                      keep_fds=(lock.fd,), dds=dds)
    watch = HangWatch(hang_timeouts(suite.nodes, args.hang_timeout_s, cfg, corners,
                                    car_cfg if full_car else None))
    print(f'{PROG}: config {args.config}, domain {domain_id}, '
          f'duration {args.duration:g} s, output {out}; DDS discovery '
          f'{dds[RANGE_VAR]}, profile {dds[PROFILE_VAR]}', flush=True)

    def kill_all():                    # second Ctrl-C: no more patience
        for name in suite.nodes:
            if suite.alive(name):
                suite.procs[name].kill()

    # no lock anywhere in the handler's path (stop_flag.Interrupts: an Event deadlocked here)
    interrupted = Interrupts(on_repeat=kill_all)
    old_int = signal.signal(signal.SIGINT, interrupted)
    old_term = signal.signal(signal.SIGTERM, interrupted)
    from .monitor_node import Monitor, start_monitor
    monitor = Monitor()
    stop_monitor = start_monitor(monitor)
    monitor_down = True
    status = 0
    codes = {}
    stats = None
    elapsed = None
    supervisor = None
    last_status = {}
    try:
        t_launch = time.monotonic()
        try:
            suite.start_all()
        except SuiteError as exc:
            print(f'{PROG}: {exc}', file=sys.stderr)
            return 2
        for name in suite.nodes:
            watch.started(name, t_launch)
        t_start = time.monotonic()
        supervisor = Supervisor(args.restart_policy, t_start)
        next_progress = args.progress_s
        stats = ProcessStats(suite, out)
        next_stats = 0.0
        while not interrupted.is_set():
            elapsed = time.monotonic() - t_start
            if args.duration and elapsed >= args.duration:
                break
            if not supervise(suite, supervisor, recording, watch, monitor):
                status = 1
                break
            if elapsed >= next_stats:
                stats.sample()
                for name, (t, seconds, main_thread) in stats.cpu_seconds.items():
                    watch.cpu(name, t, seconds, main_thread)
                next_stats += 1.0
            if not args.quiet and elapsed >= next_progress:
                print(full_car_progress_line(monitor, elapsed) if full_car
                      else vehicle_progress_line(monitor, elapsed) if vehicle
                      else corner_progress_line(monitor, elapsed, list(corners)) if corners
                      else progress_line(monitor, elapsed), flush=True)
                next_progress += args.progress_s
            interrupted.wait(0.1)
        if interrupted.is_set():
            print(f'{PROG}: interrupted, stopping the nodes', flush=True)
        elapsed = time.monotonic() - t_start
    finally:
        # the recording holds a status of every running node before any is stopped (a hang
        # guard only: a recorder that stopped recording ends the wait after STALL_S)
        wait_while_progressing(
            lambda: statuses_recorded(monitor, [n for n in suite.nodes if suite.alive(n)]),
            STALL_S, RECORDED_GUARD_S)
        if corners or vehicle:
            order = [*VEHICLE_STOP_ORDER[0]] + [
                f'{c}.{n}' for n in (QC, CTRL, RIG, IDENT) for c in corners]
            codes = suite.stop(order=order, then=VEHICLE_STOP_ORDER[1],
                               drained=lambda: corners_drained(monitor, list(corners)))
            summary = {'corners': corner_summary(monitor, list(corners))}
        else:
            exact = not any(r['node'] in (IDENT, RECORDER) for r in supervisor.restarts) \
                if supervisor is not None else True
            codes = suite.stop(drained=lambda: identifier_drained(monitor, exact))
        last_status = monitor.snapshot()[0]
        monitor_down = stop_monitor()
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)
    waiting = [n for n in codes if supervisor is not None and supervisor.pending(n)]
    for name in waiting:
        print(f'{PROG}: {name} was dead at the stop (its restart was pending)', file=sys.stderr)
    unclean = {n: rc for n, rc in codes.items() if rc not in CLEAN_EXIT and n not in waiting}
    if unclean:
        for name, rc in unclean.items():
            print(f'{PROG}: {name} exited with {rc}; last lines of its log:\n'
                  f'{suite.log_tail(name)}', file=sys.stderr)
        status = 1
    if stats is not None:
        stats.close()
        (out / 'process_stats.json').write_text(json.dumps(stats.summary(), indent=2))
    if supervisor is not None:
        (out / 'restarts.json').write_text(json.dumps(
            {'policy': vars(args.restart_policy), 'restarts': supervisor.restarts,
             'gave_up': supervisor.gave_up, 'exit_codes': codes}, indent=2))
    try:
        from . import report
        if corners or vehicle:
            from .report.corners import add_corner_losses
            summary.update(duration_s=elapsed, exit_codes={n: c for n, c in codes.items()})
            add_corner_losses(summary, out, {
                'restarts': supervisor.restarts if supervisor else [],
                'gave_up': supervisor.gave_up if supervisor else None})
            if full_car:
                summary['full_car'] = full_car_summary(monitor, summary['corners'], car_cfg,
                                                       out, plots=not args.no_plots)
            if vehicle:
                summary['vehicle'] = vehicle_summary(monitor, car_cfg, out)
            if corners:
                summary['control'] = report.control_from_recording(out, summary, list(corners))
            (out / 'summary.json').write_text(json.dumps(finite_or_none(summary), indent=2))
            for c, d in summary['corners'].items():
                print(f'{c}: {d}', flush=True)
            for line in report.restart_lines(summary):
                print(line, flush=True)
            if full_car:
                print(f'full_car: {json.dumps(finite_or_none(summary["full_car"]))}', flush=True)
            if 'control' in summary:
                print(report.format_control(summary['control']), flush=True)
            if vehicle:
                print(f'vehicle: {json.dumps(finite_or_none(summary["vehicle"]))}', flush=True)
        else:
            summary = report.make_report(out, duration_s=elapsed, plots=not args.no_plots,
                                         fallback={'config': cfg, 'status': last_status})
            print(report.format_summary(summary), flush=True)
    except Exception as exc:  # noqa: B902 - the run itself succeeded; say why there is no summary
        print(f'{PROG}: no summary: {type(exc).__name__}: {exc}', file=sys.stderr)
        status = status or 1
    print(f'{PROG}: outputs in {out} ({RECORDING}, summary.json, plots *.png, logs/)',
          flush=True)
    if not monitor_down:
        # the monitor's teardown is still stuck in the middleware: leave without the
        # interpreter's own (its exit would wait on the same locks)
        sys.stderr.flush()
        os._exit(status)
    return status


if __name__ == '__main__':
    sys.exit(main())
