"""
Benchmark: identification time of the stateful models, compiled time loops against numpy.

What ``mr-damper-identify FILE --model M`` (and ``--compare``) runs with its default options:
:func:`mr_damper_model.identification.identify.identify` /
:func:`~mr_damper_model.identification.identify.compare_models`,
method ``separable``, default bounds; wall time of the whole call, median of 5 seeds, on two
shared Quiroz files. Each is run twice in the same process: with the compiled loops
(``bouc_wen.bouc_wen_z``, ``spencer.spencer_force``) and with today's numpy references
(``bouc_wen_z_numpy``, ``spencer_force_numpy``) patched in.

Spencer: the default identification (``identify(data, 'spencer')``: swarm on the state
parameters over the first seconds at coarse sub-steps, spring by least squares, bounded
Levenberg-Marquardt polish on all samples; see ``Spencer.identification``) is measured in full,
median of the seeds, with the NRMSE of each seed. The default before it (the full PSO over all 13
parameters without polish, 25 particles, 60 iterations: ``PREVIOUS_SPENCER``) is measured once
(seed 1, several minutes at load) in the same run, with its NRMSE. The time of one swarm
evaluation (25 particles, whole record, model sub-step) is printed for the compiled loop and
numpy (60-sample excerpt scaled to the record).

The first-call cost (numba import, then compile or cache load of each kernel) is measured in
fresh interpreters with an empty ``NUMBA_CACHE_DIR`` (compile) and then the same one (load).

Usage: ``python bench/bench_models.py [--seeds 5] [--numpy-seeds 5] [--skip-numpy]
[--skip-previous] [--only bouc-wen compare spencer]``
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')     # as the CLI does

import argparse  # noqa: E402
import contextlib  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
from pathlib import Path  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from mr_damper_model.models import bouc_wen, spencer  # noqa: E402
from mr_damper_model.io.data import read_csv, validate  # noqa: E402
from mr_damper_model.identification.identify import compare_models, identify  # noqa: E402

QUIROZ = Path(__file__).resolve().parents[1] / 'data' / 'quiroz_mr_damper'
FILES = ('quiroz_sine_25mm0x25Hz_1p0A.csv.gz', 'quiroz_sine_10mm1Hz_1p0A_preproc.csv.gz')
TARGETS_S = {'bouc-wen': 0.3, 'spencer': 2.0, 'compare': 2.0}
SWARM = 25
#: The Spencer default before the identification policy: what ``identify(data, 'spencer')``
#: ran then (method 'separable' fell back to the full PSO, without polish: maxiter 60,
#: patience 20, tol 1e-6).
PREVIOUS_SPENCER = {'method': 'full', 'maxiter': 60, 'patience': 20, 'tol': 1e-6}


@contextlib.contextmanager
def numpy_loops():
    """Patch today's numpy implementations in place of the compiled loops."""
    saved = bouc_wen.bouc_wen_z, spencer.spencer_force
    bouc_wen.bouc_wen_z = bouc_wen.bouc_wen_z_numpy
    spencer.spencer_force = spencer.spencer_force_numpy
    try:
        yield
    finally:
        bouc_wen.bouc_wen_z, spencer.spencer_force = saved


def _wall(fn):
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def time_identification(data, what, seeds, **kw):
    """
    Wall times [s], NRMSE [%] and particle evaluations of one identification per seed.

    ``what``: a model name (``identify(data, what, seed=seed, **kw)``) or ``'compare'``
    (``compare_models``, all models; its NRMSE is NaN).
    """
    times, nrmse, nfev = [], [], []
    for seed in seeds:
        if what == 'compare':
            dt, res = _wall(lambda: compare_models(data, seed=seed, method='separable'))
            nfev.append(sum(r.nfev for r in res.values()))
            nrmse.append(float('nan'))
        else:
            dt, res = _wall(lambda: identify(data, what, seed=seed, **kw))
            nfev.append(res.nfev)
            nrmse.append(res.metrics['nrmse_percent'])
        times.append(dt)
    return times, nrmse, nfev


def spencer_swarm_eval(data, *, numpy_excerpt=None):
    """Seconds per swarm evaluation (25 particles) of the Spencer force on the whole record."""
    m = spencer.Spencer()
    lo, hi = m.default_bounds()
    P = lo + (hi - lo) * np.random.default_rng(0).uniform(size=(SWARM, lo.size))
    n = data.n if numpy_excerpt is None else numpy_excerpt
    sel = slice(0, n)
    with np.errstate(all='ignore'):
        m.force(P[:2], data.x[:5], data.v[:5], data.i[:5], data.t[:5])     # first-call cost
        dt, _ = _wall(lambda: m.force(P, data.x[sel], data.v[sel], data.i[sel], data.t[sel]))
    return dt * data.n / n


_COLD = r"""
import json, time
t0 = time.perf_counter()
import numba  # noqa
t_import = time.perf_counter() - t0
import numpy as np
from mr_damper_model.models import compiled
from mr_damper_model.models.bouc_wen import bouc_wen_z
from mr_damper_model.models.spencer import Spencer
from mr_damper_model.identification.presets import spencer_thesis_like
t = np.arange(50) / 1000.0
v = np.cos(t)
t0 = time.perf_counter()
bouc_wen_z(np.ones(3), np.ones(3), np.ones(3), np.ones(3), v, t)
t_bw = time.perf_counter() - t0
m = Spencer()
t0 = time.perf_counter()
m.force(m.from_dict(spencer_thesis_like()), np.sin(t), v, np.ones(50), t)
t_sp = time.perf_counter() - t0
print(json.dumps({'import': t_import, 'bouc-wen': t_bw, 'spencer': t_sp,
                  'status': compiled.cache_status()}))
"""


def first_call_costs():
    """Compile and cache-load seconds of each kernel, in fresh interpreters."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        out = []
        for _ in range(2):
            proc = subprocess.run([sys.executable, '-c', _COLD], env=env, capture_output=True,
                                  text=True, check=True, timeout=600)
            out.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    return out


def _load():
    return ', '.join(f'{x:.2f}' for x in os.getloadavg())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--seeds', type=int, default=5)
    ap.add_argument('--numpy-seeds', type=int, default=5)
    ap.add_argument('--skip-numpy', action='store_true')
    ap.add_argument('--skip-previous', action='store_true',
                    help='do not run the previous Spencer default (minutes)')
    ap.add_argument('--only', nargs='+', choices=('bouc-wen', 'compare', 'spencer'),
                    default=('bouc-wen', 'compare', 'spencer'))
    args = ap.parse_args(argv)
    print(f'machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
          f'Python {platform.python_version()}, numpy {np.__version__}; '
          f'load average at start {_load()}')
    cold, warm = first_call_costs()
    print('\nfirst call in a fresh process [s]   compile (empty cache)   load (cache)')
    print(f'  import numba                       {cold["import"]:8.2f}'
          f'                {warm["import"]:8.2f}')
    for k in ('bouc-wen', 'spencer'):
        print(f'  {k:<34} {cold[k]:8.2f}                {warm[k]:8.2f}')
    hits = sum(s['cache_hits'] for s in warm['status'].values())
    print(f'  (second process: {hits} kernels loaded from the cache, '
          f'{sum(s["cache_misses"] for s in warm["status"].values())} compiled)')

    seeds = list(range(1, args.seeds + 1))
    np_seeds = list(range(1, args.numpy_seeds + 1))
    rows = []
    spencer_rows = []
    for name in FILES:
        data = validate(read_csv(QUIROZ / name))
        print(f'\n{name}: {data.n} samples at {data.sample_rate_hz:.0f} Hz '
              f'({data.duration:.1f} s)')
        for what in [w for w in ('bouc-wen', 'compare') if w in args.only]:
            identify(data.select(slice(0, 300)), 'bouc-wen', seed=0)     # warm the kernels
            times, _, nfev = time_identification(data, what, seeds)
            tc, nf = float(np.median(times)), int(np.median(nfev))
            if args.skip_numpy:
                tn = float('nan')
            else:
                with numpy_loops():
                    tn = float(np.median(time_identification(data, what, np_seeds)[0]))
            rows.append((name, data.n, what, tc, tn, nf, TARGETS_S[what]))
            print(f'  {what:<9} compiled {tc:7.3f} s (median of {len(seeds)}; '
                  f'{nf} particle evaluations)   numpy {tn:7.2f} s (median of {len(np_seeds)})'
                  f'   ratio {tn / tc:5.1f}x   target <= {TARGETS_S[what]} s   '
                  f'load {_load()}', flush=True)
        if 'spencer' not in args.only:
            continue
        identify(data.select(slice(0, 50)), 'spencer', seed=0)         # warm the kernel
        times, nrmse, nfev = time_identification(data, 'spencer', seeds)
        print(f'  spencer   default: median {np.median(times):.3f} s of seeds {seeds[0]}-'
              f'{seeds[-1]} ({", ".join(f"{x:.2f}" for x in times)} s); NRMSE '
              f'{", ".join(f"{x:.3f}" for x in nrmse)} %; particle evaluations '
              f'{int(np.median(nfev))}; target <= 2 s   load {_load()}', flush=True)
        if args.skip_previous:
            t_prev, nr_prev = [float('nan')], [float('nan')]
        else:
            t_prev, nr_prev, nf_prev = time_identification(data, 'spencer', seeds[:1],
                                                           **PREVIOUS_SPENCER)
            print(f'  spencer   previous default (full PSO, 13 parameters, {PREVIOUS_SPENCER}), '
                  f'seed {seeds[0]}, measured once: {t_prev[0]:.1f} s, NRMSE {nr_prev[0]:.3f} %, '
                  f'{nf_prev[0]} particle evaluations   load {_load()}', flush=True)
        spencer_rows.append((name, data.n, float(np.median(times)), float(np.median(nrmse)),
                             max(nrmse), t_prev[0], nr_prev[0]))
        tc_eval = spencer_swarm_eval(data)
        with numpy_loops():
            tn_eval = spencer_swarm_eval(data, numpy_excerpt=60)
        print(f'  spencer   one swarm evaluation ({SWARM} particles, whole record, 0.1 ms '
              f'sub-steps): compiled {tc_eval:.3f} s, numpy {tn_eval:.1f} s (60-sample excerpt '
              f'scaled), ratio {tn_eval / tc_eval:.0f}x   load {_load()}', flush=True)
    if rows:
        print('\n| file | samples | identification | compiled [s] | numpy [s] | ratio | '
              'target [s] |')
        print('|---|---|---|---|---|---|---|')
    for name, n, what, tc, tn, nf, target in rows:
        numpy = '- | -' if math.isnan(tn) else f'{tn:.3g} | {tn / tc:.0f}x'   # --skip-numpy
        print(f'| {name} | {n} | {what} | {tc:.3g} | {numpy} | {target} |')
    if spencer_rows:
        print('\n| file | samples | Spencer default, median [s] | NRMSE median (worst) [%] | '
              'previous default, seed 1 [s] | its NRMSE [%] | speed-up | target [s] |')
        print('|---|---|---|---|---|---|---|---|')
        for name, n, t_new, nr_new, nr_worst, t_prev, nr_prev in spencer_rows:
            prev = ('- | - | -' if math.isnan(t_prev) else     # --skip-previous
                    f'{t_prev:.3g} | {nr_prev:.3f} | {t_prev / t_new:.0f}x')
            print(f'| {name} | {n} | {t_new:.3g} | {nr_new:.3f} ({nr_worst:.3f}) | {prev} '
                  '| 2.0 |')
    print(f'\nload average at end {_load()}')


if __name__ == '__main__':
    main()
