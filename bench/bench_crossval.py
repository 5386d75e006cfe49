"""
Cross-validation of one-model-for-all-conditions damper models on the Quiroz files (data/).

    .venv/bin/python bench/bench_crossval.py [--models kwok-current kwok-current-lag
        kwok-current-amp ...]
        [--seed 1] [--workers 2] [--swarm-size 25] [--maxiter N] [--polish] [--inverse]
        [--splits N] [--data-dir DIR]

The six test series (25 mm at 0.1, 0.25, 0.5 Hz; 10 mm at 1 Hz; 5 mm at 3 Hz; 2 mm at 5 Hz,
each at 0, 0.25, 0.5, 0.75 and 1.0 A) are split every possible way into four training and two
held-out series (15 splits). For each split and model, ONE parameter set is identified on the
20 training files joined end to end (``DamperData.concatenate(parts, restamp=True)`` and
:func:`~mr_damper_model.identification.identify.identify`), and each of the 10 held-out files is
predicted
(stateful models start from rest on each file). The score of a prediction is the ratio of its
NRMSE to the NRMSE of that file's own best Kwok fit (plain ``kwok``, identified on the file
alone with the same seed; computed once per run). Printed per model: the median and the worst
ratio over all 150 predictions (each file is held out in 5 splits), the per-series table
(median ratio of each file over its 5 splits, then the series' median and worst), the median
fit time and the training NRMSE; then a summary of all models.

A model is written ``name`` or ``name@key=value,key=value`` (numeric model options, e.g.
``kwok-current@i_ref_a=1.0``, ``kwok-current-amp@tau_a=2``). Any registered model runs;
the prototypes of docs/cross-validation.md that are not package models run through
``bench/crossval_candidates.py`` (same arguments). Seeded and deterministic: every fit uses
``--seed``, results do not depend on ``--workers`` (a process pool of at most 2 workers,
single-threaded BLAS).
The load average of the machine is printed before and after.

``--in-sample`` scores the fits on the very files they were fitted to instead (no file held
out): each model once on all 30 files and once per current level on the six series at that
level. A figure of this kind is what a single parameter set of the model family can reach when
it has seen the answer; a held-out prediction is not expected to do better, so it tells
whether a goal on the cross-validated ratios is within the family's reach at all.
``--repeat R0,R1,R2,R3,R4`` repeats every training file at 0, 0.25, 0.5, 0.75 and 1.0 A that
many times (integer weights in the least squares: e.g. ``8,4,2,1,1`` gives the small forces of
the low currents a weight closer to the NRMSE's, which divides each file by its own range).
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
os.environ.setdefault('OMP_NUM_THREADS', '1')

import argparse  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
import itertools  # noqa: E402
from pathlib import Path  # noqa: E402
import re  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from mr_damper_model.io.data import DamperData, read_csv, validate  # noqa: E402
from mr_damper_model.identification.identify import identify  # noqa: E402
from mr_damper_model.identification.metrics import fit_metrics  # noqa: E402
from mr_damper_model.models import get_model  # noqa: E402

QUIROZ = Path(__file__).resolve().parents[1] / 'data' / 'quiroz_mr_damper'
SERIES = ('25mm0x1Hz', '25mm0x25Hz', '25mm0x5Hz', '10mm1Hz', '5mm3Hz', '2mm5Hz')
CURRENTS = ('0', '0p25', '0p5', '0p75', '1p0')
_NAME = re.compile(r'quiroz_sine_(?P<series>\w+?Hz)_(?P<current>\w+?)A(_preproc)?\.csv(\.gz)?$')
N_HELD_OUT = 2
#: Series distributed as the authors' own filtered files (force and displacement averaged over a
#: tenth of the period, v = diff(x)): their knee and loop are smoothed by the processing.
PREPROC = ('25mm0x1Hz', '10mm1Hz')

_DATA = {}          # per-process cache: (series, current) -> DamperData


def load(data_dir):
    """Read and validate the 30 files; return {(series, current): DamperData}."""
    out = {}
    for path in sorted(Path(data_dir).glob('quiroz_sine_*.csv*')):
        m = _NAME.match(path.name)
        if m and m['series'] in SERIES and m['current'] in CURRENTS:
            out[(m['series'], m['current'])] = validate(read_csv(path), name=path.name)
    missing = [k for k in itertools.product(SERIES, CURRENTS) if k not in out]
    if missing:
        raise SystemExit(f'bench_crossval: {data_dir}: missing files for {missing[:3]} ...')
    return out


def parse_model(spec):
    """``name@k=v,k=v`` -> (name, options dict)."""
    name, _, rest = spec.partition('@')
    opts = {}
    for item in filter(None, rest.split(',')):
        key, _, val = item.partition('=')
        opts[key] = float(val)
    return name, opts


def _init(data_dir):
    _DATA.update(load(data_dir))


def _nrmse(model, x, rec):
    f = model.force(x, rec.x, rec.v, i=rec.i, t=rec.t)
    if not np.all(np.isfinite(f)):
        return float('inf')
    return fit_metrics(rec.f, f)['nrmse_percent']


def _fit_file(key, seed):
    res = identify(_DATA[key], 'kwok', seed=seed)
    return key, (res.metrics['nrmse_percent'], res.parameters)


def _fit(spec, train_keys, scored_keys, seed, fit_kw, repeat):
    """Fit one set on ``train_keys`` (file k ``repeat[k[1]]`` times); score ``scored_keys``."""
    name, opts = parse_model(spec)
    train = DamperData.concatenate(
        [_DATA[k] for k in train_keys for _ in range(repeat.get(k[1], 1))], restamp=True)
    res = identify(train, name, seed=seed, model_options=opts, **fit_kw)
    model = get_model(name, **opts)
    pred = {k: _nrmse(model, res.x, _DATA[k]) for k in scored_keys}
    return pred, res.metrics['nrmse_percent'], res.seconds, res.parameters


def _fit_split(spec, held, seed, fit_kw, repeat=None):
    train = [(s, c) for s in SERIES if s not in held for c in CURRENTS]
    pred, train_nrmse, seconds, params = _fit(
        spec, train, [(s, c) for s in held for c in CURRENTS], seed, fit_kw, repeat or {})
    return spec, held, pred, train_nrmse, seconds, params


def _fit_in_sample(spec, current, seed, fit_kw, repeat=None):
    """Fit on all 30 files (``current`` None) or the six of one current; score the same."""
    keys = [(s, c) for s in SERIES for c in CURRENTS if current in (None, c)]
    pred, train_nrmse, seconds, params = _fit(spec, keys, keys, seed, fit_kw, repeat or {})
    return spec, current, pred, train_nrmse, seconds, params


def _short(series):
    return series.replace('mm0x', 'mm0.').replace('25Hz', '25Hz')


def report(spec, runs, best, what='splits'):
    """Print one model's figures; return (median, worst, ratios, ratios of the raw files)."""
    ratios = {}
    for _, held, pred, _, _, _ in runs:
        for key, nrmse in pred.items():
            ratios.setdefault(key, []).append(nrmse / best[key])
    flat = np.array([q for qs in ratios.values() for q in qs])
    raw = np.array([q for k, qs in ratios.items() if k[0] not in PREPROC for q in qs])
    worst_key = max(ratios, key=lambda k: max(ratios[k]))
    fit_s = np.median([r[4] for r in runs])
    train = np.median([r[3] for r in runs])
    print(f'\n== {spec}: {len(runs)} {what}, {flat.size} predictions; median fit {fit_s:.2f} s, '
          f'median training NRMSE {train:.2f} %')
    print(f'   ratio NRMSE / own-Kwok NRMSE: median {np.median(flat):.3f}, '
          f'90th pct {np.percentile(flat, 90):.3f}, worst {flat.max():.3f} '
          f'({worst_key[0]} {worst_key[1]} A)')
    if raw.size:
        print(f'   raw files only (not {", ".join(PREPROC)}): median {np.median(raw):.3f}, '
              f'worst {raw.max():.3f} over {raw.size} predictions')
    note = '(median over the 5 held-out splits)' if what == 'splits' else '(in-sample)'
    head = ' '.join(f'{c.replace("p", "."):>6s}' for c in CURRENTS)
    print(f'   {"series":11s} {head}   median  worst   {note}')
    for s in SERIES:
        if (s, CURRENTS[0]) not in ratios:
            continue
        cells = [np.median(ratios[(s, c)]) for c in CURRENTS]
        allq = [q for c in CURRENTS for q in ratios[(s, c)]]
        print(f'   {s:11s} ' + ' '.join(f'{q:6.3f}' for q in cells)
              + f'   {np.median(allq):6.3f} {np.max(allq):6.3f}')
    return float(np.median(flat)), float(flat.max()), flat, raw


def print_force_levels(data, band=(0.03, 0.04)):
    """Print each series' median force magnitude [N] with |v| in ``band`` [m/s], per current."""
    print(f'median |f| [N] at {band[0]}-{band[1]} m/s (both directions), per series and current:')
    for s in SERIES:
        cells = []
        for c in CURRENTS:
            rec = data[(s, c)]
            m = (np.abs(rec.v) >= band[0]) & (np.abs(rec.v) < band[1])
            cells.append(f'{np.median(np.abs(rec.f[m])):7.1f}' if m.sum() >= 20 else '      -')
        print(f'   {s:11s} ' + ' '.join(cells))


def print_own_beta(data, own):
    """Print each file's own Kwok beta [s/m] and its series' peak velocity V [m/s]."""
    print('own Kwok beta [s/m] per current; V = 99th percentile of |v| [m/s]:')
    for s in SERIES:
        v99 = np.percentile(np.abs(data[(s, CURRENTS[0])].v), 99)
        print(f'   {s:11s} V {v99:.3f} ' + ' '.join(
            f'{own[(s, c)][1]["beta"]:6.0f}' for c in CURRENTS))


def bench_inverse(data, params_lag, i_ref_a, n_calls=20000):
    """
    Median time per call [us]: kwok-current scalar inverse vs the kwok-current-lag one.

    Both compiled, as shipped; and the kwok-current one's algorithm interpreted (the same
    source, ``scalar_inverse.scalar_current``, run as plain Python on lists): the alternative
    the compiled one replaced.
    """
    from mr_damper_model.models.inverse import KwokCurrentInverse, KwokCurrentLagInverse
    from mr_damper_model.models.scalar_inverse import scalar_current
    rec = data[('5mm3Hz', '0p5')]
    k = min(n_calls, rec.n)
    x, v, f = rec.x[:k].tolist(), rec.v[:k].tolist(), rec.f[:k].tolist()
    dt = 1.0 / rec.sample_rate_hz
    inv_kc = KwokCurrentInverse(params_lag[:10], i_ref_a=i_ref_a, i_max=1.0)
    inv_lag = KwokCurrentLagInverse(params_lag, i_ref_a=i_ref_a, i_max=1.0)
    plain = [a.tolist() for a in inv_kc.kernel_arguments()] + [[]]
    out = {}
    for name, call in (('kwok-current', lambda j: inv_kc.current(f[j], x[j], v[j])),
                       ('kwok-current-lag', lambda j: inv_lag.step(f[j], x[j], v[j], dt)),
                       ('kwok-current interpreted',
                        lambda j: scalar_current(*plain, f[j], x[j], v[j]))):
        reps = []
        for _ in range(3):
            t0 = time.perf_counter()
            for j in range(k):
                call(j)
            reps.append((time.perf_counter() - t0) / k * 1e6)
        out[name] = float(np.median(reps))
    return out, k


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--models', nargs='+', default=['kwok-current'],
                   help='model specs name[@key=value,...] (default kwok-current)')
    p.add_argument('--data-dir', default=str(QUIROZ), help=f'Quiroz files (default {QUIROZ})')
    p.add_argument('--seed', type=int, default=1, help='identification seed (default 1)')
    p.add_argument('--workers', type=int, default=2, help='process pool size, 1 or 2')
    p.add_argument('--swarm-size', type=int, default=25, help='particles (default 25)')
    p.add_argument('--maxiter', type=int, default=None,
                   help='swarm iterations (default: identify\'s own per method)')
    p.add_argument('--polish', action='store_true',
                   help='identify(..., polish=True) for every model: the stateful ones too '
                   '(their swarm then works on every k-th sample, the polish on all)')
    p.add_argument('--inverse', action='store_true',
                   help='also time the scalar inverses (force -> current) per call, with the '
                   'kwok-current-lag parameters of the first split')
    p.add_argument('--splits', type=int, default=None,
                   help='use only the first N of the 15 splits (quick runs)')
    p.add_argument('--in-sample', action='store_true',
                   help='score the fits on their own training files: each model on all 30 '
                   'files, then per current level on the six series at that level')
    p.add_argument('--repeat', default=None, metavar='R0,R1,R2,R3,R4',
                   help='repeat each training file at 0..1 A that many times (integer '
                   'weights; default 1 each)')
    args = p.parse_args(argv)
    if args.workers not in (1, 2):
        p.error('--workers must be 1 or 2 (two shared cores)')
    repeat = {}
    if args.repeat:
        try:
            counts = [int(r) for r in args.repeat.split(',')]
        except ValueError:
            counts = []
        if len(counts) != len(CURRENTS) or min(counts) < 1:
            p.error(f'--repeat needs {len(CURRENTS)} integers >= 1, got {args.repeat!r}')
        repeat = dict(zip(CURRENTS, counts))
    for spec in args.models:
        name, opts = parse_model(spec)
        get_model(name, **opts)          # fail early on a bad name or option
    print(f'load before: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} '
          f'{os.getloadavg()[2]:.2f} (1/5/15 min, {os.cpu_count()} cores)')
    t0 = time.perf_counter()
    _init(args.data_dir)
    splits = list(itertools.combinations(SERIES, N_HELD_OUT))
    if args.splits:
        splits = splits[:args.splits]
    fit_kw = {'swarm_size': args.swarm_size}
    if args.maxiter is not None:
        fit_kw['maxiter'] = args.maxiter
    if args.polish:
        fit_kw['polish'] = True
    keys = list(itertools.product(SERIES, CURRENTS))
    with ProcessPoolExecutor(args.workers, initializer=_init,
                             initargs=(args.data_dir,)) as pool:
        own = dict(pool.map(_fit_file, keys, itertools.repeat(args.seed)))
        best = {k: nrmse for k, (nrmse, _) in own.items()}
        if args.in_sample:
            jobs = [(spec, cur) for spec in args.models for cur in (None,) + CURRENTS]
            fit_job = _fit_in_sample
        else:
            jobs = [(spec, held) for spec in args.models for held in splits]
            fit_job = _fit_split
        runs = list(pool.map(fit_job, *zip(*jobs), itertools.repeat(args.seed),
                             itertools.repeat(fit_kw), itertools.repeat(repeat)))
    print(f'own Kwok fits (NRMSE %, per file): median {np.median(list(best.values())):.2f}, '
          f'range {min(best.values()):.2f}-{max(best.values()):.2f}')
    if repeat:
        print('training files repeated (integer weights): '
              + ', '.join(f'{c.replace("p", ".")} A x{r}' for c, r in repeat.items()))
    if args.in_sample:
        print('IN-SAMPLE: every file is scored by the fit it was part of (no file held out)')
        print_force_levels(_DATA)
        print_own_beta(_DATA, own)
    summary = []
    groups = [(spec, [r for r in runs if r[0] == spec], 'splits') for spec in args.models]
    if args.in_sample:
        groups = [(f'{spec} {label}', [r for r in runs if r[0] == spec and pick(r[1])], what)
                  for spec in args.models
                  for label, pick, what in (('all 30', lambda c: c is None, 'fit'),
                                            ('per current', lambda c: c is not None,
                                             'per-current fits'))]
    for spec, mine, what in groups:
        med, worst, flat, raw = report(spec, mine, best, what)
        if what == 'fit':
            print('   parameters: ' + ', '.join(f'{n} {v:.4g}' for n, v in mine[0][5].items()))
        summary.append((spec, med, float(np.percentile(flat, 90)), worst,
                        float(np.median(raw)) if raw.size else np.nan,
                        float(raw.max()) if raw.size else np.nan,
                        float(np.median([r[4] for r in mine]))))
    print(f'\n{"model":30s} {"median":>7s} {"p90":>7s} {"worst":>7s} {"raw med":>8s} '
          f'{"raw worst":>9s} {"fit s":>6s}')
    for spec, med, p90, worst, rmed, rworst, fit_s in summary:
        print(f'{spec:30s} {med:7.3f} {p90:7.3f} {worst:7.3f} {rmed:8.3f} {rworst:9.3f} '
              f'{fit_s:6.2f}')
    lag = [r for r in runs if parse_model(r[0])[0] == 'kwok-current-lag']
    if args.inverse and lag:
        i_ref_a = parse_model(lag[0][0])[1].get('i_ref_a', 2.0)
        p_lag = get_model('kwok-current-lag').from_dict(lag[0][5])
        times, k = bench_inverse(_DATA, p_lag, i_ref_a)
        print(f'\nscalar inverse, {k} samples of 5mm3Hz 0.5 A, median of 3 [us/call]: '
              + ', '.join(f'{n} {us:.1f}' for n, us in times.items())
              + f' (lag / kwok-current {times["kwok-current-lag"] / times["kwok-current"]:.2f};'
              f' interpreted / compiled '
              f'{times["kwok-current interpreted"] / times["kwok-current"]:.1f})')
    print(f'\nwall {time.perf_counter() - t0:.1f} s; load after: {os.getloadavg()[0]:.2f} '
          f'{os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}')


if __name__ == '__main__':
    main()
