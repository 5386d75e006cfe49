"""
Acceptance of live parameter sets on the shared Quiroz files: clean and with sensor faults.

    .venv/bin/python bench/bench_acceptance.py [--data-dir DIR] [--files GLOB] [--quick]

Every shared Quiroz record (sine tests that start and stop) is replayed sample by sample through
:class:`mr_damper_model.live.LiveIdentifier` with the identifier node's defaults as under
``use_sim_time`` (every window fitted in order, seeded per window, no wall-time budget), clean and
with four injected load-cell faults in its steady part: a 1e30 N spike, the force stuck for
0.3 s, a 0.2 s dropout to 0 N and a 1 s +400 N offset step.  Each configuration is run with the
acceptance rules off (``acceptance_checks=False``: the previous rules) and on, in the same run.

Per file it prints, for each configuration:

- ``final/best``: RMS error of the final valid set of the clean replay on the steady part of the
  clean record, over the smallest such error of any valid set of that replay (goal <= 1.1);
- ``worst fault/clean``: over the valid sets of the faulted replay, the largest ratio of the set's
  steady-part error to that of the set the clean replay held at the same window (goal <= 1.25).

The steady part: the samples whose velocity amplitude (maximum ``|v|`` over one excitation
period around them) is within 10 % of the record's median amplitude, the longest such run, less
one period at each end.  Errors are RMS force errors [N] of the kwok-current force of a set at
the record's current against the measured force.
"""
import argparse
from dataclasses import fields
import os
from pathlib import Path
import sys
import time

import numpy as np
from scipy.ndimage import maximum_filter1d

from mr_damper_model.data import DamperData, read_csv
from mr_damper_model.identify import identify
from mr_damper_model.kwok_current import kwok_current_force
from mr_damper_model.live import LiveConfig, LiveIdentifier

REPO = Path(__file__).resolve().parents[1]
#: the identifier node's defaults as a replay under use_sim_time runs them
NODE = dict(backlog_windows=300)
#: goals of issue 20
GOAL_FINAL = 1.1
GOAL_FAULT = 1.25
FAULTS = ('spike', 'stuck', 'dropout', 'offset')


def default_data_dir():
    """Return the directory of the Quiroz files the tests read (``tests/conftest.py``)."""
    sys.path.insert(0, str(REPO / 'tests'))
    from conftest import QUIROZ_DIR
    return QUIROZ_DIR


def excitation_period_s(data):
    """Period of the strongest displacement harmonic [s]."""
    x = data.x - np.mean(data.x)
    dt = float(np.median(np.diff(data.t)))
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    freq = np.fft.rfftfreq(x.size, dt)
    k = 1 + int(np.argmax(spec[1:]))
    return 1.0 / float(freq[k])


def steady_mask(data):
    """Mask of the steady part of a record (see the module docstring)."""
    period = excitation_period_s(data)
    dt = float(np.median(np.diff(data.t)))
    n_period = max(int(round(period / dt)), 1)
    amp = maximum_filter1d(np.abs(data.v), size=n_period, mode='nearest')
    ok = np.abs(amp - np.median(amp)) <= 0.1 * np.median(amp)
    # longest run
    edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(np.int8), 0]))
    starts, ends = edges[::2], edges[1::2]
    k = int(np.argmax(ends - starts))
    a, b = starts[k] + n_period, ends[k] - n_period
    mask = np.zeros(data.n, dtype=bool)
    mask[a:max(a, b)] = True
    return mask


def inject_faults(data, steady):
    """Return the record with the four faults in its steady part and their spans [s]."""
    t = data.t
    ts = t[steady]
    a, span = float(ts[0]), float(ts[-1] - ts[0])
    f = data.f.copy()
    spans = {}
    k = int(np.searchsorted(t, a + 0.15 * span))
    f[k] = 1e30
    spans['spike'] = (t[k], t[k])
    for name, frac, length in (('stuck', 0.3, 0.3), ('dropout', 0.45, 0.2),
                               ('offset', 0.6, 1.0)):
        t0 = a + frac * span
        sel = (t >= t0) & (t < t0 + length)
        idx = np.flatnonzero(sel)
        if name == 'stuck':
            f[idx] = f[idx[0]]
        elif name == 'dropout':
            f[idx] = 0.0
        else:
            f[idx] += 400.0
        spans[name] = (float(t[idx[0]]), float(t[idx[-1]]))
    return DamperData(t, data.x, data.v, f, data.i, source=data.source), spans


def replay(data, config):
    """Feed a record sample by sample; return [(window end [s], estimate)] and the status."""
    li = LiveIdentifier(config)
    out = []
    for row in zip(data.t, data.x, data.v, data.f, data.i):
        li.add_sample(*row)
        window = li.next_window()
        if window is not None:
            est = li.process(window)
            if est is not None:
                out.append((float(window.end_s), est))
    return out, li.status()


def steady_error(params, data, mask, i_ref_a):
    """RMS error [N] of a kwok-current set on the masked samples."""
    f = kwok_current_force(dict(params, i_ref_a=i_ref_a), data.x[mask], data.v[mask],
                           data.i[mask])
    return float(np.sqrt(np.mean((data.f[mask] - f) ** 2)))


def valid_errors(published, data, mask, i_ref_a):
    """[(window end, error of the valid set published then)] in order."""
    cache = {}
    out = []
    for end, est in published:
        if not est.valid:
            continue
        key = tuple(sorted(est.parameters.items()))
        if key not in cache:
            cache[key] = steady_error(est.parameters, data, mask, i_ref_a)
        out.append((end, cache[key]))
    return out


def held_at(errors, end):
    """Error of the valid set a replay held at window end ``end`` (None before its first)."""
    held = None
    for e, err in errors:
        if e > end + 1e-9:
            break
        held = err
    return held


def evaluate(path, config_changes):
    data = read_csv(path)
    steady = steady_mask(data)
    best_kwok = identify(data.select(steady), 'kwok', method='separable', seed=1)
    best_rmse = float(best_kwok.metrics['rmse_n'])
    faulted, spans = inject_faults(data, steady)
    rows = {}
    for label, changes in config_changes.items():
        config = LiveConfig(**dict(NODE, **changes))
        t0 = time.perf_counter()
        clean_pub, clean_status = replay(data, config)
        fault_pub, fault_status = replay(faulted, config)
        seconds = time.perf_counter() - t0
        clean = valid_errors(clean_pub, data, steady, config.i_ref_a)
        fault = valid_errors(fault_pub, data, steady, config.i_ref_a)
        row = {'seconds': seconds, 'n_valid_clean': len(clean), 'n_valid_fault': len(fault),
               'clean_status': clean_status, 'fault_status': fault_status}
        if clean:
            errs = [e for _, e in clean]
            row.update(final=errs[-1], best=min(errs), final_best=errs[-1] / min(errs),
                       final_vs_kwok=errs[-1] / best_rmse)
        if fault:
            errs = [e for _, e in fault]
            row.update(fault_final_best=errs[-1] / min(errs))
            ratios = []
            for end, err in fault:
                ref = held_at(clean, end)
                if ref is not None:
                    ratios.append((err / ref, end))
            if ratios:
                worst, at = max(ratios)
                row.update(worst_fault=worst, worst_at=at)
        rows[label] = row
    return {'file': Path(path).name, 'n': data.n, 'steady_s': float(np.ptp(data.t[steady])),
            'best_kwok_rmse': best_rmse, 'spans': spans, 'rows': rows}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--data-dir', default=None,
                   help='Quiroz files (default: the tests\' QUIROZ_DIR)')
    p.add_argument('--files', default='quiroz_sine_*.csv*', help='glob inside the directory')
    p.add_argument('--only', choices=('before', 'after'), default=None)
    args = p.parse_args(argv)
    os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
    data_dir = Path(args.data_dir) if args.data_dir else default_data_dir()
    paths = sorted(data_dir.glob(args.files))
    configs = {'before': {}, 'after': {}}
    if 'acceptance_checks' in {f.name for f in fields(LiveConfig)}:
        configs = {'before': {'acceptance_checks': False}, 'after': {'acceptance_checks': True}}
    if args.only:
        configs = {args.only: configs[args.only]}
    print(f'load average at start: {os.getloadavg()[0]:.2f}; {len(paths)} files from {data_dir}')
    head = f'{"file":<40} {"steady":>6} {"kwok":>6}'
    for label in configs:
        head += f' | {label + " final/best":>17} {"worst f/c":>9} {"at":>6} {"s":>5}'
    print(head)
    results = []
    for path in paths:
        r = evaluate(path, configs)
        results.append(r)
        line = f'{r["file"][:40]:<40} {r["steady_s"]:6.1f} {r["best_kwok_rmse"]:6.1f}'
        for label in configs:
            row = r['rows'][label]
            line += (f' | {row.get("final_best", float("nan")):17.3f}'
                     f' {row.get("worst_fault", float("nan")):9.3f}'
                     f' {row.get("worst_at", float("nan")):6.1f} {row["seconds"]:5.1f}')
        print(line, flush=True)
    for label in configs:
        fb = [r['rows'][label].get('final_best', np.nan) for r in results]
        wf = [r['rows'][label].get('worst_fault', np.nan) for r in results]
        print(f'{label}: final/best max {np.nanmax(fb):.3f} (files over {GOAL_FINAL}: '
              f'{sum(1 for v in fb if not v <= GOAL_FINAL)}), worst fault/clean max '
              f'{np.nanmax(wf):.3f} (files over {GOAL_FAULT}: '
              f'{sum(1 for v in wf if not v <= GOAL_FAULT)})')
    print(f'load average at end: {os.getloadavg()[0]:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
