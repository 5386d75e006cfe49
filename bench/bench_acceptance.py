"""
Acceptance of live parameter sets on the shared Quiroz files: clean and with sensor faults.

    .venv/bin/python bench/bench_acceptance.py [--data-dir DIR] [--files GLOB]
        [--configs previous,issue20,after] [--cases steady|start|all]

Every shared Quiroz record (sine tests that start and stop) is replayed sample by sample through
:class:`mr_damper_model.live.LiveIdentifier` with the identifier node's defaults as under
``use_sim_time`` (every window fitted in order, seeded per window, no wall-time budget), clean and
with four injected load-cell faults in its steady part: a 1e30 N spike, the force stuck for
0.3 s, a 0.2 s dropout to 0 N and a 1 s +400 N offset step.  The rule sets compared in one run
(``--configs``): ``previous`` (``acceptance_checks=False``, the rules before issue 20),
``issue20`` (the acceptance review, without the force-step check: ``force_step_percent=0``) and
``after`` (the node's defaults: with the force-step check of issue 32); by default the last two.
Start-of-stream cases (issue 32): the same record with a 1 s +400 N offset 1.5 s after its
start and a 1e30 N spike at 4 s (``live_records.inject_start_faults``), shifted into the first,
second and third window: faults that arrive before a good set exists, which no comparison with
a set in use can catch.

Per file it prints, for each configuration:

- ``final/best``: RMS error of the final valid set of the clean replay on the steady part of the
  clean record, over the smallest such error of any valid set of that replay (goal <= 1.1);
- ``worst fault/clean``: over the valid sets of the faulted replay, the largest ratio of the set's
  steady-part error to that of the set the clean replay held at the same window (goal <= 1.25;
  nan when the faulted replay published no valid set: the 2 mm records are so short that the
  faults fill every window);
- ``at``: the window end of that set [s]; ``s``: seconds of all replays; ``fs``: windows of
  the clean replay whose set the force-step check refused (false alarms on clean data);
- ``start w/c``: the same ratio over the valid sets of the three start-of-stream replays
  (judged against the clean replay's set at the same window, or its first valid set when it
  had none yet), worst of the three (goal <= 1.25; nan when none published a valid set);
  ``w``: the window (1-3) of that worst case;
- ``f/kwok``: the final valid set's steady-part error over ``kwok`` (absolute quality: a replay
  that never takes a good set meets ``final/best`` with a poor final set).

The steady part (``live_records.steady_mask``): the samples whose velocity amplitude (maximum
``|v|`` over one excitation period around them) is within 10 % of the record's median amplitude,
the longest such run, less one period at each end; the faults: ``live_records.inject_faults``.
Errors are RMS force errors [N] of the kwok-current force of a set at the record's current
against the measured force; ``steady``: its length [s]; ``kwok``: the RMS error of the best
offline Kwok fit of the steady part [N] (for scale).
"""
import argparse
import os
from pathlib import Path
import sys
import time

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / 'tests'))
from live_records import (clean_reference, held_at, inject_faults,  # noqa: E402
                          inject_start_faults, replay_published, steady_errors, steady_mask)
from mr_damper_model.io.data import read_csv  # noqa: E402
from mr_damper_model.identification.identify import identify  # noqa: E402
from mr_damper_model.live import LiveConfig, LiveIdentifier  # noqa: E402

#: the identifier node's defaults as a replay under use_sim_time runs them
NODE = dict(backlog_windows=300)
#: goals of issue 20
GOAL_FINAL = 1.1
GOAL_FAULT = 1.25
#: the start-of-stream faults in the first, second and third window (issue 32)
START_WINDOWS = (1, 2, 3)
#: the rule sets compared (LiveConfig changes): the rules before issue 20, its acceptance review
#: without issue 32's force-step check, the node's defaults
CONFIGS = {'previous': {'acceptance_checks': False, 'force_step_percent': 0.0},
           'issue20': {'acceptance_checks': True, 'force_step_percent': 0.0},
           'after': {}}


def default_data_dir():
    """Return the directory of the Quiroz files the tests read (``tests/conftest.py``)."""
    from conftest import QUIROZ_DIR
    return QUIROZ_DIR


def replay(data, config):
    """Replay a record through a new identifier; return [(window end, estimate)], status."""
    li = LiveIdentifier(config)
    return replay_published(li, data), li.status()


def worst_ratio(faulted, clean, reference=held_at):
    """Return (worst ratio, window end) of faulted sets' errors over the clean reference's."""
    ratios = []
    for end, err in faulted:
        ref = reference(clean, end)
        if ref is not None:
            ratios.append((err / ref, end))
    return max(ratios) if ratios else (np.nan, np.nan)


def evaluate(path, config_changes, cases='all'):
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
        fault_pub, fault_status = replay(faulted, config) if cases != 'start' else ([], {})
        start_pubs = {}
        if cases != 'steady':
            for w in START_WINDOWS:
                start_data, start_spans = inject_start_faults(data, w, config.window_s)
                if 'offset' in start_spans:
                    start_pubs[w] = replay(start_data, config)[0]
        seconds = time.perf_counter() - t0
        clean = steady_errors(clean_pub, data, steady, config.i_ref_a)
        fault = steady_errors(fault_pub, data, steady, config.i_ref_a)
        row = {'seconds': seconds, 'n_valid_clean': len(clean), 'n_valid_fault': len(fault),
               'clean_status': clean_status, 'fault_status': fault_status,
               'clean_force_steps': clean_status['windows_refused'].get('force_step', 0)}
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
        starts = {}
        for w, pub in start_pubs.items():
            errs = steady_errors(pub, data, steady, config.i_ref_a)
            starts[w] = worst_ratio(errs, clean, clean_reference) + (len(errs),)
        row['start'] = starts
        judged = [(r, w) for w, (r, _, _) in starts.items() if np.isfinite(r)]
        if judged:
            row['worst_start'], row['worst_start_window'] = max(judged)
        rows[label] = row
    return {'file': Path(path).name, 'n': data.n, 'steady_s': float(np.ptp(data.t[steady])),
            'best_kwok_rmse': best_rmse, 'spans': spans, 'rows': rows}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--data-dir', default=None,
                   help='Quiroz files (default: the tests\' QUIROZ_DIR)')
    p.add_argument('--files', default='quiroz_sine_*.csv*', help='glob inside the directory')
    p.add_argument('--configs', default='issue20,after',
                   help=f'comma-separated rule sets of {tuple(CONFIGS)}')
    p.add_argument('--cases', choices=('steady', 'start', 'all'), default='all',
                   help='faults in the steady part, at the start of the stream, or both')
    args = p.parse_args(argv)
    os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
    data_dir = Path(args.data_dir) if args.data_dir else default_data_dir()
    paths = sorted(data_dir.glob(args.files))
    configs = {name: CONFIGS[name] for name in args.configs.split(',')}
    print(f'load average at start: {os.getloadavg()[0]:.2f}; {len(paths)} files from {data_dir}')
    head = f'{"file":<40} {"steady":>6} {"kwok":>6}'
    for label in configs:
        head += (f' | {label + " final/best":>17} {"f/kwok":>6} {"worst f/c":>9} {"at":>6}'
                 f' {"start w/c":>9} {"w":>2} {"fs":>3} {"s":>5}')
    print(head)
    results = []
    for path in paths:
        r = evaluate(path, configs, args.cases)
        results.append(r)
        line = f'{r["file"][:40]:<40} {r["steady_s"]:6.1f} {r["best_kwok_rmse"]:6.1f}'
        for label in configs:
            row = r['rows'][label]
            line += (f' | {row.get("final_best", float("nan")):17.3f}'
                     f' {row.get("final_vs_kwok", float("nan")):6.2f}'
                     f' {row.get("worst_fault", float("nan")):9.3f}'
                     f' {row.get("worst_at", float("nan")):6.1f}'
                     f' {row.get("worst_start", float("nan")):9.3f}'
                     f' {row.get("worst_start_window", 0):2d} {row["clean_force_steps"]:3d}'
                     f' {row["seconds"]:5.1f}')
        print(line, flush=True)
    for label in configs:
        fb = [r['rows'][label].get('final_best', np.nan) for r in results]
        wf = [r['rows'][label].get('worst_fault', np.nan) for r in results]
        none = sum(1 for v in wf if np.isnan(v))
        print(f'{label}: final/best max {np.nanmax(fb):.3f} (files over {GOAL_FINAL}: '
              f'{sum(1 for v in fb if v > GOAL_FINAL)}), worst fault/clean max '
              f'{np.nanmax(wf):.3f} (files over {GOAL_FAULT}: '
              f'{sum(1 for v in wf if v > GOAL_FAULT)}; {none} with no valid set in the '
              'faulted replay: nan)')
        ws = [r['rows'][label].get('worst_start', np.nan) for r in results]
        cases = [(w, c) for r in results for w, c in r['rows'][label]['start'].items()]
        over = sum(1 for _, c in cases if np.isfinite(c[0]) and c[0] > GOAL_FAULT)
        worst = np.nanmax(ws) if np.isfinite(ws).any() else np.nan
        print(f'{label}: start of stream worst {worst:.3f} '
              f'(cases over {GOAL_FAULT}: {over} of {len(cases)}; files over: '
              f'{sum(1 for v in ws if v > GOAL_FAULT)} of {len(results)}; cases with no valid '
              f'set: {sum(1 for _, c in cases if c[2] == 0)})')
    print(f'load average at end: {os.getloadavg()[0]:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
