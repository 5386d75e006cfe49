"""
Summary and plots of one suite run (``mr-damper-suite``), without ROS.

Inputs, in the run's output folder:

- ``suite.mcap``: the run's one recording (``mr-damper-record``, :mod:`mr_damper_bringup.
  recorder`): every suite topic with its receive time, and on ``/mr_damper/suite_config`` the
  parameter YAML the nodes were started with, and on ``/mr_damper/node_parameters`` the
  parameters each node reported running with (defaults included; :func:`effective_config`
  merges both, so the settings are the nodes' own; the fallback values in this module only
  matter for a recording without them). :func:`read_recording` reads it back in one streamed
  pass (rosbags): measurements into a temporary column log (t, x, v, f, i and the
  receive time), parameter messages into a temporary JSON-lines file, and the bounded rest
  (counters, true parameters, the last status of each node, the last ride metrics);
- ``quarter_car_log.f64/.json``: column log of every control step of the quarter-car node
  (``live_loop.TRACE_COLUMNS``), streamed by the node; its header holds ``dt`` and the final
  status;
- ``process_stats.json`` (optional): CPU and memory of the processes (the launcher).

Memory is bounded for runs of any length: every figure over the whole record is computed in
streamed passes over the files (chunks of 65,536 rows); plots and the offline best fit use at
most a few hundred thousand evenly spaced rows; percentiles of loop timing use at most two
million evenly spaced periods (every period up to ~33 minutes at 1 kHz).

Outputs: ``summary.json`` (keys below) and, with ``plots=True``, ``hysteresis.png`` (measured
force against velocity and displacement per current level, with the final identified model on
the same samples), ``convergence.png`` (parameters and identification error over time) and
``ride.png`` (body acceleration of the live controller and of the passive damper on the same
road, coil current command, fail-safe periods).

``summary.json`` keys: ``duration_s``; ``identification`` {``rmse_n``, ``nrmse_percent`` (final
valid model on every recorded measurement), ``updates``, ``valid_updates``, ``first_valid_s``
(wall seconds from the recorder's start), ``parameters``, ``truth``, ``history``, ...};
``ride`` {``skyhook`` (the live controller, whatever its name), ``passive`` (the safe current on
the same road, seed and plant, simulated offline here), ``passive_0a`` (the softest setting,
best for comfort), same metric keys, ``window_s``};
``failsafe_s``; ``messages_lost`` (total) and ``messages`` (breakdown); ``loop`` (timing).

Command line (regenerate from a finished run): ``python -m mr_damper_bringup.report OUT``.
"""
from array import array
import json
import math
from pathlib import Path
import sys
import tempfile

import numpy as np

from mr_damper_model.io.columnlog import (ArrayLog, ColumnReader, ColumnWriter, exists,
                                          finite_or_none, JsonLines, open_log)
from mr_damper_model.models.kwok_current import KwokCurrent, kwok_current_force
from mr_damper_model.live.sample_stream import BatchIndex

from .config import IDENT, node_params, QC, RIG
from .topics import (CAN_TOPICS, CONFIG_TOPIC, decode_parameters, decode_status,
                     NODE_PARAMETERS_TOPIC, SENSING_TOPICS, STATUS_KEYS, SUITE_TOPICS)

KWOK_CURRENT_NAMES = KwokCurrent.param_names
#: file name of the run's recording in the output folder
RECORDING = 'suite.mcap'
MEAS_COLUMNS = ('t', 'x', 'v', 'f', 'i', 'recv_epoch_s')


def read_recording(path, work, *, identifier_starts=(), car_modes_from=None):
    """
    Read a suite recording back in one streamed pass (bounded memory).

    Each file is read front to back (``mr_damper_model.io.mcap_scan.McapScan``, messages in the
    order the recorder wrote them), a file whose recorder was killed up to its last complete
    chunk.

    Parameters
    ----------
    path : str or Path, or a list of them
        The ``suite.mcap`` file, or the parts of a recording (a restarted recorder writes a new
        part, ``recorder.recording_parts``), read one after the other.
    work : str or Path
        Folder for the streamed extracts: column log ``measurement`` (:data:`MEAS_COLUMNS`,
        ``recv_epoch_s`` = receive time [s]) and ``parameters.jsonl`` (``[t_s, dict]`` per
        message, ``t_s`` seconds since the recording started, the dict with ``recv_epoch_s``).
    identifier_starts : sequence of float, optional
        Epoch times [s] the identifier was restarted at (the launcher's record): a count after
        one belongs to a new life, even when the recorder missed the new life's first counts.
    car_modes_from : float, optional
        Epoch time [s] from which the car states are decoded into ``car_modes`` (the first
        death of a node; None: not at all, a 1 kHz topic the rest of the report does not need).

    Returns
    -------
    dict
        ``config`` (the parameter dict the suite ran with, or None), ``node_parameters``
        (node -> the parameters it reported running with, its defaults included), ``truth``,
        ``truth_spencer`` (decoded true parameters), ``status`` (last status per node),
        ``status_messages``, ``ride_metrics`` (last), ``topic_messages`` (messages per topic
        key), ``parameter_messages``, ``measurements_received``, ``measurement_gaps`` (samples
        missing between consecutive stamps), ``measurement_out_of_order``, ``undecodable``
        (messages per key whose payload did not decode), ``start_epoch_s``, ``end_epoch_s``,
        ``parts`` (per file: ``complete``, ``messages``, first and last log time, ``error``;
        ``McapScan.summary``), ``identifier_lives`` (the identifier's ``samples_received``
        counts, one entry per process life: a count after a restart in ``identifier_starts``
        or one that goes down starts a life; ``counts``: its ``(t, count)`` series),
        ``gap_events`` (``(receive time, samples missing)`` of each stamp gap) and
        ``car_modes`` (runs ``[first_s, last_s, fail_safe_mode]`` of the car state, split at a
        mode change or a silence longer than :data:`CAR_STATE_GAP_S`; receive times [s]).

    """
    import yaml

    from mr_damper_model.io.bag_types import suite_typestore
    from mr_damper_model.io.mcap_scan import McapScan
    from .topics import decode_measurement
    work = Path(work)
    tables = {**SUITE_TOPICS, **CAN_TOPICS, **SENSING_TOPICS}
    keys = {row.name: key for key, row in tables.items()}
    keys[CONFIG_TOPIC.name] = 'config'
    keys[NODE_PARAMETERS_TOPIC.name] = 'node_parameters'
    rec = {'config': None, 'node_parameters': {}, 'truth': None, 'truth_spencer': None,
           'status': {}, 'status_messages': {}, 'ride_metrics': None, 'topic_messages': {},
           'parameter_messages': 0, 'measurements_received': 0, 'measurement_gaps': 0,
           'measurement_out_of_order': 0, 'undecodable': {}, 'start_epoch_s': None,
           'end_epoch_s': None, 'parts': [], 'identifier_lives': [], 'car_modes': [],
           'gap_events': []}
    meas = ColumnWriter(work / 'measurement', MEAS_COLUMNS, chunk_rows=4096)
    params = JsonLines(work / 'parameters.jsonl')
    gaps = _Gaps()
    typestore = suite_typestore()
    try:
        for part in (path if isinstance(path, (list, tuple)) else [path]):
            reader = McapScan(part)
            for topic, msgtype, t_ns, raw in reader.messages(keys):
                key = keys[topic]
                t_rx = t_ns * 1e-9
                if rec['start_epoch_s'] is None:
                    rec['start_epoch_s'] = t_rx
                rec['end_epoch_s'] = t_rx
                rec['topic_messages'][key] = rec['topic_messages'].get(key, 0) + 1
                if key not in ('measurement', 'parameters', 'truth', 'truth_spencer',
                               'config', 'node_parameters', 'samples_received', 'car_state',
                               *STATUS_KEYS) or (key == 'car_state' and (
                                   car_modes_from is None or t_rx < car_modes_from)):
                    continue
                msg = reader.deserialize(raw, msgtype, typestore)
                try:
                    if key == 'measurement':
                        sample = decode_measurement(msg)
                    elif key == 'samples_received':
                        _count_lives(rec['identifier_lives'], t_rx, int(msg.data),
                                     identifier_starts)
                        continue
                    elif key == 'car_state':
                        _mode_runs(rec['car_modes'], t_rx, int(msg.fail_safe_mode))
                        continue
                    elif key == 'config':
                        rec['config'] = yaml.safe_load(msg.data)
                        continue
                    elif key == 'node_parameters':
                        for node, section in yaml.safe_load(msg.data).items():
                            rec['node_parameters'][node] = section['ros__parameters']
                        continue
                    elif key in ('parameters', 'truth', 'truth_spencer'):
                        d = decode_parameters(msg)
                    else:
                        for node, d in decode_status(key, msg).items():
                            rec['status'][node] = d
                            rec['status_messages'][node] = \
                                rec['status_messages'].get(node, 0) + 1
                            if node == 'quarter_car' and d.get('ride_metrics'):
                                rec['ride_metrics'] = d['ride_metrics']
                        continue
                except (ValueError, yaml.YAMLError, AttributeError, KeyError, TypeError):
                    rec['undecodable'][key] = rec['undecodable'].get(key, 0) + 1
                    continue
                if key == 'parameters':
                    d['recv_epoch_s'] = t_rx
                    params.append([t_rx - rec['start_epoch_s'], d])
                    rec['parameter_messages'] += 1
                elif key != 'measurement':
                    rec[key] = d
                else:
                    missing = rec['measurement_gaps']
                    _take_measurement(rec, gaps, sample, getattr(msg, 'first_index', None),
                                      meas, t_rx)
                    if rec['measurement_gaps'] > missing:
                        rec['gap_events'].append((t_rx, rec['measurement_gaps'] - missing))
            rec['parts'].append(reader.summary())
    finally:
        meas.close()
        params.close()
    return rec


#: a silence of the car state longer than this [s] ends a run of its mode (the car was down)
CAR_STATE_GAP_S = 0.5


def _count_lives(lives, t, count, starts=()):
    """
    Add one count of a process's counter at ``t`` to its ``lives``.

    A count that goes down, or the first count after a (re)start time in ``starts``, starts a
    new life.
    """
    if (not lives or count < lives[-1]['last_count']
            or any(lives[-1]['last_s'] < t0 <= t for t0 in starts)):
        lives.append({'first_s': t, 'first_count': count, 'last_s': t, 'last_count': count,
                      'counts': [(t, count)]})
    else:
        lives[-1].update(last_s=t, last_count=count)
        lives[-1]['counts'].append((t, count))


def _received_between(lives, a, b):
    """Return the samples the identifier's lives counted in ``(a, b]`` (count at b less at a)."""
    def at(life, t):
        got = [c for tc, c in life['counts'] if tc <= t]
        return got[-1] if got else 0
    return sum(at(life, b) - at(life, a) for life in lives)


def _mode_runs(runs, t, mode):
    """Add one car state's mode at ``t`` to the runs ``[first_s, last_s, mode]``."""
    if runs and t - runs[-1][1] <= CAR_STATE_GAP_S:
        if runs[-1][2] == mode:
            runs[-1][1] = t
            return
        runs[-1][1] = t                # contiguous: the previous mode lasted until now
    runs.append([t, t, mode])


class _Gaps:
    """Samples missing from the recorded measurement stream (see :func:`_take_measurement`)."""

    def __init__(self):
        self.index = BatchIndex()
        self.last_t = None
        self.dt = None


def _take_measurement(rec, gaps, cols, first_index, meas, t_rx):
    """
    Append one recorded measurement message (arrays ``t, x, v, f, i``) to the column log.

    Samples not after the newest kept stamp are counted (``measurement_out_of_order``) and
    left out. Missing samples (``measurement_gaps``) are counted exactly from the batches'
    stream index (``first_index``); for single-sample JointState recordings, from stamp steps
    longer than 1.5 sample periods (the period: the shortest step of the first 20 samples).
    """
    t = cols[0]
    prev = -np.inf if gaps.last_t is None else gaps.last_t
    keep = t > np.maximum.accumulate(np.concatenate(([prev], t)))[:-1]
    rec['measurement_out_of_order'] += int(keep.size - np.count_nonzero(keep))
    if not keep.any():
        return
    if first_index is not None:
        rec['measurement_gaps'] += gaps.index.update(first_index, t.size)
    else:
        t0 = float(t[keep][0])
        if gaps.last_t is not None:
            step = t0 - gaps.last_t
            if gaps.dt is None or rec['measurements_received'] < 20:
                gaps.dt = step if gaps.dt is None else min(gaps.dt, step)
            elif step > 1.5 * gaps.dt:
                rec['measurement_gaps'] += int(round(step / gaps.dt)) - 1
    gaps.last_t = float(t[keep][-1])
    block = np.column_stack([c[keep] for c in cols] + [np.full(np.count_nonzero(keep), t_rx)])
    meas.append_block(block)
    rec['measurements_received'] += int(block.shape[0])


def fit_error(f_meas, f_model):
    """Return ``(rmse_n, nrmse_percent)``; NRMSE normalised by the measured force range."""
    f_meas = np.asarray(f_meas, dtype=float)
    err = np.asarray(f_model, dtype=float) - f_meas
    if f_meas.size == 0:
        return math.nan, math.nan
    rmse = float(np.sqrt(np.mean(err ** 2)))
    span = float(np.ptp(f_meas))
    return rmse, (100.0 * rmse / span if span > 0 else math.nan)


CHUNK_ROWS = 65536


class ParamsLog:
    """
    The parameter messages of a run, read from ``parameters.jsonl`` on each pass (bounded).

    Iterating yields ``(wall_s, dict)``; ``len()`` counts the records (one pass). Lines that are
    not JSON (the last line of a crashed run) are skipped and listed in ``bad_lines``.
    """

    def __init__(self, path):
        self.path = Path(path)
        self.bad_lines = []

    def __iter__(self):
        from mr_damper_model.io.columnlog import read_json_lines
        if not self.path.exists():
            return
        bad = []
        for rec in read_json_lines(self.path, bad):
            if isinstance(rec, list) and len(rec) == 2 and isinstance(rec[1], dict):
                yield float(rec[0]), rec[1]
        self.bad_lines = bad

    def __len__(self):
        return sum(1 for _ in self)


def record_error(meas, params):
    """
    ``(rmse_n, nrmse_percent)`` of kwok-current ``params`` on every sample of ``meas``, streamed.

    Same figures as :func:`fit_error` on the whole arrays (NRMSE by the measured force range).
    """
    meas = open_log(meas)
    n, se, fmin, fmax = 0, 0.0, math.inf, -math.inf
    for c in meas.chunks(CHUNK_ROWS, ('x', 'v', 'f', 'i')):
        with np.errstate(over='ignore', invalid='ignore'):
            e = kwok_current_force(params, c['x'], c['v'], c['i']) - c['f']
        se += float(e @ e)
        n += e.size
        fmin, fmax = min(fmin, float(c['f'].min())), max(fmax, float(c['f'].max()))
    if n == 0:
        return math.nan, math.nan
    rmse = math.sqrt(se / n)
    span = fmax - fmin
    return rmse, (100.0 * rmse / span if span > 0 else math.nan)


def offline_best_fit(meas, *, budget_s=5.0, max_samples=8000, seed=1):
    """
    Fit kwok-current offline to the whole record: a yardstick.

    The fit is ``mr_damper_model.identification.identify``.

    When the true damper is not a kwok-current model (the Spencer plant), no parameter can be
    compared with a truth; the best kwok-current fit of everything recorded says how close the
    live estimate is to the best this model can do. The fit uses at most ``max_samples`` evenly
    spaced samples; its error is then measured on every sample.

    Returns
    -------
    dict or None
        ``parameters``, ``rmse_n``, ``nrmse_percent`` (on the whole record), ``seconds``; None
        if the record covers fewer than two current levels or the fit fails.

    """
    from mr_damper_model.io.data import DamperData
    from mr_damper_model.identification.identify import identify
    meas = open_log(meas)
    sub = meas.strided(max_samples, ('t', 'x', 'v', 'f', 'i'))
    t, x, v, f, i = (np.asarray(sub[k], dtype=float) for k in ('t', 'x', 'v', 'f', 'i'))
    if np.unique(np.round(i / 0.05)).size < 2:
        return None
    try:
        res = identify(DamperData(t, x, v, f, i, source='suite'), 'kwok-current', seed=seed,
                       budget_s=budget_s)
    except (ValueError, FloatingPointError, np.linalg.LinAlgError):
        return None
    p = dict(res.parameters, i_ref_a=float((res.model_options or {}).get('i_ref_a', 2.0)))
    rmse, nrmse = record_error(meas, p)
    return {'parameters': res.parameters, 'rmse_n': rmse, 'nrmse_percent': nrmse,
            'seconds': res.seconds}


def identification_summary(meas, params_log, truth=None, *, max_history=80,
                           offline_budget_s=5.0):
    """
    Identification figures of a run.

    Parameters
    ----------
    meas : column log, reader or dict
        Columns ``t, x, v, f, i`` of the recorded measurements
        (``mr_damper_model.io.columnlog.open_log``); read in streamed passes.
    params_log : iterable of (float, dict)
        Wall receipt time [s] and decoded ``/mr_damper/kwok_parameters`` message; iterated a
        few times (a list, or :class:`ParamsLog` that reads its file on each pass).
    truth : dict, optional
        True kwok-current parameters (when the plant is kwok-current).
    max_history : int
        At most this many history entries are evaluated on the record.
    offline_budget_s : float
        Compute budget [s] of :func:`offline_best_fit` (run when there is no kwok-current
        truth; 0 = skip).

    Returns
    -------
    dict

    """
    meas = open_log(meas)
    n_upd, n_valid, first_valid, final = 0, 0, None, None
    for t, p in params_log:
        n_upd += 1
        if p.get('valid') == 1.0:
            n_valid += 1
            final = p
            if first_valid is None:
                first_valid = t
    out = {'updates': n_upd, 'valid_updates': n_valid, 'first_valid_s': first_valid,
           'rmse_n': math.nan, 'nrmse_percent': math.nan, 'parameters': None, 'truth': None,
           'reported_rmse_n': math.nan, 'reported_nrmse_percent': math.nan, 'history': []}
    have = meas.rows > 0
    if final is not None:
        out['parameters'] = {n: final[n] for n in KWOK_CURRENT_NAMES if n in final}
        out['parameters']['i_ref_a'] = final.get('i_ref_a', 2.0)
        out['reported_rmse_n'] = final.get('rmse_n', math.nan)
        out['reported_nrmse_percent'] = final.get('nrmse_percent', math.nan)
        out['current_range_a'] = [final.get('current_min_a'), final.get('current_max_a')]
        if have:
            out['rmse_n'], out['nrmse_percent'] = record_error(meas, final)
    if truth:
        tp = {n: truth[n] for n in KWOK_CURRENT_NAMES if n in truth}
        if len(tp) == len(KWOK_CURRENT_NAMES):
            tp['i_ref_a'] = truth.get('i_ref_a', 2.0)
            out['truth'] = tp
            if out['parameters']:
                out['parameter_error_percent'] = {
                    n: (100.0 * (out['parameters'][n] - tp[n]) / abs(tp[n]) if tp[n] else math.nan)
                    for n in KWOK_CURRENT_NAMES}
            if have:
                out['truth_rmse_n'], out['truth_nrmse_percent'] = record_error(meas, tp)
    if have and not out['truth'] and offline_budget_s > 0:
        out['offline_best_fit'] = offline_best_fit(meas, budget_s=offline_budget_s)
    step = max(1, int(math.ceil(n_upd / max_history)))
    picks = set(range(0, n_upd, step)) | ({n_upd - 1} if n_upd else set())
    dec = meas.strided(20000, ('x', 'v', 'f', 'i'))      # <= ~20k samples per evaluation
    x, v, f, i = (np.asarray(dec[k], dtype=float) for k in 'xvfi')
    for k, (t, p) in enumerate(params_log):
        if k not in picks:
            continue
        entry = {'t_s': t, 'valid': p.get('valid') == 1.0, 'rmse_n': p.get('rmse_n'),
                 'nrmse_percent': p.get('nrmse_percent'),
                 'parameters': {n: p.get(n) for n in KWOK_CURRENT_NAMES}}
        if f.size and all(math.isfinite(p.get(n, math.nan)) for n in KWOK_CURRENT_NAMES):
            with np.errstate(over='ignore', invalid='ignore'):
                fm = kwok_current_force(p, x, v, i)
            if np.all(np.isfinite(fm)):
                entry['record_rmse_n'], entry['record_nrmse_percent'] = fit_error(f, fm)
        out['history'].append(entry)
    return out


def _static_load(qc_params):
    return _car_params(qc_params).static_tyre_load


def _car_params(qc_params):
    from quarter_car_sim.params import QuarterCarParams
    g = qc_params.get
    return QuarterCarParams(m_s=g('m_s', 300.0), m_u=g('m_u', 60.0), k_s=g('k_s', 16000.0),
                            k_t=g('k_t', 190000.0))


def _metrics_of_blocks(blocks, window, static_load, dt, *, current_key='current_cmd',
                       keep=None, max_keep=200000, n_total=None):
    """
    Ride metrics over the time ``window`` of a stream of blocks (the Wk filter runs over all).

    ``keep``: a dict filled with at most ``max_keep`` evenly spaced rows of ``t`` and ``a_s``
    (for the plot), given ``n_total`` rows in all.
    """
    from quarter_car_sim.ride_metrics import RunningRideMetrics
    m = RunningRideMetrics(1.0 / dt, static_load)
    lo, hi = window[0] - 0.5 * dt, window[1] + 0.5 * dt
    step = max(1, int(math.ceil((n_total or 1) / max_keep)))
    seen = 0
    kt, ka = array('d'), array('d')
    for b in blocks:
        t = np.asarray(b['t'], dtype=float)
        m.update_block(b['a_s'], b['travel'], b['tyre_force'], b['damper_force'],
                       b.get(current_key), use=(t >= lo) & (t <= hi))
        if keep is not None:
            first = (-seen) % step
            kt.extend(t[first::step])
            ka.extend(np.asarray(b['a_s'], dtype=float)[first::step])
        seen += t.size
    if keep is not None:
        keep['t'] = np.frombuffer(kt, dtype=float) if len(kt) else np.zeros(0)
        keep['a_s'] = np.frombuffer(ka, dtype=float) if len(ka) else np.zeros(0)
    return m.as_dict()


def passive_reference(qc_params, t_end, dt, current=None, *, window=None, keep=None):
    """
    Simulate the passive damper (safe current) on the node's road, plant and car, offline.

    The simulation is streamed in blocks (``simulate.simulate_blocks``) into running ride
    metrics: memory does not grow with the run length.

    Parameters
    ----------
    qc_params : dict
        The quarter-car node's parameters (as in the YAML; node defaults otherwise).
    t_end : float
        Last simulated time [s] of the live run.
    dt : float
        Control period [s].
    current : float, optional
        Passive coil current [A] (default: the node's ``safe_current_a``, 0.5 A if unset).
    window : (float, float), optional
        Simulated-time window [s] of the metrics (default ``(0, t_end)``).
    keep : dict, optional
        Filled with at most 200,000 evenly spaced ``t`` and ``a_s`` samples (plots).

    Returns
    -------
    dict
        Ride metrics over the window (``ride_metrics.METRIC_KEYS``) plus ``static_load`` and
        ``current_a``.

    """
    from quarter_car_sim import live_loop
    from quarter_car_sim.controllers import Passive
    from quarter_car_sim.simulate import simulate_blocks
    g = qc_params.get
    car = _car_params(qc_params)
    from mr_damper_model.models.plant import make_plant
    from quarter_car_sim.road import make_road
    road = make_road(g('road', 'iso8608'), road_class=g('road_class', 'C'),
                     speed_m_s=g('speed_m_s', 20.0), rng=int(g('road_seed', 1)),
                     duration_s=g('road_duration_s', 300.0), dt=dt,
                     file=g('road_file', ''), repeat=bool(g('road_repeat', False)))
    current = float(g('safe_current_a', 0.5) if current is None else current)
    plant = make_plant(g('plant', 'spencer'), g('truth_file', ''))
    duration = max(float(t_end) + dt, dt)
    blocks = simulate_blocks(car, road, Passive(current), plant, dt=dt,
                             settle_s=g('settle_s', live_loop.SETTLE_S), duration_s=duration)
    n_total = int(round(duration / dt)) + 1
    m = _metrics_of_blocks(blocks, window or (0.0, float(t_end)), car.static_tyre_load, dt,
                           keep=keep, n_total=n_total)
    m.update(static_load=car.static_tyre_load, current_a=current)
    return m


def _trace_blocks(log, columns):
    for c in log.chunks(CHUNK_ROWS, columns):
        yield c


def ride_summary(log, qc_params):
    """
    Ride metrics of the live controller against the passive damper on the same road.

    Both are evaluated on the same simulated-time window: from the first control step in normal
    mode (the controller actually used a model) to the end of the live run. The live log is read
    in streamed passes; the passive runs are simulated in blocks.

    Parameters
    ----------
    log : column log, reader or dict
        The quarter-car trace (``live_loop.TRACE_COLUMNS``; ``dt`` in its header or a key).
    qc_params : dict
        The quarter-car node's parameters.

    Returns
    -------
    dict
        ``skyhook`` and ``passive`` metric dicts, ``controller``, ``passive_current_a``,
        ``window_s``, ``wk_improvement_percent`` (positive = live controller better) and
        ``passive_trace`` (at most 200,000 evenly spaced ``t``, ``a_s`` of the passive run).

    """
    log = open_log(log)
    g = qc_params.get
    static = _static_load(qc_params)
    # pass 1: first step in normal mode, end time, normal fraction after t = 0
    t_first_normal, t_last, n_pos, n_pos_normal, dt = math.inf, math.nan, 0, 0, None
    for c in log.chunks(CHUNK_ROWS, ('t', 'mode')):
        t, mode = c['t'], c['mode']
        if dt is None and t.size > 1:
            dt = float(np.median(np.diff(t[:1000])))
        normal = mode > 0.5
        if math.isinf(t_first_normal) and normal.any():
            t_first_normal = float(t[np.argmax(normal)])
        pos = t >= 0
        n_pos += int(pos.sum())
        n_pos_normal += int((normal & pos).sum())
        t_last = float(t[-1])
    dt = float(log.meta.get('dt', dt))
    t0 = max(0.0, t_first_normal)
    out = {'controller': g('controller', 'skyhook'),
           'passive_current_a': float(g('safe_current_a', 0.0)), 'window_s': [t0, t_last],
           'normal_fraction': n_pos_normal / n_pos if n_pos else 0.0}
    if not (t_last - t0 >= dt):
        # never in normal mode: compare the whole run (the live car was passive throughout)
        out['window_s'] = [0.0, t_last]
        out['note'] = 'the controller never left fail-safe: both runs are passive'
    window = out['window_s']
    cols = ('t', 'a_s', 'travel', 'tyre_force', 'damper_force', 'i_cmd')
    out['skyhook'] = _metrics_of_blocks(_trace_blocks(log, cols), window, static, dt,
                                        current_key='i_cmd')
    keep = {}
    ref = passive_reference(qc_params, t_last, dt, window=window, keep=keep)
    out['passive'] = {k: v for k, v in ref.items() if k not in ('static_load', 'current_a')}
    out['passive_trace'] = keep
    if out['passive_current_a'] != 0.0:
        # the softest passive setting too (best for comfort on this damper): the honest
        # comfort baseline, while the safe current is the car without identification
        soft = passive_reference(qc_params, t_last, dt, current=0.0, window=window)
        out['passive_0a'] = {k: v for k, v in soft.items()
                             if k not in ('static_load', 'current_a')}
    a, b = out['skyhook']['rms_body_accel_wk'], out['passive']['rms_body_accel_wk']
    out['wk_improvement_percent'] = 100.0 * (b - a) / b if b > 0 else math.nan
    return out


def measurement_to_parameters(meas, params_log):
    """
    Delays [s] from the newest measurement of each identified window to its parameters.

    Each window counts once, at its first arrival: a set the identifier publishes again (it
    refused a newer window and keeps the set in use) is not a new identification.

    The newest sample's arrival (``mr-damper-record`` receives the measurement stream as the
    identifier does) is found from its stamp ``window_end_s``; the delay runs to the arrival of
    the parameter message at the recorder (the quarter car subscribes to it the same way and
    uses it from its next 1 ms step on). Windows older than the record are ignored. The record
    is read in one streamed pass.

    Returns
    -------
    numpy.ndarray
        One delay per parameter message [s].

    """
    meas = open_log(meas)
    if meas.rows < 2 or 'recv_epoch_s' not in meas.columns:
        return np.zeros(0)
    ends, gots = array('d'), array('d')
    for _, p in params_log:
        end, got = p.get('window_end_s', math.nan), p.get('recv_epoch_s', math.nan)
        if end is not None and got is not None and math.isfinite(end) and math.isfinite(got):
            ends.append(end)
            gots.append(got)
    if not ends:
        return np.zeros(0)
    ends, gots = np.frombuffer(ends, dtype=float), np.frombuffer(gots, dtype=float)
    order = np.argsort(ends, kind='stable')
    ends, gots = ends[order], gots[order]
    # a set re-published (a refused window keeps the set in use, with its window) is not a new
    # identification: each window counts once, from its first arrival
    ends, first = np.unique(ends, return_index=True)
    gots = np.minimum.reduceat(gots, first)
    delays = np.full(ends.size, np.nan)
    k = None
    for c in meas.chunks(CHUNK_ROWS, ('t', 'recv_epoch_s'), overlap=1):
        t, recv = c['t'], c['recv_epoch_s']
        if k is None:           # windows ending before the record are ignored
            k = int(np.searchsorted(ends, t[0], side='left'))
        stop = int(np.searchsorted(ends, t[-1], side='right'))
        if stop > k:
            delays[k:stop] = gots[k:stop] - np.interp(ends[k:stop], t, recv)
            k = stop
    return delays[np.isfinite(delays)]


def messages_summary(rec, qc_status):
    """
    Measurements lost on their way to the identifier.

    The recorder (``mr-damper-record``) takes the same stream; the samples in its stamp span
    (received plus stamp gaps) are what the rig published in that span (the rig waits for both
    subscribers before its first sample and stops before the identifier), so the identifier
    lost ``span - samples_received``. Gaps at the recorder itself are listed but are not losses
    of the suite (the recorder is a monitor, not part of the loop).

    Returns
    -------
    (int, dict)
        Total lost and the breakdown.

    """
    st = rec.get('status', {})
    rig = st.get('rig', {}) or {}
    ident = st.get('identifier', {}) or {}
    br = {'measurement_gaps_at_recorder': int(rec.get('measurement_gaps', 0)),
          'measurements_received_by_recorder': int(rec.get('measurements_received', 0))}
    published = _first(rig, ('samples_published', 'published'))
    received = _first(ident, ('samples_received', 'received'))
    lives = rec.get('identifier_lives') or []
    if len(lives) > 1:      # a restarted identifier counts from 0: add up its lives
        received = (sum(life['last_count'] for life in lives[:-1])
                    + max(lives[-1]['last_count'], received or 0))
        br['identifier_lives'] = len(lives)
    if published is not None:
        br['measurements_published_by_rig_last_status'] = published
    lost_ident = None
    if received is not None:
        br['measurements_received_by_identifier'] = received
        # samples in the recorded stamp span = what the rig published in it (the rig waits for
        # both subscribers before its first sample, and stops first at shutdown)
        span = br['measurements_received_by_recorder'] + br['measurement_gaps_at_recorder']
        if span:
            lost_ident = max(0, int(span - received))
            br['measurements_lost_to_identifier'] = lost_ident
    if lost_ident is None:
        # no identifier counters: the launcher's own copy of the stream is the best evidence
        br['note'] = 'identifier status missing: messages_lost counts the recorder gaps'
        return br['measurement_gaps_at_recorder'], br
    return lost_ident, br


def restart_figures(supervision, rec, meas):
    """
    Return what each restart of a node cost, from the recording.

    Each restart's window runs from its node's death to the next death of any node (or the end
    of the recording): ``failsafe_s`` is the time the car state said fail-safe in it,
    ``no_car_state_s`` the time without any car state (the car or the recorder was down),
    ``car_normal_at_end`` whether the car was back to normal at its end.
    ``measurements_lost``: the samples the rig published in the window (recorded, or missing
    between recorded stamps) that no life of the identifier counted (``samples_received``),
    the window starting at the identifier's last count before the death (what a killed
    identifier took after its last count is lost with it).

    Parameters
    ----------
    supervision : dict
        The launcher's record (``restarts.json``): ``restarts`` (entries of
        ``supervisor.Supervisor.restarts``), ``gave_up``, ``policy``.
    rec : dict
        :func:`read_recording` (``car_modes``, ``identifier_lives``, ``gap_events``,
        ``end_epoch_s``).
    meas : column log
        The recorded measurements (``recv_epoch_s``).

    Returns
    -------
    list of dict
        One per restart: its record plus the figures above.

    """
    restarts = [dict(r) for r in supervision.get('restarts') or ()]
    deaths = sorted(r['death_epoch_s'] for r in restarts if r.get('death_epoch_s') is not None)
    end = rec.get('end_epoch_s')
    runs = rec.get('car_modes') or []
    lives = rec.get('identifier_lives') or []
    counted = sorted(t for life in lives for t, _ in life['counts'])
    windows = []
    for r in restarts:
        a = r.get('death_epoch_s')
        if a is None or end is None:
            continue
        later = [d for d in deaths if d > a]
        b = max(min(later) if later else end, a)
        fs = sum(max(0.0, min(b, hi) - max(a, lo)) for lo, hi, mode in runs if mode)
        seen = sum(max(0.0, min(b, hi) - max(a, lo)) for lo, hi, _ in runs)
        last = [mode for lo, hi, mode in runs if lo < b and hi > a]
        r.update(failsafe_s=fs, no_car_state_s=max(b - a - seen, 0.0),
                 car_normal_at_end=(not last[-1]) if last else None, window_s=b - a)
        before = [t for t in counted if t <= a]
        if before:
            lo = before[-1]
            missing = sum(n for t, n in rec.get('gap_events') or () if lo < t <= b)
            windows.append((r, lo, b, missing - _received_between(lives, lo, b)))
    if windows:
        n = [0] * len(windows)
        for c in open_log(meas).chunks(CHUNK_ROWS, ('recv_epoch_s',)):
            t = c['recv_epoch_s']
            for k, (_, lo, hi, _) in enumerate(windows):
                n[k] += int(np.count_nonzero((t > lo) & (t <= hi)))
        for k, (r, _, _, rest) in enumerate(windows):
            r['measurements_lost'] = max(0, n[k] + int(rest))
    return restarts


def attribute_losses(breakdown, restarts):
    """
    Split the measurements lost to the identifier between the restarts of nodes and the rest.

    Each restart keeps its estimate (:func:`restart_figures`), capped so that the restarts
    together never claim more than ``measurements_lost_to_identifier``; the remainder is
    ``measurements_lost_not_at_restarts``. Updates both in place.
    """
    total = breakdown.get('measurements_lost_to_identifier')
    if total is None:
        return
    left = int(total)
    for r in restarts:
        if r.get('measurements_lost') is not None:
            r['measurements_lost'] = min(int(r['measurements_lost']), left)
            left -= r['measurements_lost']
    if any(r.get('measurements_lost') is not None for r in restarts):
        breakdown['measurements_lost_at_restarts'] = int(total) - left
        breakdown['measurements_lost_not_at_restarts'] = left


def can_summary(status, corner='fl'):
    """
    Commands over CAN (``--config can``): frames the bridge sent vs frames the driver received.

    Parameters
    ----------
    status : dict
        The last status of each node (``read_recording(...)['status']``): ``can_bridge`` and
        ``can_driver_sim`` (each node's final status, published as it stops; the driver stops
        after the bridge).
    corner : str
        The bridged corner.

    Returns
    -------
    dict or None
        ``frames_sent`` (bridge, all command frames incl. keep-alive re-sends), ``received``
        (driver, valid command frames), ``lost`` (their difference), ``counter_jumps``,
        ``frames_missed``, ``bad_checksum`` (driver), ``commands`` (bridge: ROS commands
        taken), ``resent``, ``failsafe_entries``, ``failsafe_s``, ``bridge_faults`` (the
        bridge's fault counters that are not zero), ``zero_lost`` (frames_sent == received and
        no counter jump); None when neither node reported.

    """
    bridge = status.get('can_bridge')
    driver = status.get('can_driver_sim')
    if bridge is None and driver is None:
        return None
    br = ((bridge or {}).get('corners') or {}).get(corner) or {}
    drv = ((driver or {}).get('corners') or {}).get(corner) or {}
    sent, received = br.get('frames_sent'), drv.get('received')
    out = {'corner': corner, 'frames_sent': sent, 'received': received,
           'lost': (sent - received if isinstance(sent, (int, float))
                    and isinstance(received, (int, float)) else None),
           'counter_jumps': drv.get('counter_jumps'), 'frames_missed': drv.get('frames_missed'),
           'bad_checksum': drv.get('bad_checksum'), 'commands': br.get('commands'),
           'resent': br.get('resent'), 'failsafe_entries': br.get('failsafe_entries'),
           'failsafe_s': br.get('failsafe_s'), 'bridge_mode': br.get('mode'),
           'bridge_reason': br.get('reason'),
           'bridge_faults': {k: v for k, v in ((bridge or {}).get('faults') or {}).items()
                             if v},
           'bridge_dropped': (bridge or {}).get('dropped') or {}}
    out['zero_lost'] = out['lost'] == 0 and out['counter_jumps'] == 0
    return out


def _first(d, keys):
    for k in keys:
        if isinstance(d.get(k), (int, float)):
            return d[k]
    return None


def make_report(out, *, duration_s=None, config=None, plots=True, fallback=None):
    """
    Build ``summary.json`` (and plots) for the run in folder ``out``, with bounded memory.

    The recording may be in parts (a restarted recorder) and a part may be cut (a killed
    recorder): the summary is made from what exists, and ``recording.complete`` is False unless
    one part holds the whole run, closed properly. With no recording at all, the summary comes
    from the statuses in ``fallback`` (no plots). ``restarts.json`` (written by the launcher),
    if present, lists the restarts of nodes: ``restarts`` in the summary, each with what it cost
    (:func:`restart_figures`).

    Parameters
    ----------
    out : path
        Run output folder (see the module docstring for the inputs).
    duration_s : float, optional
        Wall duration of the run [s] (default: from the quarter-car log).
    config : dict, optional
        The parameter dict of the run (default: the one recorded in ``suite.mcap``).
    plots : bool
        Also write the PNG plots.
    fallback : dict, optional
        What the launcher knows, used when the recording lacks it: ``config`` (the run's
        parameter dict) and ``status`` (the last status of each node, by short name).

    Returns
    -------
    dict
        The summary (as written to ``summary.json``); a HIL run (car plant ``rig``) also has
        ``hil`` (tracking error and identification quality against the cam rig).

    Raises
    ------
    FileNotFoundError
        No recording and no ``fallback`` statuses.
    ValueError
        No suite configuration, neither recorded nor in ``fallback``.

    """
    from .recorder import recording_parts
    out = Path(out)
    path = out / RECORDING
    fallback = fallback or {}
    parts = [f for _, f in recording_parts(path)]
    if not parts and not fallback.get('status'):
        raise FileNotFoundError(f'{path}: no recording of the run')
    supervision = {}
    if (out / 'restarts.json').is_file():
        supervision = json.loads((out / 'restarts.json').read_text())
    with tempfile.TemporaryDirectory(prefix='.report_', dir=out) as work:
        starts = [r['restart_epoch_s'] for r in supervision.get('restarts') or ()
                  if r['node'] == IDENT and r.get('restart_epoch_s') is not None]
        deaths = [r['death_epoch_s'] for r in supervision.get('restarts') or ()
                  if r.get('death_epoch_s') is not None]
        rec = read_recording(parts, work, identifier_starts=starts,
                             car_modes_from=min(deaths) - 1.0 if deaths else None)
        if not parts:
            rec['status'] = dict(fallback['status'])
        cfg = config if config is not None else effective_config(rec)
        cfg = cfg if cfg is not None else fallback.get('config')
        if cfg is None:
            raise ValueError(f'{path}: no {CONFIG_TOPIC.name} message (the suite config)')
        meas = (ColumnReader(Path(work) / 'measurement') if rec['measurements_received']
                else ArrayLog({k: [] for k in MEAS_COLUMNS}))
        params_log = ParamsLog(Path(work) / 'parameters.jsonl')
        rec['restarts'] = restart_figures(supervision, rec, meas)
        rec['gave_up'] = supervision.get('gave_up')
        rec['exit_codes'] = supervision.get('exit_codes')
        return _report(out, rec, cfg, meas, params_log, duration_s, plots and bool(parts))


def effective_config(rec):
    """
    Return the settings of a recorded run: the suite YAML with each node's own report on top.

    The YAML (``/mr_damper/suite_config``) holds what was set; the node parameters
    (``/mr_damper/node_parameters``) what each node ran with, its defaults included, so no node
    default is copied here. None when the recording has neither.
    """
    import copy
    if rec.get('config') is None and not rec.get('node_parameters'):
        return None
    cfg = copy.deepcopy(rec.get('config') or {})
    for node, params in (rec.get('node_parameters') or {}).items():
        cfg.setdefault(node, {}).setdefault('ros__parameters', {}).update(params)
    return cfg


def _report(out, rec, cfg, meas, params_log, duration_s, plots):
    hil = node_params(cfg, QC).get('plant') == 'rig'
    qc_params = node_params(hil_report_config(cfg) if hil else cfg, QC)
    rig_params = node_params(cfg, RIG)
    truth = rec.get('truth')
    summary = {'duration_s': duration_s,
               'config': 'replay' if rig_params.get('mode', 'sim') != 'sim' else 'sim',
               'plant': qc_params.get('plant', 'spencer'),
               'recording': {'file': RECORDING, 'messages': rec['topic_messages'],
                             'statuses': rec['status_messages'],
                             'undecodable': rec['undecodable'],
                             'node_parameters': sorted(rec.get('node_parameters') or {}),
                             **recording_state(rec)}}
    if rec.get('restarts') or rec.get('gave_up'):
        summary['restarts'] = rec.get('restarts') or []
        counts = {}
        for r in summary['restarts']:
            counts[r['node']] = counts.get(r['node'], 0) + (r.get('restart_s') is not None)
        summary['restart_counts'] = counts
        summary['gave_up'] = rec.get('gave_up')
    if rec.get('exit_codes') is not None:
        summary['exit_codes'] = rec['exit_codes']
    summary['identification'] = identification_summary(meas, params_log, truth)
    summary['identification']['truth_model'] = (
        'kwok-current' if summary['identification']['truth'] else
        ('spencer' if rec.get('truth_spencer') else None))
    if rec.get('truth_spencer'):
        summary['identification']['truth_spencer'] = rec['truth_spencer']
    log = ColumnReader(out / 'quarter_car_log') if exists(out / 'quarter_car_log') else None
    qc_status = (log.meta.get('status') if log is not None else None) or \
        (rec.get('status', {}).get('quarter_car') or {})
    passive_trace = None
    if log is not None and log.rows > 10:
        ride = ride_summary(log, qc_params)
        passive_trace = ride.pop('passive_trace')
        summary['ride'] = ride
        if duration_s is None:
            ends = log.strided(2, ('wall',))['wall']
            summary['duration_s'] = float(ends[-1] - ends[0])
    else:
        summary['ride'] = {'skyhook': None, 'passive': None, 'note': 'no quarter-car log'}
    car_restarts = [r for r in rec.get('restarts') or () if r['node'] == QC]
    if car_restarts and summary['ride'].get('skyhook'):
        summary['ride']['note_restart'] = (
            f'the car was restarted at {car_restarts[-1]["restart_s"]:.1f} s: the ride, loop '
            'and fail-safe totals cover its last life only (its log starts anew)')
    summary['failsafe_s'] = qc_status.get('failsafe_s')
    summary['failsafe'] = {k: qc_status.get(k) for k in (
        'mode', 'reason', 'failsafe_entries', 'params_accepted', 'params_rejected',
        'safe_current_a')}
    ctrl_status = rec.get('status', {}).get('controller')
    if ctrl_status is not None or 'command_timeouts' in qc_status:
        # --external-controller: the link car state -> controller -> current command
        summary['controller_link'] = {
            'command_timeouts': qc_status.get('command_timeouts'),
            'command_timeout_s_total': qc_status.get('command_timeout_s_total'),
            'commands_received': qc_status.get('commands_received'),
            'controller_dropped': (ctrl_status or {}).get('dropped') or {},
            'controller_mode': (ctrl_status or {}).get('mode'),
            'controller_reason': (ctrl_status or {}).get('reason')}
    can = can_summary(rec.get('status', {}))
    if can is not None:
        summary['config'] = 'can'
        summary['can'] = can
    _add_sensing(summary, out, rec, qc_status)
    lost, breakdown = messages_summary(rec, qc_status)
    attribute_losses(breakdown, rec.get('restarts') or [])
    summary['messages_lost'] = lost
    summary['messages'] = breakdown
    summary['loop'] = qc_status.get('loop')
    if log is not None and log.rows > 10:
        summary['loop_full_run'] = loop_figures(log)
    if (out / 'process_stats.json').exists():
        summary['processes'] = json.loads((out / 'process_stats.json').read_text())
    lat = measurement_to_parameters(meas, params_log)
    if lat.size:
        summary['measurement_to_parameters_s'] = {
            'p50': float(np.percentile(lat, 50)), 'p99': float(np.percentile(lat, 99)),
            'max': float(lat.max()), 'n': int(lat.size)}
    if hil:
        from mr_damper_bringup.car_in_the_loop import hil_summary
        status = rec.get('status', {})
        summary['hil'] = hil_summary(status.get('quarter_car'), status.get('rig'),
                                     (summary.get('identification') or {}).get('parameters'),
                                     plant=rig_params.get('plant', 'spencer'),
                                     truth_file=rig_params.get('truth_file', ''))
    summary = finite_or_none(summary)
    (out / 'summary.json').write_text(json.dumps(summary, indent=2, allow_nan=False))
    if plots:
        from . import plots as suite_plots
        step = max(1, int(math.ceil(summary['identification']['updates'] / 5000)))
        params_plot = [tp for k, tp in enumerate(params_log) if k % step == 0]
        trace = None
        if log is not None:
            trace = log.strided(200000, ('t', 'a_s', 'i_cmd', 'coil_current', 'mode'))
        suite_plots.plot_all(out, meas.strided(200000), params_plot, summary, trace,
                             passive_trace)
    return summary


def _add_sensing(summary, out, rec, qc_status):
    """``--sensing vehicle``: the ``sensing`` section (:mod:`mr_damper_bringup.sensing_report`)."""
    if 'estimator' not in rec.get('status', {}) and 'sensing' not in qc_status:
        return
    from .recorder import recording_parts
    from .sensing_report import sensing_summary
    parts = [f for _, f in recording_parts(out / RECORDING)]
    summary['sensing'] = sensing_summary(rec.get('status', {}), qc_status, parts)


def recording_state(rec):
    """
    Return how complete the recording is: ``complete``, ``parts``, ``note``.

    ``complete`` is True only for one part closed properly (a restarted recorder leaves parts
    with a gap between them; a killed one a part without its footer, read up to its last
    complete chunk); ``parts`` lists each file read (``McapScan.summary``).
    """
    parts = rec.get('parts') or []
    complete = len(parts) == 1 and parts[0]['complete']
    out = {'complete': complete, 'parts': parts}
    if not parts:
        out['note'] = 'no recording: the summary comes from the nodes\' last statuses'
    elif not complete:
        cut = [p for p in parts if not p['complete']]
        out['note'] = (f'{len(parts)} part(s), {len(cut)} cut short by a killed recorder '
                       '(read up to the last complete chunk); messages between the parts were '
                       'not recorded')
    return out


def hil_report_config(cfg):
    """Config for the report of a HIL run: the passive reference drives the rig's damper."""
    import copy
    from .config import set_param
    report = copy.deepcopy(cfg)
    set_param(report, QC, 'plant', node_params(cfg, RIG).get('plant', 'spencer'))
    set_param(report, QC, 'truth_file', node_params(cfg, RIG).get('truth_file', ''))
    return report


#: periods kept for the timing percentiles (every period of a run up to ~33 min at 1 kHz)
MAX_TIMING_SAMPLES = 2_000_000


def loop_figures(log):
    """
    Return the loop timing of the whole run from the quarter-car trace, in one streamed pass.

    Mean, maximum and count are exact; percentiles come from at most
    :data:`MAX_TIMING_SAMPLES` evenly spaced periods and compute times.
    """
    from quarter_car_sim.live_loop import timing_stats
    log = open_log(log)
    step = max(1, int(math.ceil(log.rows / MAX_TIMING_SAMPLES)))
    per_keep, lat_keep = array('d'), array('d')
    n_per = n_lat = 0
    sum_per = sum_lat = 0.0
    min_per, max_per, max_lat = math.inf, -math.inf, -math.inf
    t_first = t_last = math.nan
    seen = 0
    for c in log.chunks(CHUNK_ROWS, ('t', 'wall', 'compute_s'), overlap=1):
        first_row = 0 if seen == 0 else 1            # the overlap row was counted before
        w = c['wall']
        per = np.diff(w)
        lat = c['compute_s'][first_row:]
        if math.isnan(t_first):
            t_first = float(c['t'][0])
        t_last = float(c['t'][-1])
        if per.size:
            n_per += per.size
            sum_per += float(per.sum())
            min_per, max_per = min(min_per, float(per.min())), max(max_per, float(per.max()))
            per_keep.extend(per[::step])
        n_lat += lat.size
        sum_lat += float(lat.sum())
        if lat.size:
            max_lat = max(max_lat, float(lat.max()))
            lat_keep.extend(lat[::step])
        seen += lat.size
    per_a = np.frombuffer(per_keep, dtype=float) if len(per_keep) else np.zeros(0)
    lat_a = np.frombuffer(lat_keep, dtype=float) if len(lat_keep) else np.zeros(0)
    nominal = float(np.median(per_a)) if per_a.size else None
    period = timing_stats(per_a, nominal)
    latency = timing_stats(lat_a)
    if n_per:
        period.update(n=n_per, mean_ms=1e3 * sum_per / n_per, max_ms=1e3 * max_per,
                      jitter_max_ms=1e3 * max(abs(max_per - nominal), abs(nominal - min_per)))
    if n_lat:
        latency.update(n=n_lat, mean_ms=1e3 * sum_lat / n_lat, max_ms=1e3 * max_lat)
    dt = float(log.meta.get('dt', 1e-3))
    return {'period': period, 'latency': latency,
            'real_time_factor_measured': dt / nominal if nominal else None,
            'sim_time_s': t_last - t_first, 'timing_sample_stride': step}


def format_summary(s):
    """Return the human-readable summary printed by the launcher."""
    ident = s.get('identification') or {}
    lines = ['', '=== MR damper suite summary ===',
             f'duration {s.get("duration_s") or float("nan"):.1f} s ({s.get("config")}, '
             f'plant {s.get("plant")})']
    fv = ident.get('first_valid_s')
    lines.append(f'identification: {ident.get("updates", 0)} updates, '
                 f'{ident.get("valid_updates", 0)} valid, first valid after '
                 f'{"never" if fv is None else f"{fv:.1f} s"}')
    if ident.get('parameters'):
        lines.append(f'  final model on all recorded samples: RMSE '
                     f'{ident.get("rmse_n") or 0:.1f} N, '
                     f'NRMSE {ident.get("nrmse_percent") or 0:.2f} % (identifier reported '
                     f'{ident.get("reported_nrmse_percent") or 0:.2f} % on its window)')
        truth = ident.get('truth') or {}
        lines.append('  ' + ' '.join(f'{n:>9s}' for n in ('param',) + KWOK_CURRENT_NAMES))
        lines.append('  ' + f'{"ident.":>9s} ' + ' '.join(
            f'{ident["parameters"][n]:9.4g}' for n in KWOK_CURRENT_NAMES))
        if truth:
            lines.append('  ' + f'{"truth":>9s} ' + ' '.join(
                f'{truth[n]:9.4g}' for n in KWOK_CURRENT_NAMES))
            errs = {k: v for k, v in (ident.get('parameter_error_percent') or {}).items()
                    if v is not None}
            if errs:
                worst = max(errs, key=lambda k: abs(errs[k]))
                lines.append(f'  parameter errors: largest {errs[worst]:+.2f} % ({worst}); '
                             + ', '.join(f'{k} {v:+.1f} %' for k, v in errs.items()))
            if ident.get('truth_nrmse_percent') is not None:
                lines.append(f'  true parameters on the same samples: NRMSE '
                             f'{ident["truth_nrmse_percent"]:.2f} % (noise floor)')
        else:
            if ident.get('truth_model') == 'spencer':
                lines.append('  truth is a Spencer (Bouc-Wen) damper: no kwok-current truth; the '
                             'force error above is the error against it')
            best = ident.get('offline_best_fit')
            if best:
                lines.append('  ' + f'{"offline":>9s} ' + ' '.join(
                    f'{best["parameters"][n]:9.4g}' for n in KWOK_CURRENT_NAMES))
                lines.append(f'  offline best kwok-current fit of the whole record: NRMSE '
                             f'{best["nrmse_percent"]:.2f} % (live final '
                             f'{ident.get("nrmse_percent") or 0:.2f} %)')
    hist = [h for h in ident.get('history', []) if h.get('record_nrmse_percent') is not None]
    if hist:
        pts = hist[:: max(1, len(hist) // 6)]
        lines.append('  error over time (NRMSE on the whole record): ' + ', '.join(
            f'{h["t_s"]:.0f} s: {h["record_nrmse_percent"]:.1f} %' for h in pts))
    ride = s.get('ride') or {}
    if ride.get('skyhook') and ride.get('passive'):
        sk, pa = ride['skyhook'], ride['passive']
        w = ride.get('window_s', [0, 0])
        lines.append(f'ride ({ride.get("controller")} vs passive@'
                     f'{ride.get("passive_current_a")} A, same road/seed, '
                     f'sim time {w[0]:.1f}..{w[1]:.1f} s):')
        for key, unit in (('rms_body_accel_wk', 'm/s^2'), ('rms_body_accel', 'm/s^2'),
                          ('rms_tyre_load_ratio', '-'), ('rms_suspension_travel', 'm')):
            a, b = sk.get(key), pa.get(key)
            if a is not None and b is not None:
                lines.append(f'  {key:24s} live {a:8.4f}  passive {b:8.4f} {unit}'
                             f'  ({100 * (a - b) / b:+.1f} %)')
        soft = ride.get('passive_0a')
        if soft and None not in (soft.get('rms_body_accel_wk'), soft.get('rms_tyre_load_ratio'),
                                 sk.get('rms_body_accel_wk'), sk.get('rms_tyre_load_ratio')):
            wk0, ty0 = soft['rms_body_accel_wk'], soft['rms_tyre_load_ratio']
            lines.append(f'  vs passive@0 A (softest, best comfort): Wk {wk0:.4f} m/s^2 '
                         f'({100 * (sk["rms_body_accel_wk"] / wk0 - 1):+.1f} %), tyre load '
                         f'{ty0:.4f} ({100 * (sk["rms_tyre_load_ratio"] / ty0 - 1):+.1f} %)')
        if ride.get('note'):
            lines.append(f'  note: {ride["note"]}')
    lines.append(f'fail-safe: {s.get("failsafe_s") or 0:.2f} s in total; '
                 f'refused parameter sets: {(s.get("failsafe") or {}).get("params_rejected")}')
    lines.append(f'messages lost: {s.get("messages_lost")} ({s.get("messages")})')
    can = s.get('can')
    if can:
        lines.append(f'CAN ({can["corner"]}): bridge sent {can["frames_sent"]} command frames '
                     f'({can["resent"]} re-sends), driver received {can["received"]}: lost '
                     f'{can["lost"]}, counter jumps {can["counter_jumps"]}, bad checksums '
                     f'{can["bad_checksum"]}; bridge fail-safe entries '
                     f'{can["failsafe_entries"]} ({can["failsafe_s"] or 0:.2f} s), faults '
                     f'{can["bridge_faults"] or "none"}')
    if s.get('sensing'):
        from .sensing_report import format_sensing
        lines.extend(format_sensing(s['sensing']))
    lines.extend(restart_lines(s))
    loop = s.get('loop_full_run') or {}
    m2p = s.get('measurement_to_parameters_s')
    if m2p:
        lines.append(f'newest sample of a window -> its parameters at the car: p50 '
                     f'{1e3 * m2p["p50"]:.0f} ms, p99 {1e3 * m2p["p99"]:.0f} ms')
    if loop.get('period'):
        p, lat = loop['period'], loop['latency']
        lines.append(f'control loop: period p50 {p["p50_ms"]:.3f} ms, jitter p99 '
                     f'{p.get("jitter_p99_ms") or float("nan"):.3f} ms; state -> command '
                     f'p50 {lat["p50_ms"]:.3f} ms, p99 {lat["p99_ms"]:.3f} ms')
    if s.get('hil'):
        from mr_damper_bringup.car_in_the_loop import format_hil_summary
        lines.append(format_hil_summary(s['hil']))
    return '\n'.join(lines)


def restart_lines(s):
    """Return the summary lines on the recording's completeness and the restarts of nodes."""
    lines = []
    rec = s.get('recording') or {}
    if rec.get('complete') is False:
        lines.append(f'recording INCOMPLETE: {rec.get("note")}')
        parts = rec.get('parts') or ()
        t0 = parts[0].get('first_log_time_s') if parts else None
        for p in parts:
            if not p['complete'] and p.get('last_log_time_s') is not None and t0 is not None:
                lines.append(f'  {p["file"]}: truncated after {p["messages"]} messages, the '
                             f'last {p["last_log_time_s"] - t0:.1f} s after the recording\'s '
                             'start')
    restarts = s.get('restarts') or []
    if restarts:
        lines.append(f'restarts: {len(restarts)} ' + '(' + ', '.join(
            f'{n} {c}' for n, c in (s.get('restart_counts') or {}).items()) + ')')
    for r in restarts:
        how = r.get('signal') or f'exit {r.get("exit_code")}'
        line = f'  {r["node"]} died at {r["death_s"]:.1f} s ({how}), '
        line += ('not restarted before the end' if r.get('restart_s') is None
                 else f'restarted at {r["restart_s"]:.1f} s')
        if r.get('failsafe_s') is not None:
            line += (f'; car in fail-safe {r["failsafe_s"]:.1f} s of the '
                     f'{r["window_s"]:.1f} s after it, without state {r["no_car_state_s"]:.1f} s')
        if r.get('measurements_lost') is not None:
            line += f'; {r["measurements_lost"]} measurements lost to the identifier'
        lines.append(line)
    gave = s.get('gave_up')
    if gave:
        lines.append(f'gave up: {gave["node"]} died {gave["deaths_in_window"]} times within '
                     f'{gave["restart_window_s"]:g} s (last at {gave["death_s"]:.1f} s)')
    return lines


def main(argv=None):
    """Regenerate ``summary.json`` and the plots of a finished run: ``report OUT``."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print('usage: python -m mr_damper_bringup.report RUN_OUTPUT_FOLDER', file=sys.stderr)
        return 2
    summary = make_report(argv[0])
    print(format_summary(summary))
    return 0


if __name__ == '__main__':
    sys.exit(main())
