"""
Benchmark of the batch identification (``mr-damper-identify --batch``): serial vs Dask workers.

    .venv/bin/python bench/bench_batch.py [--dampers 200] [--repeat 3] [--keep DIR]

Archive (generated, the truth known): the master is kwok-current (i_ref 1 A) fitted to the
shared Quiroz files 10 mm / 1 Hz at 0, 0.5 and 1 A (seed 1). Each damper is one folder with one
CSV: the motion and currents of those three files (every 4th sample, 250 Hz, about 8,700
samples), the force of the master's model with its viscous and hysteretic coefficients (c0, c1,
alpha0..2) scaled by a factor drawn per damper, plus Gaussian noise of the master's own fit
RMSE. About 80 % of the factors lie in 0.95-1.05 and 20 % in 0.75-0.85 or 1.15-1.30; the true
pass / fail is the envelope of the true parameters against the master's with the batch's rule
(10 % / 20 N at 0.02, 0.04, 0.06 m/s, 10 mm stroke, 0 / 0.5 / 1 A). Two dampers get a
truncated file and two a file with a wrong column name (truth: error).

Runs: serially in this process (``workers=0``), and on a loopback LocalCluster of 1 and 2
single-threaded worker processes, each ``--repeat`` times with ``force`` (every damper redone).
Prints per run kind the median wall time (with the cluster start and stop), the median
throughput from the first to the last finished damper ("steady"), the speed-ups, the CPU
seconds of the run (this process and its worker processes: the work, whatever the load),
whether every table is byte-identical to the serial one, and the confusion matrix of the
batch's status against the truth. The machine load is printed at the start and the end (2 shared
cores: a loaded machine gives less speed-up).
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from mr_damper_model.identification import batch  # noqa: E402
from mr_damper_model.tools.cli import read_record  # noqa: E402
from mr_damper_model.io.data import DamperData, write_csv  # noqa: E402
from mr_damper_model.identification.identify import identify  # noqa: E402
from mr_damper_model.models import get_model  # noqa: E402
from mr_damper_model.io.params_file import save_params  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
QUIROZ_DIRS = (REPO / 'data' / 'quiroz_mr_damper',)
LEVELS = (('0A', 0.0), ('0p5A', 0.5), ('1p0A', 1.0))
SCALED = ('c0', 'c1', 'alpha0', 'alpha1', 'alpha2')
OPTIONS = {'i_ref_a': 1.0}
VELOCITIES = (0.02, 0.04, 0.06)
CURRENTS = (0.0, 0.5, 1.0)
STROKE = 0.01


def quiroz_motion():
    """Return the three 10 mm / 1 Hz Quiroz records joined, every 4th sample."""
    for d in QUIROZ_DIRS:
        found = [sorted(d.glob(f'quiroz_sine_10mm1Hz_{tag}_preproc.csv*')) for tag, _ in LEVELS]
        if all(found):
            parts = [read_record(str(f[0])) for f in found]
            break
    else:
        raise SystemExit(f'bench_batch: no Quiroz 10 mm / 1 Hz files in {QUIROZ_DIRS}')
    parts = [p.select(slice(None, None, 4)) for p in parts]
    return DamperData.concatenate(parts, restamp=True), d


def make_archive(root, n, seed):
    """Write the archive; return (master file, truth {record: status}, scale {record: s})."""
    data, src = quiroz_motion()
    res = identify(data, 'kwok-current', seed=1, model_options=OPTIONS)
    master = root.parent / 'master.json'
    save_params(master, dict(res.to_json_dict(), source=f'{src}: 10 mm / 1 Hz, 0-1 A'))
    mdl = get_model('kwok-current', **OPTIONS)
    ref = batch.force_envelope('kwok-current', OPTIONS, res.parameters, CURRENTS, VELOCITIES,
                               STROKE)
    sigma = res.metrics['rmse_n']
    rng = np.random.default_rng(seed)
    truth, scales = {}, {}
    bad = {n // 3: 'truncated', n // 3 + 1: 'truncated', 2 * n // 3: 'columns',
           2 * n // 3 + 1: 'columns'}
    for k in range(n):
        name = f'SN{k:04d}'
        if rng.random() < 0.8:
            s = rng.uniform(0.95, 1.05)
        else:
            s = rng.choice([rng.uniform(0.75, 0.85), rng.uniform(1.15, 1.30)])
        p = {q: v * s if q in SCALED else v for q, v in res.parameters.items()}
        f = mdl.force(mdl.from_dict(p), data.x, data.v, i=data.i, t=data.t)
        f = f + sigma * rng.standard_normal(f.size)
        (root / name).mkdir(parents=True)
        path = root / name / 'eol.csv'
        write_csv(path, DamperData(data.t, data.x, data.v, f, data.i))
        env = batch.force_envelope('kwok-current', OPTIONS, p, CURRENTS, VELOCITIES, STROKE)
        ok = np.all(batch.envelope_ratio(env, ref, batch.DEFAULT_REL_TOL,
                                         batch.DEFAULT_ABS_TOL_N) <= 1.0)
        truth[name], scales[name] = ('pass' if ok else 'fail'), s
        if k in bad:
            text = path.read_text()
            path.write_text(text[:len(text) // 2] if bad[k] == 'truncated'
                            else text.replace('t,x,v,f,i', 't,x,v,force,i', 1))
            truth[name] = 'error'
    return master, truth, scales, sigma


def run(root, settings, table, workers):
    stamps = []
    c0 = _cpu()
    t0 = time.perf_counter()
    out = batch.run_batch(root, settings, table=table, workers=workers, force=True,
                          progress=False, callback=lambda r: stamps.append(time.perf_counter()))
    wall = time.perf_counter() - t0
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0]) if len(stamps) > 1 else float('nan')
    return wall, rate, _cpu() - c0, out


def _cpu():
    """CPU seconds of this process and its finished children (the cluster's workers)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--dampers', type=int, default=200)
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--seed', type=int, default=7)
    ap.add_argument('--keep', metavar='DIR', help='write the archive and tables here')
    a = ap.parse_args()
    print(f'bench_batch: load at start {os.getloadavg()}, {os.cpu_count()} CPUs')
    work = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix='bench_batch_'))
    try:
        root = work / 'archive'
        if root.exists():
            shutil.rmtree(root)
        t0 = time.perf_counter()
        master, truth, scales, sigma = make_archive(root, a.dampers, a.seed)
        print(f'archive: {a.dampers} dampers in {time.perf_counter() - t0:.1f} s '
              f'({sum(v == "pass" for v in truth.values())} truly pass, '
              f'{sum(v == "fail" for v in truth.values())} fail, '
              f'{sum(v == "error" for v in truth.values())} bad files); noise {sigma:.1f} N')
        m = batch.load_master(master)
        settings = batch.BatchSettings(master=m, currents_a=CURRENTS, velocities_mps=VELOCITIES,
                                       stroke_m=STROKE)
        results, tables = {}, {}
        for rep in range(a.repeat):
            for label, workers in (('serial', 0), ('1 worker', 1), ('2 workers', 2)):
                table = work / f'table_{workers}_{rep}.csv'
                results.setdefault(label, []).append(run(root, settings, table, workers))
                tables.setdefault(label, []).append(table.read_bytes())
        ref = tables['serial'][0]
        print(f'\n{"run":<12}{"wall [s]":>10}{"dampers/s":>12}{"steady /s":>12}'
              f'{"speed-up":>10}{"CPU [s]":>10}{"same table":>12}')
        med = {}
        for label, rs in results.items():
            wall = statistics.median(r[0] for r in rs)
            steady = statistics.median(r[1] for r in rs)
            cpu = statistics.median(r[2] for r in rs)
            med[label] = wall
            same = all(t == ref for t in tables[label])
            print(f'{label:<12}{wall:>10.2f}{a.dampers / wall:>12.2f}{steady:>12.2f}'
                  f'{med["serial"] / wall:>10.2f}{cpu:>10.1f}{str(same):>12}')
        print(f'speed-up 2 workers vs 1 worker (wall, medians of {a.repeat}): '
              f'{med["1 worker"] / med["2 workers"]:.2f}')
        rows = {r['record']: r for r in batch.read_table(work / 'table_2_0.csv')}
        kinds = ('pass', 'fail', 'error')
        print('\nconfusion matrix (rows: truth, columns: batch status)')
        print(f'{"":<8}' + ''.join(f'{k:>8}' for k in kinds))
        for t in kinds:
            print(f'{t:<8}' + ''.join(
                f'{sum(truth[r] == t and rows[r]["status"] == k for r in truth):>8}'
                for k in kinds))
        wrong = [r for r in truth if rows[r]['status'] != truth[r]]
        for r in wrong:
            print(f'  mismatch {r}: scale {scales[r]:.3f}, truth {truth[r]}, batch '
                  f'{rows[r]["status"]} ({rows[r]["reason"] or rows[r]["error"]})')
        print(f'\nbench_batch: load at end {os.getloadavg()}')
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
