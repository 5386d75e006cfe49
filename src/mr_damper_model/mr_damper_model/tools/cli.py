"""
``mr-damper-identify``: identify MR damper model parameters from rig test records.

Usage::

    mr-damper-identify FILE... [--model kwok|kwok-current|kwok-current-lag|kwok-current-amp|
                                bingham|bouc-wen|spencer]
        [--per-current] [--method separable|full] [--unbounded] [--seed N] [--topic TOPIC]
        [--json] [--plot OUT.png] [--out PARAMS.json] [--compare]
    mr-damper-identify --validate PARAMS.json FILE... [--model NAME] [--topic TOPIC]
        [--json] [--plot OUT.png]
    mr-damper-identify --batch ROOT [--master PARAMS.json] [--workers N | --scheduler ADDR]
        [--serial-pattern REGEX] [--table FILE.csv] [--force] [--trend] ...  (docs/batch.md)

A FILE is a ``t,x,v,f,i`` CSV (plain or ``.csv.gz``), a rosbag2 directory, a ``.mcap`` or
``.db3`` bag (measurement JointState topic), a directory (its CSV files, bags and rosbag2
directories) or a glob. Several files are fitted as one record (each keeps its own time base;
see ``DamperData.concatenate``) and the metrics of the joint fit are printed per file too.
``--validate`` fits nothing: it prints the metrics of a saved parameter file on each file and
over all files.

Default model: ``kwok-current-amp`` when the records hold several coil-current levels (the
model that predicts held-out tests best, docs/cross-validation.md), ``kwok`` otherwise (and
with ``--per-current``). Bad input exits with code 2 and one line on stderr naming
the file and the problem. A ``.mcap`` recording cut short (its writer was killed: no footer) is
read up to its last complete chunk: the fit or validation runs on that part, a warning on stderr
says how many messages and samples were used and where the file ends, the ``--json`` output
lists it under ``truncated_inputs``, and the exit code is 3 (:data:`EXIT_TRUNCATED`; 0 when
every input was complete).
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

import numpy as np  # noqa: E402

from mr_damper_common.health import finite_or_none  # noqa: E402
from mr_damper_model.identification.identify import (compare_models,  # noqa: E402
                                                     current_group_levels, current_groups,
                                                     identify, identify_per_current)
from mr_damper_model.identification.metrics import fit_metrics, METRIC_KEYS  # noqa: E402
from mr_damper_model.io.bag_io import MEASUREMENT_TOPIC  # noqa: E402
from mr_damper_model.io.data import DamperData, DataError  # noqa: E402
from mr_damper_model.io.params_file import load_params, save_params  # noqa: E402
from mr_damper_model.io.records import expand_inputs, InputError, read_record  # noqa: E402
from mr_damper_model.models import get_model  # noqa: E402

PROG = 'mr-damper-identify'
#: Exit code of a run that used only the readable part of a truncated recording (outputs written).
EXIT_TRUNCATED = 3
MODEL_CHOICES = ('kwok', 'kwok-current', 'kwok-current-lag', 'kwok-current-amp', 'bingham',
                 'bouc-wen', 'spencer')
#: Default model for records at several coil-current levels: the best cross-validated model
#: (bench/bench_crossval.py, docs/cross-validation.md).
MULTI_CURRENT_MODEL = 'kwok-current-amp'
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
    p = _Parser(prog=PROG, description='Identify MR damper model parameters (PSO) from rig '
                'test records: CSV files with header t,x,v,f,i (s, m, m/s, N, A) or rosbag2 '
                'bags of the measurement topic; several files give one model.')
    p.add_argument('files', nargs='*', metavar='FILE',
                   help='rig test record: CSV, rosbag2 directory, .mcap or .db3 bag, a '
                   'directory of them, or a glob (quote it)')
    p.add_argument('--model', default=None,
                   help=' | '.join(MODEL_CHOICES)
                   + f' (default: {MULTI_CURRENT_MODEL} if the records have several current '
                   'levels, else kwok; '
                   'with --validate: the model the parameter file must hold)')
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
    p.add_argument('--validate', metavar='PARAMS.json',
                   help='fit nothing: metrics of this saved model on each FILE and on all')
    p.add_argument('--topic', default=None,
                   help='measurement topic of bags (default: %s if present, else the '
                   "bag's only JointState topic)" % MEASUREMENT_TOPIC)
    from mr_damper_model.tools.batch_cli import add_arguments   # lazy: it imports this module
    add_arguments(p)
    return p


def _warn_truncated(text):
    """Warning of a truncated recording: what is used of it and the exit code it gives."""
    print(f'{PROG}: warning: {text} (exit code {EXIT_TRUNCATED})', file=sys.stderr)


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
    """Metrics as JSON values (non-finite -> None, ``columnlog.finite_or_none``)."""
    return finite_or_none(m)


def _predict(model, model_options, x, data):
    """Force [N] of a model with parameter vector ``x`` on one record (from rest)."""
    mdl = get_model(model, **(model_options or {}))
    with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
        return np.asarray(mdl.force(x, data.x, data.v, i=data.i, t=data.t), dtype=float)


def _safe_metrics(f, fm):
    """fit_metrics, or NaN for every key when the model force is not finite."""
    if not np.all(np.isfinite(fm)):
        return dict.fromkeys(METRIC_KEYS, math.nan)
    return fit_metrics(f, fm)


def _per_file(model, model_options, x, parts):
    """Per-record forces and metrics, and the metrics over all records."""
    forces = [_predict(model, model_options, x, p) for p in parts]
    rows = [(p.source, p.n, _safe_metrics(p.f, fm)) for p, fm in zip(parts, forces)]
    if len(parts) == 1:             # the one record's (no copy of a large record's forces)
        return forces, rows, dict(rows[0][2])
    overall = _safe_metrics(np.concatenate([p.f for p in parts]), np.concatenate(forces))
    return forces, rows, overall


def _files_table(rows, overall=None):
    w = max([len(Path(src).name) for src, _, _ in rows] + [4]) + 2
    lines = ['file'.ljust(w) + 'samples'.rjust(9)
             + ''.join(head.rjust(18) for _, head in METRIC_UNITS)]
    extra = [('all files', sum(n for _, n, _ in rows), overall)] if overall is not None else []
    for src, n, m in [(Path(src).name, n, m) for src, n, m in rows] + extra:
        lines.append(src.ljust(w) + str(n).rjust(9)
                     + ''.join(_fmt(m[key]).rjust(18) for key, _ in METRIC_UNITS))
    return '\n'.join(lines)


def _files_json(rows):
    return [{'source': src, 'samples': n, 'metrics': _metrics_json(m)} for src, n, m in rows]


def _read_all(names, topic, truncated=None):
    """Read every record; return ``(parts, None)`` or ``(None, exit code)``."""
    parts = []
    for name in names:
        try:
            parts.append(read_record(name, topic=topic, truncated=truncated,
                                     warn=_warn_truncated))
        except DataError as exc:
            msg = str(exc)
            return None, _fail('', msg if name in msg else f'{name}: {msg}')
        except OSError as exc:
            return None, _fail(name, f'cannot read file ({exc.strerror or exc})')
    return parts, None


def _views(data, labels):
    """Return the records joined into ``data`` as views of its arrays; ``labels``: (source, n)."""
    out, a = [], 0
    for source, n in labels:
        b = a + n
        starts = data.starts[(data.starts >= a) & (data.starts < b)] - a
        out.append(DamperData(data.t[a:b], data.x[a:b], data.v[a:b], data.f[a:b], data.i[a:b],
                              source=source, starts=starts if starts.size else None))
        a = b
    return out


def _suffix_path(path, level):
    p = Path(path)
    tag = f'{level:.2f}'.replace('.', 'p')
    return p.with_name(f'{p.stem}_{tag}A{p.suffix}')


def run(argv=None):
    """Run the tool; return the exit code."""
    try:
        args = build_parser().parse_args(argv)
    except _UsageError as exc:
        return _fail('', f'{exc} (see --help)')
    if args.batch is not None:
        from mr_damper_model.tools.batch_cli import run as run_batch   # lazy: imports this
        return run_batch(args, _fail)
    if not args.files:
        return _fail('', 'the following arguments are required: FILE (see --help)')
    if args.validate is not None:
        return _run_validate(args)
    try:
        names = expand_inputs(args.files)
    except InputError as exc:
        return _fail(*exc.args)
    name = names[0] if len(names) == 1 else f'{len(names)} files'
    if args.model is not None and args.model not in MODEL_CHOICES:
        return _fail(name, f'unknown model {args.model!r}; expected one of '
                     f'{", ".join(MODEL_CHOICES)}')
    if args.method not in ('separable', 'full'):
        return _fail(name, f'unknown method {args.method!r}; expected separable or full')
    truncated = []
    parts, code = _read_all(names, args.topic, truncated)
    if code is not None:
        return code
    # several files: one record, each part on its own time base (stateful models restart)
    if len(parts) == 1:
        data = parts[0]
    else:                   # the files become views of the joined record: one copy in memory
        labels = [(p.source, p.n) for p in parts]
        data = DamperData.concatenate(parts, restamp=True, release=True)
        parts = _views(data, labels)
    levels = current_group_levels(data) or list(data.current_levels())
    model = args.model or (MULTI_CURRENT_MODEL if len(levels) > 1 and not args.per_current
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
    source = ', '.join(names)

    if args.compare:
        out = {'model': 'compare', 'models': {
            k: {'parameters': r.parameters, 'metrics': _metrics_json(r.metrics),
                'seconds': r.seconds}
            for k, r in results.items()},
            'seconds': seconds, 'seed': args.seed, 'source': source}
        res_list = list(results.values())
        labels = list(results)
    elif args.per_current:
        out = {'model': model, 'parameters': {}, 'metrics': {}, 'seconds': seconds,
               'seed': args.seed, 'source': source,
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
               'current_max_a': r.current_max_a, 'method': r.method, 'source': source}
        res_list = results
        labels = [r.model]
        file_forces, file_rows, file_all = _per_file(r.model, r.model_options, r.x, parts)
        out['files'] = _files_json(file_rows)

    if args.per_current:
        from mr_damper_model.tools.plots import model_force  # lazy: matplotlib
        groups = [part for _, part in current_groups(data)]
        f_all = np.concatenate([p.f for p in groups])
        fm_all = np.concatenate([model_force(r, p) for r, p in zip(results, groups)])
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
                save_params(args.out, dict(results[0].to_json_dict(), source=source))
        if args.plot and len(parts) > 1 and not (args.compare or args.per_current):
            _plot_files(args.plot, parts, file_forces, title=f'{results[0].model}, {name}')
        elif args.plot:
            _plot(args.plot, data, results, compare=args.compare, title=Path(name).name)
    except OSError as exc:
        return _fail(name, f'cannot write output ({exc.strerror or exc})')

    if truncated:
        out['truncated_inputs'] = truncated
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        units = get_model(res_list[0].model).param_units if not args.compare else {}
        what = f', {data.duration:.3f} s' if len(parts) == 1 else ''
        print(f'{name}: {data.n} samples{what}, current levels '
              f'{", ".join(f"{lv:.2f}" for lv in levels)} A; method {args.method}, '
              f'seed {args.seed}, {seconds:.2f} s')
        if args.compare:
            for k, r in results.items():
                u = get_model(k).param_units
                print(f'\n[{k}]')
                print(_param_table([r], [k], u))
        else:
            print(_param_table(res_list, labels, units))
            if len(parts) > 1:
                print('\nmetrics of the joint fit per file')
                print(_files_table(file_rows, file_all))
    return EXIT_TRUNCATED if truncated else 0


def _run_validate(args):
    """``--validate PARAMS.json FILE...``: metrics of a saved model, no fit."""
    for flag, used in (('--out', args.out), ('--compare', args.compare),
                       ('--per-current', args.per_current)):
        if used:
            return _fail('', f'--validate fits nothing; {flag} cannot be used with it '
                         '(see --help)')
    if args.model is not None and args.model not in MODEL_CHOICES:
        return _fail(args.validate, f'unknown model {args.model!r}; expected one of '
                     f'{", ".join(MODEL_CHOICES)}')
    try:
        pf = load_params(args.validate, model=args.model)
        x = get_model(pf.model, **(pf.model_options or {})).from_dict(pf.parameters)
    except (DataError, ValueError) as exc:     # load_params names the file
        msg = str(exc)
        return _fail('', msg if args.validate in msg else f'{args.validate}: {msg}')
    try:
        names = expand_inputs(args.files)
    except InputError as exc:
        return _fail(*exc.args)
    truncated = []
    parts, code = _read_all(names, args.topic, truncated)
    if code is not None:
        return code
    forces, rows, overall = _per_file(pf.model, pf.model_options, x, parts)
    if args.plot:
        try:
            _plot_files(args.plot, parts, forces,
                        title=f'{pf.model} from {Path(args.validate).name}')
        except OSError as exc:
            return _fail(args.plot, f'cannot write output ({exc.strerror or exc})')
    if args.json:
        doc = {'model': pf.model, 'params_file': args.validate, 'files': _files_json(rows),
               'metrics': _metrics_json(overall)}
        if truncated:
            doc['truncated_inputs'] = truncated
        print(json.dumps(doc, indent=2))
    else:
        lo, hi = pf.current_min_a, pf.current_max_a
        fitted = f', fitted on {lo:.2f}-{hi:.2f} A' if np.isfinite([lo, hi]).all() else ''
        print(f'{args.validate}: model {pf.model}{fitted}; {len(parts)} file(s), '
              f'{sum(p.n for p in parts)} samples')
        print(_files_table(rows, overall))
    return EXIT_TRUNCATED if truncated else 0


def _plot_files(path, parts, forces, *, title):
    """One row per record: measured and model force vs time, displacement, velocity, error."""
    from mr_damper_model.tools.plots import fit_figure, save_figure  # lazy: matplotlib
    fig = fit_figure([(Path(p.source).name, p.t, p.x, p.v, p.f, fm)
                      for p, fm in zip(parts, forces)], title=title)
    save_figure(fig, path)


def _plot(path, data, results, *, compare, title):
    from mr_damper_model.tools.plots import (compare_figure, fit_figure,  # lazy: matplotlib
                                             model_force, save_figure)
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
        sys.stdout.flush()      # a block-buffered pipe is written here, inside the try
    except KeyboardInterrupt:
        code = _fail('', 'interrupted', 130)
    except BrokenPipeError:     # the reader went away (e.g. `| head`): stop quietly, as cat does
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        code = 141
    except Exception as exc:  # never a traceback for the user; say what failed
        code = _fail('', f'internal error: {type(exc).__name__}: {exc}', 1)
    sys.exit(code)


if __name__ == '__main__':
    main()
