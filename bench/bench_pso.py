"""
Benchmark of the identification methods at equal budget (model evaluations), fixed seeds.

    .venv/bin/python bench/bench_pso.py [--seeds 10] [--budget 1000] [--all-quiroz]

Data: (1) a 2,000-sample window (2 s at 1 kHz, thesis cam 1.1 Hz / 30 mm, coil 0-2 A in 0.5 A
steps) from the thesis-like kwok-current truth with 1 % noise, model kwok-current; (2) the
shared Quiroz file 5 mm / 3 Hz / 0.5 A, model kwok. Methods: this project's separable (default,
its own stopping rule; its evaluations are reported) and full PSO, pyswarms GlobalBestPSO
(same swarm, iterations and inertia/c1/c2), scipy differential_evolution and multi-start
scipy least_squares (trf), all under the model's default bounds and the same number of model
evaluations. Prints median wall time, median RMSE and ratios to the best; the separable
method's final polish time is reported separately (the polish share). CPU times (process time,
single-threaded BLAS) are printed next to the wall times: on the shared 2-core machine the wall
time of a loaded machine is up to about twice the CPU time.

Time to quality (full PSO vs pyswarms): at equal evaluation count both spend their time in
model evaluations, so the equal-budget wall times cannot differ much; the standard comparison
is the wall time each needs to reach a given RMSE: pyswarms' and our full PSO's median final
RMSE at the common budget, and 10 % and 1 % above the best RMSE any method found. Each run is
traced (best RMSE so far against wall time) up to 10 times the common budget; medians over the
seeds, "n/s" when fewer than half the seeds reach the level (the ratio is then a lower bound:
pyswarms' whole capped run over our time to the level).

The load average of the machine is printed before and after (2 shared cores: timings of a
loaded machine are slower; the separable window target is 20 ms).
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import argparse  # noqa: E402
import logging  # noqa: E402
from pathlib import Path  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import differential_evolution, least_squares  # noqa: E402

from mr_damper_model.io.data import DamperData, read_csv, validate  # noqa: E402
import mr_damper_model.identification.identify as identify_module  # noqa: E402
from mr_damper_model.identification.identify import identify  # noqa: E402
from mr_damper_model.models import get_model  # noqa: E402
from mr_damper_model.identification.presets import thesis_kwok_current  # noqa: E402

QUIROZ = Path(__file__).resolve().parents[1] / 'data' / 'quiroz_mr_damper'
SWARM = 25


def window():
    m, truth = thesis_kwok_current()
    t = np.arange(2000) * 1e-3
    w = 2 * np.pi * 1.1
    x, v = 0.03 * np.sin(w * t), 0.03 * w * np.cos(w * t)
    i = np.repeat([0.0, 0.5, 1.0, 1.5, 2.0], 400)
    f = m.force(m.from_dict(truth), x, v, i=i, t=t)
    f = f + 0.01 * np.max(np.abs(f)) * np.random.default_rng(0).standard_normal(f.size)
    return DamperData(t, x, v, f, i, source='kwok-current window')


def rmse_of(m, d, p):
    return float(np.sqrt(np.mean((m.force(p, d.x, d.v, i=d.i, t=d.t) - d.f) ** 2)))


def run_pyswarms(m, d, lo, hi, budget, seed):
    import pyswarms as ps
    logging.getLogger('pyswarms').setLevel(logging.ERROR)
    np.random.seed(seed)            # pyswarms draws from the global generator
    opt = ps.single.GlobalBestPSO(n_particles=SWARM, dimensions=lo.size,
                                  options={'c1': 2.0, 'c2': 2.0, 'w': 0.65},
                                  bounds=(lo, hi), velocity_clamp=(-0.2 * (hi - lo).max(),
                                                                   0.2 * (hi - lo).max()))

    def cost(P):
        with np.errstate(over='ignore', invalid='ignore'):
            r = np.sqrt(np.mean((m.force(P, d.x, d.v, i=d.i, t=d.t) - d.f) ** 2, axis=1))
        return np.where(np.isfinite(r), r, 1e300)
    _, pos = opt.optimize(cost, iters=budget // SWARM - 1, verbose=False)
    return pos


def run_de(m, d, lo, hi, budget, seed):
    def cost(P):
        with np.errstate(over='ignore', invalid='ignore'):
            return np.sqrt(np.mean((m.force(P.T, d.x, d.v, i=d.i, t=d.t) - d.f) ** 2, axis=1))
    pop = 15
    res = differential_evolution(cost, list(zip(lo, hi)), popsize=pop, vectorized=True,
                                 maxiter=max(1, budget // (pop * lo.size) - 1), rng=seed,
                                 polish=False, tol=0, updating='deferred')
    return res.x


def run_multistart_ls(m, d, lo, hi, budget, seed):
    rng = np.random.default_rng(seed)
    best, best_x, used = np.inf, None, 0
    while used < budget:
        x0 = lo + rng.random(lo.size) * (hi - lo)
        try:
            r = least_squares(lambda p: m.force(p, d.x, d.v, i=d.i, t=d.t) - d.f, x0,
                              bounds=(lo, hi), method='trf', max_nfev=100)
        except ValueError:
            used += 1
            continue
        used += r.nfev + r.njev * (lo.size + 1)
        c = float(r.fun @ r.fun)
        if c < best:
            best, best_x = c, r.x
    return best_x


class _Reached(Exception):
    """Raised inside pyswarms' objective to stop it once a quality level is reached."""


def trace_full(d, model, seed, budget, level):
    """(time [s], best RMSE) after each iteration of this project's full PSO."""
    trace = []
    t0 = time.perf_counter()

    def cb(r):
        trace.append((time.perf_counter() - t0, r.fun))
        return bool(r.fun <= level)
    identify(d, model, method='full', seed=seed, maxiter=budget // SWARM - 1, tol=0,
             patience=10 ** 6, callback=cb)
    return trace


def trace_pyswarms(m, d, lo, hi, budget, seed, level):
    """(time [s], best RMSE) after each swarm evaluation of pyswarms GlobalBestPSO."""
    import pyswarms as ps
    logging.getLogger('pyswarms').setLevel(logging.ERROR)
    np.random.seed(seed)
    opt = ps.single.GlobalBestPSO(n_particles=SWARM, dimensions=lo.size,
                                  options={'c1': 2.0, 'c2': 2.0, 'w': 0.65},
                                  bounds=(lo, hi), velocity_clamp=(-0.2 * (hi - lo).max(),
                                                                   0.2 * (hi - lo).max()))
    trace = []
    best = [np.inf]
    t0 = time.perf_counter()

    def cost(P):
        with np.errstate(over='ignore', invalid='ignore'):
            r = np.sqrt(np.mean((m.force(P, d.x, d.v, i=d.i, t=d.t) - d.f) ** 2, axis=1))
        r = np.where(np.isfinite(r), r, 1e300)
        best[0] = min(best[0], float(r.min()))
        trace.append((time.perf_counter() - t0, best[0]))
        if best[0] <= level:
            raise _Reached
        return r
    try:
        opt.optimize(cost, iters=budget // SWARM - 1, verbose=False)
    except _Reached:
        pass
    return trace


def time_to(trace, level):
    return next((t for t, r in trace if r <= level), np.inf)


def time_to_quality(d, model, seeds, budget, levels):
    m = get_model(model)
    lo, hi = m.default_bounds()
    cap = 10 * budget
    print(f'\nTime to quality ({d.n} samples, model {model}, one traced run per seed and method, '
          f'capped at {cap} evaluations, {len(seeds)} seeds): median wall time [ms] to reach '
          'the RMSE level')
    print('| level | RMSE [N] | full PSO (this project) | pyswarms GlobalBestPSO | '
          'pyswarms / full |')
    print('|---|---:|---:|---:|---:|')
    stop = min(level for _, level in levels)
    traces_f = [trace_full(d, model, s, cap, stop) for s in seeds]
    traces_p = [trace_pyswarms(m, d, lo, hi, cap, s, stop) for s in seeds]
    for label, level in levels:
        t_f = [time_to(tr, level) for tr in traces_f]
        t_p = [time_to(tr, level) for tr in traces_p]

        def fmt(ts):
            ok = np.isfinite(ts).sum()
            med = np.median(ts)
            return (f'{med * 1e3:.1f} ({ok}/{len(ts)} reached)' if np.isfinite(med)
                    else f'n/s ({ok}/{len(ts)} reached)'), med
        sf, mf = fmt(t_f)
        sp, mp = fmt(t_p)
        if np.isfinite(mf) and np.isfinite(mp):
            ratio = f'{mp / mf:.1f}'
        elif np.isfinite(mf):       # pyswarms did not get there: its whole run is a lower bound
            ratio = f'> {np.median([tr[-1][0] for tr in traces_p]) / mf:.1f}'
        else:
            ratio = 'n/a'
        print(f'| {label} | {level:.3f} | {sf} | {sp} | {ratio} |')


def bench(name, d, model, seeds, budget):
    m = get_model(model)
    lo, hi = m.default_bounds()
    rows = {}
    cpu = {}

    def timed(label, fn):
        ts, cs, rs = [], [], []
        for s in seeds:
            t0, c0 = time.perf_counter(), time.process_time()
            p = fn(s)
            ts.append(time.perf_counter() - t0)
            cs.append(time.process_time() - c0)
            rs.append(rmse_of(m, d, p))
        rows[label] = (np.median(ts), np.median(rs))
        cpu[label] = np.median(cs)

    nfev = []
    polish_s = []
    orig_polish = identify_module._polish

    def timed_polish(*args, **kw):
        t0 = time.perf_counter()
        out = orig_polish(*args, **kw)
        polish_s[-1] += time.perf_counter() - t0
        return out

    def sep(s):
        polish_s.append(0.0)
        identify_module._polish = timed_polish
        try:
            r = identify(d, model, seed=s)
        finally:
            identify_module._polish = orig_polish
        nfev.append(r.nfev)
        return r.x
    timed('separable (default)', sep)
    timed('full PSO (this project)', lambda s: identify(
        d, model, method='full', seed=s, maxiter=budget // SWARM - 1, tol=0,
        patience=10 ** 6).x)
    timed('pyswarms GlobalBestPSO', lambda s: run_pyswarms(m, d, lo, hi, budget, s))
    timed('scipy differential_evolution', lambda s: run_de(m, d, lo, hi, budget, s))
    timed('multi-start least_squares', lambda s: run_multistart_ls(m, d, lo, hi, budget, s))
    best_t = min(v[0] for v in rows.values())
    best_r = min(v[1] for v in rows.values())
    print(f'\n{name}: model {model}, {d.n} samples, budget {budget} evaluations '
          f'(separable used median {int(np.median(nfev))}), {len(seeds)} seeds')
    print('| method | median wall time [ms] | median CPU time [ms] | median RMSE [N] | '
          'time / best | RMSE / best |')
    print('|---|---:|---:|---:|---:|---:|')
    for k, (t, r) in rows.items():
        print(f'| {k} | {t * 1e3:.1f} | {cpu[k] * 1e3:.1f} | {r:.4f} | {t / best_t:.2f} | '
              f'{r / best_r:.4f} |')
    share = np.median(np.array(polish_s) / np.array([rows['separable (default)'][0]]))
    print(f'separable: final polish (bounded Levenberg-Marquardt on all samples) median '
          f'{np.median(polish_s) * 1e3:.1f} ms, about {100 * share:.0f} % of the median wall time')
    return rows


def all_quiroz(seeds, budget):
    print('\n| file | default RMSE [N] | best other RMSE [N] | ratio | NRMSE [%] | mean % err |')
    print('|---|---:|---:|---:|---:|---:|')
    per_current = {}
    for path in sorted(QUIROZ.glob('*.csv.gz')):
        d = validate(read_csv(path))
        m = get_model('kwok')
        lo, hi = m.default_bounds()
        r = identify(d, 'kwok', seed=1)
        others = [identify(d, 'kwok', method='full', seed=1, maxiter=budget // SWARM - 1,
                           tol=0, patience=10 ** 6).x,
                  run_de(m, d, lo, hi, budget, 1), run_multistart_ls(m, d, lo, hi, budget, 1)]
        best = min(rmse_of(m, d, p) for p in others)
        best = min(best, r.metrics['rmse_n'])
        per_current.setdefault(float(d.i.mean().round(2)), []).append(
            r.metrics['mean_percent_error'])
        print(f'| {path.name} | {r.metrics["rmse_n"]:.3f} | {best:.3f} | '
              f'{r.metrics["rmse_n"] / best:.4f} | {r.metrics["nrmse_percent"]:.3f} | '
              f'{r.metrics["mean_percent_error"]:.2f} |')
    print('\n| current [A] | mean % error (mean over files) | thesis Table 4.2 |')
    print('|---:|---:|---|')
    for c, v in sorted(per_current.items()):
        print(f'| {c:.2f} | {np.mean(v):.2f} | 5.11-8.47 (0-2 A) |')


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seeds', type=int, default=10)
    ap.add_argument('--budget', type=int, default=1000)
    ap.add_argument('--all-quiroz', action='store_true')
    ap.add_argument('--no-ttq', action='store_true', help='skip the time-to-quality runs')
    a = ap.parse_args()
    seeds = list(range(a.seeds))
    print(f'load average before: {load()} ({os.cpu_count()} cores), '
          f'OPENBLAS_NUM_THREADS={os.environ.get("OPENBLAS_NUM_THREADS")}')
    if a.all_quiroz:
        all_quiroz(seeds, a.budget)
        return
    cases = [('2,000-sample window', window(), 'kwok-current'),
             ('Quiroz 5 mm 3 Hz 0.5 A',
              validate(read_csv(QUIROZ / 'quiroz_sine_5mm3Hz_0p5A.csv.gz')), 'kwok')]
    for name, d, model in cases:
        rows = bench(name, d, model, seeds, a.budget)
        if not a.no_ttq:
            best = min(r for _, r in rows.values())
            levels = [('pyswarms final RMSE at the common budget',
                       rows['pyswarms GlobalBestPSO'][1]),
                      ('full PSO final RMSE at the common budget',
                       rows['full PSO (this project)'][1]),
                      ('best RMSE any method found + 10 %', 1.10 * best),
                      ('best RMSE any method found + 1 %', 1.01 * best)]
            time_to_quality(d, model, seeds, a.budget, levels)
        print(f'load average now: {load()}')


def load():
    try:
        return ', '.join(f'{x:.2f}' for x in os.getloadavg())
    except OSError:
        return 'n/a'


if __name__ == '__main__':
    main()
