"""Ride figures of a run: the live car against passive dampers on the same road, loop timing."""
from array import array
import math

import numpy as np

from mr_damper_bringup.config import node_params, QC, RIG
from mr_damper_bringup.report import recording
from mr_damper_common.recording.columnlog import open_log


def _static_load(qc_params):
    return _car_params(qc_params).static_tyre_load


def _car_params(qc_params):
    from semi_active_control.car.quarter_car import QuarterCarParams
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
    from quarter_car_sim.metrics.quarter_car import RunningRideMetrics
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
    from quarter_car_sim.simulate import live_loop
    from semi_active_control.laws import Passive
    from quarter_car_sim.simulate.quarter_car import simulate_blocks
    g = qc_params.get
    car = _car_params(qc_params)
    from mr_damper_model.io.params_file import load_plant
    from quarter_car_sim.plant.road import make_road
    road = make_road(g('road', 'iso8608'), road_class=g('road_class', 'C'),
                     speed_m_s=g('speed_m_s', 20.0), rng=int(g('road_seed', 1)),
                     duration_s=g('road_duration_s', 300.0), dt=dt,
                     file=g('road_file', ''), repeat=bool(g('road_repeat', False)))
    current = float(g('safe_current_a', 0.5) if current is None else current)
    plant = load_plant(g('plant', 'spencer'), g('truth_file', ''))
    duration = max(float(t_end) + dt, dt)
    blocks = simulate_blocks(car, road, Passive(current), plant, dt=dt,
                             settle_s=g('settle_s', live_loop.SETTLE_S), duration_s=duration)
    n_total = int(round(duration / dt)) + 1
    m = _metrics_of_blocks(blocks, window or (0.0, float(t_end)), car.static_tyre_load, dt,
                           keep=keep, n_total=n_total)
    m.update(static_load=car.static_tyre_load, current_a=current)
    return m


def _trace_blocks(log, columns):
    for c in log.chunks(recording.CHUNK_ROWS, columns):
        yield c


#: ``ride_summary(law_first_normal_t=FROM_LOG)``: the law's first normal step from the log
FROM_LOG = 'log'


def ride_summary(log, qc_params, law_first_normal_t=FROM_LOG):
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
    law_first_normal_t : float, None or :data:`FROM_LOG`
        Car time [s] of the law's first step on a model: from the log's ``mode`` (the car runs
        the law), or given (an external controller: the car's mode says only that commands
        came; None: the controller never had a model).

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
    for c in log.chunks(recording.CHUNK_ROWS, ('t', 'mode')):
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
    if law_first_normal_t != FROM_LOG:
        t_first_normal = math.inf if law_first_normal_t is None else float(law_first_normal_t)
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


def hil_report_config(cfg):
    """Config for the report of a HIL run: the passive reference drives the rig's damper."""
    import copy
    from mr_damper_bringup.config import set_param
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
    ``real_time_factor_measured``: simulated over wall time of the whole run (first to last
    step; 1 = the loop kept real time on average); ``real_time_factor_median``: the step over
    the median period (what a typical step achieved).
    """
    from quarter_car_sim.simulate.live_loop import timing_stats
    log = open_log(log)
    step = max(1, int(math.ceil(log.rows / MAX_TIMING_SAMPLES)))
    per_keep, lat_keep = array('d'), array('d')
    n_per = n_lat = 0
    sum_per = sum_lat = 0.0
    min_per, max_per, max_lat = math.inf, -math.inf, -math.inf
    t_first = t_last = math.nan
    seen = 0
    for c in log.chunks(recording.CHUNK_ROWS, ('t', 'wall', 'compute_s'), overlap=1):
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
    wall_span = sum_per if n_per else 0.0
    return {'period': period, 'latency': latency,
            'real_time_factor_measured': (t_last - t_first) / wall_span if wall_span > 0
            else None,
            'real_time_factor_median': dt / nominal if nominal else None,
            'sim_time_s': t_last - t_first, 'timing_sample_stride': step}
