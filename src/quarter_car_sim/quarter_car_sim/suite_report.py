"""
Summary and plots of one suite run (``launch_scripts/run_suite.py``), without ROS.

Inputs, all in the run's output folder:

- ``suite_params.yaml``: the single parameter file the three nodes were started with;
- ``measurement.npz`` (t, x, v, f, i of every measurement the launcher's recorder received) and
  ``recording.json`` (every ``/mr_damper/kwok_parameters`` message with its wall receipt time,
  the true parameters, the last status of each node, ...), written by the launcher;
- ``quarter_car_log.npz``: every control step of the quarter-car node (``live_loop.TRACE_COLUMNS``)
  and its final status, written by the node at shutdown.

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

Command line (regenerate from a finished run): ``python -m quarter_car_sim.suite_report OUT``.
"""
import json
import math
from pathlib import Path
import sys

import numpy as np

from mr_damper_model.models import get_model

KWOK_CURRENT_NAMES = get_model('kwok-current').param_names


def _load_yaml(path):
    import yaml
    return yaml.safe_load(Path(path).read_text())


def _node_params(cfg, node):
    merged = dict((cfg or {}).get('/**', {}).get('ros__parameters', {}))
    merged.update((cfg or {}).get(node, {}).get('ros__parameters', {}))
    return merged


def _finite_or_none(value):
    if isinstance(value, dict):
        return {str(k): _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def model_force(params, x, v, i):
    """
    Force [N] of the kwok-current model with named parameters (``i_ref_a`` optional).

    Parameters
    ----------
    params : dict
        Kwok-current parameters by name (and ``i_ref_a`` [A], default 2).
    x, v, i : array_like with shape (n,)
        Displacement [m], velocity [m/s], coil current [A].

    Returns
    -------
    numpy.ndarray with shape (n,)

    """
    model = get_model('kwok-current', i_ref_a=float(params.get('i_ref_a', 2.0)))
    return model.force(model.from_dict(params), x, v, i=i)


def fit_error(f_meas, f_model):
    """Return ``(rmse_n, nrmse_percent)``; NRMSE normalised by the measured force range."""
    f_meas = np.asarray(f_meas, dtype=float)
    err = np.asarray(f_model, dtype=float) - f_meas
    if f_meas.size == 0:
        return math.nan, math.nan
    rmse = float(np.sqrt(np.mean(err ** 2)))
    span = float(np.ptp(f_meas))
    return rmse, (100.0 * rmse / span if span > 0 else math.nan)


def offline_best_fit(meas, *, budget_s=5.0, max_samples=8000, seed=1):
    """
    Fit kwok-current offline to the whole record (``mr_damper_model.identify``): a yardstick.

    When the true damper is not a kwok-current model (the Spencer plant), no parameter can be
    compared with a truth; the best kwok-current fit of everything recorded says how close the
    live estimate is to the best this model can do.

    Returns
    -------
    dict or None
        ``parameters``, ``rmse_n``, ``nrmse_percent`` (on the whole record), ``seconds``; None
        if the record covers fewer than two current levels or the fit fails.

    """
    from mr_damper_model.data import DamperData
    from mr_damper_model.identify import identify
    t, x, v, f, i = (np.asarray(meas[k], dtype=float) for k in ('t', 'x', 'v', 'f', 'i'))
    if np.unique(np.round(i / 0.05)).size < 2:
        return None
    step = max(1, int(math.ceil(t.size / max_samples)))
    sel = slice(None, None, step)
    try:
        res = identify(DamperData(t[sel], x[sel], v[sel], f[sel], i[sel], source='suite'),
                       'kwok-current', seed=seed, budget_s=budget_s)
    except (ValueError, FloatingPointError, np.linalg.LinAlgError):
        return None
    p = dict(res.parameters, i_ref_a=float((res.model_options or {}).get('i_ref_a', 2.0)))
    rmse, nrmse = fit_error(f, model_force(p, x, v, i))
    return {'parameters': res.parameters, 'rmse_n': rmse, 'nrmse_percent': nrmse,
            'seconds': res.seconds}


def identification_summary(meas, params_log, truth=None, *, max_history=80,
                           offline_budget_s=5.0):
    """
    Identification figures of a run.

    Parameters
    ----------
    meas : dict
        Arrays ``t, x, v, f, i`` of the recorded measurements.
    params_log : list of (float, dict)
        Wall receipt time [s] and decoded ``/mr_damper/kwok_parameters`` message.
    truth : dict, optional
        True kwok-current parameters (when the plant is kwok-current).
    max_history : int
        At most this many history entries are evaluated on the whole record.
    offline_budget_s : float
        Compute budget [s] of :func:`offline_best_fit` (run when there is no kwok-current
        truth; 0 = skip).

    Returns
    -------
    dict

    """
    valid = [(t, p) for t, p in params_log if p.get('valid') == 1.0]
    out = {'updates': len(params_log), 'valid_updates': len(valid),
           'first_valid_s': valid[0][0] if valid else None,
           'rmse_n': math.nan, 'nrmse_percent': math.nan, 'parameters': None, 'truth': None,
           'reported_rmse_n': math.nan, 'reported_nrmse_percent': math.nan, 'history': []}
    x, v, f, i = (np.asarray(meas.get(k, []), dtype=float) for k in 'xvfi')
    if valid:
        final = valid[-1][1]
        out['parameters'] = {n: final[n] for n in KWOK_CURRENT_NAMES if n in final}
        out['parameters']['i_ref_a'] = final.get('i_ref_a', 2.0)
        out['reported_rmse_n'] = final.get('rmse_n', math.nan)
        out['reported_nrmse_percent'] = final.get('nrmse_percent', math.nan)
        out['current_range_a'] = [final.get('current_min_a'), final.get('current_max_a')]
        if f.size:
            out['rmse_n'], out['nrmse_percent'] = fit_error(f, model_force(final, x, v, i))
    if truth:
        tp = {n: truth[n] for n in KWOK_CURRENT_NAMES if n in truth}
        if len(tp) == len(KWOK_CURRENT_NAMES):
            tp['i_ref_a'] = truth.get('i_ref_a', 2.0)
            out['truth'] = tp
            if out['parameters']:
                out['parameter_error_percent'] = {
                    n: (100.0 * (out['parameters'][n] - tp[n]) / abs(tp[n]) if tp[n] else math.nan)
                    for n in KWOK_CURRENT_NAMES}
            if f.size:
                out['truth_rmse_n'], out['truth_nrmse_percent'] = fit_error(
                    f, model_force(tp, x, v, i))
    if f.size and not out['truth'] and offline_budget_s > 0:
        out['offline_best_fit'] = offline_best_fit(meas, budget_s=offline_budget_s)
    step = max(1, int(math.ceil(len(params_log) / max_history)))
    picks = list(range(0, len(params_log), step))
    if params_log and picks[-1] != len(params_log) - 1:
        picks.append(len(params_log) - 1)
    dec = slice(None, None, max(1, f.size // 20000))      # <= ~20k samples per evaluation
    for k in picks:
        t, p = params_log[k]
        entry = {'t_s': t, 'valid': p.get('valid') == 1.0, 'rmse_n': p.get('rmse_n'),
                 'nrmse_percent': p.get('nrmse_percent'),
                 'parameters': {n: p.get(n) for n in KWOK_CURRENT_NAMES}}
        if f.size and all(math.isfinite(p.get(n, math.nan)) for n in KWOK_CURRENT_NAMES):
            with np.errstate(over='ignore', invalid='ignore'):
                fm = model_force(p, x[dec], v[dec], i[dec])
            if np.all(np.isfinite(fm)):
                entry['record_rmse_n'], entry['record_nrmse_percent'] = fit_error(f[dec], fm)
        out['history'].append(entry)
    return out


def _windowed_metrics(trace, mask, static_load, dt):
    from quarter_car_sim.ride_metrics import ride_metrics, wk_filter
    sub = {k: np.asarray(trace[k])[mask] for k in ('t', 'a_s', 'travel', 'tyre_force',
                                                   'damper_force')}
    sub['current_cmd'] = np.asarray(trace['current_cmd'])[mask]
    m = ride_metrics(sub, static_load=static_load)
    # Wk filter over the whole run, RMS over the window (no filter start-up in the window)
    wk = wk_filter(np.asarray(trace['a_s'], dtype=float), 1.0 / dt)[mask]
    m['rms_body_accel_wk'] = float(np.sqrt(np.mean(wk ** 2)))
    return m


def passive_reference(qc_params, t_end, dt, current=None):
    """
    Simulate the passive damper (safe current) on the node's road, plant and car, offline.

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

    Returns
    -------
    dict
        Arrays ``t, a_s, travel, tyre_force, damper_force, current_cmd``, ``static_load`` and
        ``current_a``.

    """
    from quarter_car_sim import live_loop
    from quarter_car_sim.controllers import Passive
    from quarter_car_sim.params import QuarterCarParams
    from quarter_car_sim.road import RoadProfile
    from quarter_car_sim.simulate import simulate
    g = qc_params.get
    car = QuarterCarParams(m_s=g('m_s', 300.0), m_u=g('m_u', 60.0), k_s=g('k_s', 16000.0),
                           k_t=g('k_t', 190000.0))
    road = live_loop.make_road(g('road', 'iso8608'), road_class=g('road_class', 'C'),
                               speed_m_s=g('speed_m_s', 20.0), seed=g('road_seed', 1),
                               duration_s=g('road_duration_s', 300.0), dt=dt,
                               file=g('road_file', ''))
    n = min(road.n, int(round(t_end / dt)) + 2)
    road = RoadProfile(road.t[:n], road.z[:n], road.zdot[:n], name=road.name,
                       speed_m_s=road.speed_m_s)
    current = float(g('safe_current_a', 0.5) if current is None else current)
    plant = live_loop.make_plant(g('plant', 'spencer'), g('truth_file', ''))
    res = simulate(car, road, Passive(current), plant, dt=dt,
                   settle_s=g('settle_s', live_loop.SETTLE_S))
    return {'t': res.t, 'a_s': res.a_s, 'travel': res.travel, 'tyre_force': res.tyre_force,
            'damper_force': res.damper_force, 'current_cmd': res.current_cmd,
            'static_load': car.static_tyre_load, 'current_a': current}


def ride_summary(log, qc_params):
    """
    Ride metrics of the live controller against the passive damper on the same road.

    Both are evaluated on the same simulated-time window: from the first control step in normal
    mode (the controller actually used a model) to the end of the live run.

    Returns
    -------
    dict
        ``skyhook`` and ``passive`` metric dicts, ``controller``, ``passive_current_a``,
        ``window_s`` and ``wk_improvement_percent`` (positive = live controller better).

    """
    from quarter_car_sim.params import QuarterCarParams
    t = np.asarray(log['t'], dtype=float)
    dt = float(log['dt']) if 'dt' in log else float(np.median(np.diff(t)))
    mode = np.asarray(log['mode'])
    g = qc_params.get
    static = QuarterCarParams(m_s=g('m_s', 300.0), m_u=g('m_u', 60.0), k_s=g('k_s', 16000.0),
                              k_t=g('k_t', 190000.0)).static_tyre_load
    normal = np.flatnonzero(mode > 0.5)
    t0 = max(0.0, float(t[normal[0]])) if normal.size else math.inf
    out = {'controller': g('controller', 'skyhook'),
           'passive_current_a': float(g('safe_current_a', 0.0)), 'window_s': [t0, float(t[-1])],
           'normal_fraction': float(mode[t >= 0].mean()) if np.any(t >= 0) else 0.0}
    live = {'t': t, 'a_s': log['a_s'], 'travel': log['travel'], 'tyre_force': log['tyre_force'],
            'damper_force': log['damper_force'], 'current_cmd': log['i_cmd']}
    mask = t >= t0
    if mask.sum() < 2:
        # never in normal mode: compare the whole run (the live car was passive throughout)
        mask = t >= 0.0
        out['window_s'] = [0.0, float(t[-1])]
        out['note'] = 'the controller never left fail-safe: both runs are passive'
    out['skyhook'] = _windowed_metrics(live, mask, static, dt)
    ref = passive_reference(qc_params, float(t[-1]), dt)
    rt = np.asarray(ref['t'])
    rmask = (rt >= out['window_s'][0] - 0.5 * dt) & (rt <= out['window_s'][1] + 0.5 * dt)
    out['passive'] = _windowed_metrics(ref, rmask, static, dt)
    out['passive_trace'] = {'t': rt, 'a_s': np.asarray(ref['a_s'])}
    if out['passive_current_a'] != 0.0:
        # the softest passive setting too (best for comfort on this damper): the honest
        # comfort baseline, while the safe current is the car without identification
        soft = passive_reference(qc_params, float(t[-1]), dt, current=0.0)
        out['passive_0a'] = _windowed_metrics(soft, rmask, static, dt)
    a, b = out['skyhook']['rms_body_accel_wk'], out['passive']['rms_body_accel_wk']
    out['wk_improvement_percent'] = 100.0 * (b - a) / b if b > 0 else math.nan
    return out


def measurement_to_parameters(meas, params_log):
    """
    Delays [s] from the newest measurement of each identified window to its parameters.

    The newest sample's arrival (the launcher's recorder receives the measurement stream as the
    identifier does) is found from its stamp ``window_end_s``; the delay runs to the arrival of
    the parameter message at the recorder (the quarter car subscribes to it the same way and
    uses it from its next 1 ms step on). Windows older than the record are ignored.

    Returns
    -------
    numpy.ndarray
        One delay per parameter message [s].

    """
    t = np.asarray(meas.get('t', []), dtype=float)
    recv = np.asarray(meas.get('recv_epoch_s', []), dtype=float)
    if t.size < 2 or recv.size != t.size:
        return np.zeros(0)
    out = []
    for _, p in params_log:
        end, got = p.get('window_end_s', math.nan), p.get('recv_epoch_s', math.nan)
        if math.isfinite(end) and math.isfinite(got) and t[0] <= end <= t[-1]:
            out.append(got - float(np.interp(end, t, recv)))
    return np.asarray(out)


def messages_summary(rec, qc_status):
    """
    Measurements lost on their way to the identifier.

    The launcher's recorder takes the same stream; the samples in its stamp span (received plus
    stamp gaps) are what the rig published in that span (the rig waits for both subscribers
    before its first sample and stops before the identifier), so the identifier lost
    ``span - samples_received``. Gaps at the recorder itself are listed but are not losses of
    the suite (the recorder is a monitor in the launcher process, not one of its nodes).

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


def _first(d, keys):
    for k in keys:
        if isinstance(d.get(k), (int, float)):
            return d[k]
    return None


def make_report(out, *, duration_s=None, config=None, plots=True):
    """
    Build ``summary.json`` (and plots) for the run in folder ``out``.

    Parameters
    ----------
    out : path
        Run output folder (see the module docstring for the inputs).
    duration_s : float, optional
        Wall duration of the run [s] (default: from the quarter-car log).
    config : dict, optional
        The parameter YAML as a dict (default: read ``suite_params.yaml``).
    plots : bool
        Also write the PNG plots.

    Returns
    -------
    dict
        The summary (as written to ``summary.json``).

    """
    out = Path(out)
    cfg = config if config is not None else _load_yaml(out / 'suite_params.yaml')
    qc_params = _node_params(cfg, 'quarter_car_node')
    rig_params = _node_params(cfg, 'mr_damper_rig')
    rec = json.loads((out / 'recording.json').read_text())
    with np.load(out / 'measurement.npz') as z:
        meas = {k: z[k] for k in z.files}
    params_log = [(t, p) for t, p in rec.get('params', [])]
    truth = rec.get('truth')
    summary = {'duration_s': duration_s,
               'config': 'replay' if rig_params.get('mode', 'sim') != 'sim' else 'sim',
               'plant': qc_params.get('plant', 'spencer')}
    summary['identification'] = identification_summary(meas, params_log, truth)
    summary['identification']['truth_model'] = (
        'kwok-current' if summary['identification']['truth'] else
        ('spencer' if rec.get('truth_spencer') else None))
    if rec.get('truth_spencer'):
        summary['identification']['truth_spencer'] = rec['truth_spencer']
    log_path = out / 'quarter_car_log.npz'
    log = None
    if log_path.exists():
        with np.load(log_path) as z:
            log = {k: z[k] for k in z.files}
    qc_status = json.loads(str(log['status'])) if log is not None and 'status' in log else \
        (rec.get('status', {}).get('quarter_car') or {})
    if log is not None and len(log['t']) > 10:
        ride = ride_summary(log, qc_params)
        passive_trace = ride.pop('passive_trace')
        summary['ride'] = ride
        if duration_s is None:
            summary['duration_s'] = float(log['wall'][-1] - log['wall'][0])
    else:
        summary['ride'] = {'skyhook': None, 'passive': None, 'note': 'no quarter-car log'}
        passive_trace = None
    summary['failsafe_s'] = qc_status.get('failsafe_s')
    summary['failsafe'] = {k: qc_status.get(k) for k in (
        'mode', 'reason', 'failsafe_entries', 'params_accepted', 'params_rejected',
        'safe_current_a')}
    lost, breakdown = messages_summary(rec, qc_status)
    summary['messages_lost'] = lost
    summary['messages'] = breakdown
    summary['loop'] = qc_status.get('loop')
    if log is not None and len(log['t']) > 10:
        summary['loop_full_run'] = _loop_figures(log)
    if (out / 'process_stats.json').exists():
        summary['processes'] = json.loads((out / 'process_stats.json').read_text())
    lat = measurement_to_parameters(meas, params_log)
    if lat.size:
        summary['measurement_to_parameters_s'] = {
            'p50': float(np.percentile(lat, 50)), 'p99': float(np.percentile(lat, 99)),
            'max': float(lat.max()), 'n': int(lat.size)}
    summary = _finite_or_none(summary)
    (out / 'summary.json').write_text(json.dumps(summary, indent=2, allow_nan=False))
    if plots:
        from quarter_car_sim import suite_plots
        suite_plots.plot_all(out, meas, params_log, summary, log, passive_trace)
    return summary


def _loop_figures(log):
    from quarter_car_sim.live_loop import timing_stats
    wall = np.asarray(log['wall'], dtype=float)
    dt = float(log['dt'])
    rtf = None
    periods = np.diff(wall)
    if periods.size:
        nominal = float(np.median(periods))
        rtf = dt / nominal if nominal > 0 else None
    st = {'period': timing_stats(periods, float(np.median(periods)) if periods.size else None),
          'latency': timing_stats(np.asarray(log['compute_s'], dtype=float)),
          'real_time_factor_measured': rtf,
          'sim_time_s': float(log['t'][-1] - log['t'][0])}
    return st


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
        if soft:
            wk0, ty0 = soft['rms_body_accel_wk'], soft['rms_tyre_load_ratio']
            lines.append(f'  vs passive@0 A (softest, best comfort): Wk {wk0:.4f} m/s^2 '
                         f'({100 * (sk["rms_body_accel_wk"] / wk0 - 1):+.1f} %), tyre load '
                         f'{ty0:.4f} ({100 * (sk["rms_tyre_load_ratio"] / ty0 - 1):+.1f} %)')
        if ride.get('note'):
            lines.append(f'  note: {ride["note"]}')
    lines.append(f'fail-safe: {s.get("failsafe_s") or 0:.2f} s in total; '
                 f'refused parameter sets: {(s.get("failsafe") or {}).get("params_rejected")}')
    lines.append(f'messages lost: {s.get("messages_lost")} ({s.get("messages")})')
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
    return '\n'.join(lines)


def main(argv=None):
    """Regenerate ``summary.json`` and the plots of a finished run: ``suite_report OUT``."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print('usage: python -m quarter_car_sim.suite_report RUN_OUTPUT_FOLDER', file=sys.stderr)
        return 2
    summary = make_report(argv[0])
    print(format_summary(summary))
    return 0


if __name__ == '__main__':
    sys.exit(main())
