"""The summary of a suite run: made from the recording, printed and written as JSON."""
import json
import math
from pathlib import Path
import sys
import tempfile

import numpy as np

from mr_damper_bringup.config import IDENT, node_params, QC, RIG
from mr_damper_bringup.report.control import control_summary, format_control
from mr_damper_bringup.report.identification import (identification_summary,
                                                     measurement_to_parameters)
from mr_damper_bringup.report.losses import (attribute_losses, can_summary, messages_summary,
                                             restart_figures, restart_lines)
from mr_damper_bringup.report.recording import (MEAS_COLUMNS, ParamsLog,
                                                read_recording, RECORDING, recording_state)
from mr_damper_bringup.report.ride import (FROM_LOG, hil_report_config, loop_figures,
                                           ride_summary)
from mr_damper_bringup.topics import CONFIG_TOPIC
from mr_damper_common.contract import KWOK_CURRENT_NAMES
from mr_damper_common.health import finite_or_none
from mr_damper_common.recording.columnlog import ArrayLog, ColumnReader, exists


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
    from mr_damper_bringup.recorder import recording_parts
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
                             'bad_messages': rec['bad_messages'],
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
        # with an external controller the law's first step on a model is the controller's
        law_t0 = (rec['control'].law_first_t_sim('') if qc_params.get('controller') == 'external'
                  else FROM_LOG)
        ride = ride_summary(log, qc_params, law_t0)
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
        # --external-controller: the link car state -> controller -> current command; the
        # commands lost on it are the controller's `commands` less the car's received ones
        # (Float64 carries no number: docs/faults.md, Lost messages)
        summary['controller_link'] = {
            'command_timeouts': qc_status.get('command_timeouts'),
            'command_timeout_s_total': qc_status.get('command_timeout_s_total'),
            'commands_received': qc_status.get('commands_received'),
            'controller_commands': (ctrl_status or {}).get('commands'),
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
    summary['control'] = control_summary(rec['control'], rec.get('start_epoch_s'), summary,
                                         logs={'': log})
    summary = finite_or_none(summary)
    (out / 'summary.json').write_text(json.dumps(summary, indent=2, allow_nan=False))
    if plots:
        from mr_damper_bringup import plots as suite_plots
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
    from mr_damper_bringup.recorder import recording_parts
    from mr_damper_bringup.sensing_report import sensing_summary
    parts = [f for _, f in recording_parts(out / RECORDING)]
    summary['sensing'] = sensing_summary(rec.get('status', {}), qc_status, parts)


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
    bad = (s.get('recording') or {}).get('bad_messages')
    if bad:
        lines.append('bad recorded messages, left out of the figures: ' + '; '.join(
            f'{key} ' + ', '.join(f'{n} {reason}' for reason, n in sorted(reasons.items()))
            for key, reasons in sorted(bad.items())))
    can = s.get('can')
    if can:
        lines.append(f'CAN ({can["corner"]}): bridge sent {can["frames_sent"]} command frames '
                     f'({can["resent"]} re-sends), driver received {can["received"]}: lost '
                     f'{can["lost"]}, counter jumps {can["counter_jumps"]}, bad checksums '
                     f'{can["bad_checksum"]}; bridge fail-safe entries '
                     f'{can["failsafe_entries"]} ({can["failsafe_s"] or 0:.2f} s), faults '
                     f'{can["bridge_faults"] or "none"}')
    if s.get('sensing'):
        from mr_damper_bringup.sensing_report import format_sensing
        lines.extend(format_sensing(s['sensing']))
    lines.extend(restart_lines(s))
    if s.get('control'):
        lines.append(format_control(s['control']))
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


def main(argv=None):
    """Regenerate ``summary.json`` and the plots of a finished run: ``report OUT``."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print('usage: python -m mr_damper_bringup.report RUN_OUTPUT_FOLDER', file=sys.stderr)
        return 2
    summary = make_report(argv[0])
    print(format_summary(summary))
    return 0
