"""
``mr-damper-identify``: identify MR damper model parameters from a rig test CSV.

Usage::

    mr-damper-identify FILE.csv [--model kwok|kwok-current|bingham|bouc-wen|spencer]
        [--per-current] [--method separable|full] [--unbounded] [--seed N]
        [--json] [--plot OUT.png] [--out PARAMS.json] [--compare]

Default model: ``kwok-current`` when the file holds several coil-current levels, ``kwok``
otherwise (and with ``--per-current``). Bad input exits with code 2 and one line on stderr naming
the file and the problem.
"""
import os

# The swarm multiplies many small matrices; on a shared 2-core machine multi-threaded BLAS makes
# them several times slower. Set before numpy is imported (a user's own setting wins).
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
from pathlib import Path  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

PROG = 'mr-damper-identify'
MODEL_CHOICES = ('kwok', 'kwok-current', 'bingham', 'bouc-wen', 'spencer')
METRIC_UNITS = (('rmse_n', 'RMSE [N]'), ('nrmse_percent', 'NRMSE [%]'),
                ('mean_abs_error_n', 'mean |error| [N]'),
                ('mean_percent_error', 'mean % error'), ('max_percent_error', 'max % error'))


class _UsageError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise _UsageError(message)


def build_parser():
    """Return the argument parser."""
    p = _Parser(prog=PROG, description='Identify MR damper model parameters (PSO) from a '
                'CSV with header t,x,v,f,i (s, m, m/s, N, A).')
    p.add_argument('file', metavar='FILE.csv', help='rig test record')
    p.add_argument('--model', default=None,
                   help='kwok | kwok-current | bingham | bouc-wen | spencer (default: '
                   'kwok-current if the file has several current levels, else kwok)')
    p.add_argument('--per-current', action='store_true',
                   help='one fit per current level (thesis Table 4.3 layout)')
    p.add_argument('--method', default='separable',
                   help='separable (default: PSO on nonlinear parameters, bounded least '
                   'squares for the linear ones) or full (PSO on all, as in the thesis)')
    p.add_argument('--unbounded', action='store_true',
                   help='wide thesis-comparison bounds (c, k, alpha, f0 of either sign)')
    p.add_argument('--seed', type=int, default=1, help='swarm seed (default 1)')
    p.add_argument('--json', action='store_true', help='one JSON object on stdout')
    p.add_argument('--plot', metavar='OUT.png', help='thesis Figure 4.16 layout plot')
    p.add_argument('--out', metavar='PARAMS.json', help='write the parameter file')
    p.add_argument('--compare', action='store_true',
                   help='Bingham, Bouc-Wen and Kwok side by side (thesis Table 4.1)')
    return p


def _fail(name, message, code=2):
    text = ' '.join(str(message).split())
    print(f'{PROG}: {name}: {text}' if name else f'{PROG}: {text}', file=sys.stderr)
    return code


class _Progress:
    """Progress line on stderr once a fit runs longer than ``after_s``."""

    def __init__(self, label, after_s=2.0, every_s=1.0):
        self.label = label
        self.after_s = after_s
        self.every_s = every_s
        self.t0 = time.perf_counter()
        self.last = -math.inf

    def __call__(self, res):
        now = time.perf_counter() - self.t0
        if now >= self.after_s and now - self.last >= self.every_s:
            self.last = now
            print(f'{PROG}: {self.label}: iteration {res.nit}, best RMSE {res.fun:.4g} N, '
                  f'{now:.1f} s', file=sys.stderr, flush=True)
        return False


def _fmt(v):
    return f'{v:.6g}' if isinstance(v, float) else str(v)


def _param_table(results, labels, units):
    names = list(results[0].parameters)
    w = max([len(n) + len(units.get(n, '-')) + 4 for n in names]
            + [len(h) + 1 for _, h in METRIC_UNITS])
    lines = ['parameter'.ljust(w) + ''.join(lb.rjust(14) for lb in labels)]
    for n in names:
        head = f'{n} [{units.get(n, "-")}]'
        lines.append(head.ljust(w) + ''.join(_fmt(r.parameters[n]).rjust(14) for r in results))
    for key, head in METRIC_UNITS:
        lines.append(head.ljust(w) + ''.join(_fmt(r.metrics[key]).rjust(14) for r in results))
    lines.append('time [s]'.ljust(w) + ''.join(f'{r.seconds:.3f}'.rjust(14) for r in results))
    return '\n'.join(lines)


def _metrics_json(m):
    return {k: (None if not math.isfinite(v) else float(v)) for k, v in m.items()}


def _suffix_path(path, level):
    p = Path(path)
    tag = f'{level:.2f}'.replace('.', 'p')
    return p.with_name(f'{p.stem}_{tag}A{p.suffix}')


def run(argv=None):
    """Run the tool; return the exit code."""
    from .data import DataError, read_csv, validate
    from .identify import compare_models, current_groups, identify, identify_per_current
    from .models import get_model
    from .params_file import save_params

    try:
        args = build_parser().parse_args(argv)
    except _UsageError as exc:
        return _fail('', f'{exc} (see --help)')
    name = args.file
    if args.model is not None and args.model not in MODEL_CHOICES:
        return _fail(name, f'unknown model {args.model!r}; expected one of '
                     f'{", ".join(MODEL_CHOICES)}')
    if args.method not in ('separable', 'full'):
        return _fail(name, f'unknown method {args.method!r}; expected separable or full')
    try:
        data = validate(read_csv(name), name=name)
    except DataError as exc:
        msg = str(exc)
        return _fail('', msg if name in msg else f'{name}: {msg}')
    except OSError as exc:
        return _fail(name, f'cannot read file ({exc.strerror or exc})')
    levels = [lv for lv, _ in current_groups(data)] or list(data.current_levels())
    model = args.model or ('kwok-current' if len(levels) > 1 and not args.per_current
                           else 'kwok')
    kw = dict(method=args.method, unbounded=args.unbounded, seed=args.seed)
    t0 = time.perf_counter()
    try:
        if args.compare:
            results = compare_models(data, callback=_Progress(f'{name} compare'), **kw)
        elif args.per_current:
            results = identify_per_current(data, model,
                                           callback=_Progress(f'{name} {model}'), **kw)
        else:
            results = [identify(data, model, callback=_Progress(f'{name} {model}'), **kw)]
    except DataError as exc:
        return _fail(name, exc)
    except ValueError as exc:
        return _fail(name, exc)
    seconds = time.perf_counter() - t0

    if args.compare:
        out = {'model': 'compare', 'models': {
            k: {'parameters': r.parameters, 'metrics': _metrics_json(r.metrics),
                'seconds': r.seconds}
            for k, r in results.items()},
            'seconds': seconds, 'seed': args.seed, 'source': name}
        res_list = list(results.values())
        labels = list(results)
    elif args.per_current:
        out = {'model': model, 'parameters': {}, 'metrics': {}, 'seconds': seconds,
               'seed': args.seed, 'source': name,
               'groups': [{'current_a': r.current_a, 'parameters': r.parameters,
                           'metrics': _metrics_json(r.metrics)} for r in results]}
        # top-level metrics: over all groups (each sample with its own group's fit)
        res_list = results
        labels = [f'{r.current_a:.2f} A' for r in results]
    else:
        r = results[0]
        out = {'model': r.model, 'parameters': r.parameters,
               'metrics': _metrics_json(r.metrics), 'seconds': seconds, 'seed': args.seed,
               'model_options': r.model_options, 'current_min_a': r.current_min_a,
               'current_max_a': r.current_max_a, 'method': r.method, 'source': name}
        res_list = results
        labels = [r.model]

    if args.per_current:
        import numpy as np
        from .metrics import fit_metrics
        from .plots import model_force
        parts = [part for _, part in current_groups(data)]
        f_all = np.concatenate([p.f for p in parts])
        fm_all = np.concatenate([model_force(r, p) for r, p in zip(results, parts)])
        out['metrics'] = _metrics_json(fit_metrics(f_all, fm_all))
        out['parameters'] = {}

    try:
        if args.out:
            if args.compare:
                for k, r in results.items():
                    save_params(Path(args.out).with_name(
                        f'{Path(args.out).stem}_{k}{Path(args.out).suffix}'), r)
            elif args.per_current:
                for r in results:
                    save_params(_suffix_path(args.out, r.current_a), r)
            else:
                save_params(args.out, results[0])
        if args.plot:
            _plot(args.plot, data, results, compare=args.compare, title=Path(name).name)
    except OSError as exc:
        return _fail(name, f'cannot write output ({exc.strerror or exc})')

    if args.json:
        print(json.dumps(out, indent=2))
    else:
        units = get_model(res_list[0].model).param_units if not args.compare else {}
        print(f'{name}: {data.n} samples, {data.duration:.3f} s, current levels '
              f'{", ".join(f"{lv:.2f}" for lv in levels)} A; method {args.method}, '
              f'seed {args.seed}, {seconds:.2f} s')
        if args.compare:
            for k, r in results.items():
                u = get_model(k).param_units
                print(f'\n[{k}]')
                print(_param_table([r], [k], u))
        else:
            print(_param_table(res_list, labels, units))
    return 0


def _plot(path, data, results, *, compare, title):
    from .identify import current_groups
    from .plots import compare_figure, fit_figure, model_force, save_figure
    if compare:
        forces = {k: model_force(r, data) for k, r in results.items()}
        fig = compare_figure(data.t, data.f, forces, title=title)
    elif len(results) > 1 or len(current_groups(data)) > 1:
        groups = []
        parts = [part for _, part in current_groups(data)]
        if len(results) > 1:
            pairs = zip(results, parts)
        else:
            pairs = [(results[0], part) for part in parts]
        for r, part in pairs:
            lvl = float(part.i.mean())
            groups.append((f'{lvl:.2f} A', part.t, part.x, part.v, part.f,
                           model_force(r, part)))
        fig = fit_figure(groups, title=title)
    else:
        r = results[0]
        fig = fit_figure([(f'{r.model}', data.t, data.x, data.v, data.f,
                           model_force(r, data))], title=title)
    save_figure(fig, path)


def main(argv=None):
    """Console-script entry point."""
    try:
        code = run(argv)
    except KeyboardInterrupt:
        code = _fail('', 'interrupted', 130)
    except Exception as exc:  # never a traceback for the user; say what failed
        code = _fail('', f'internal error: {type(exc).__name__}: {exc}', 1)
    sys.exit(code)


if __name__ == '__main__':
    main()
