"""
The ``--batch`` options of ``mr-damper-identify``: argument definitions and the run.

The work is done by :mod:`mr_damper_model.identification.batch`; this module turns the parsed
arguments into its settings and prints the outcome (docs/batch.md).
"""
import json
import math
import os
from pathlib import Path
import sys

from mr_damper_model.identification import batch
from mr_damper_model.identification.batch import (DEFAULT_ABS_TOL_N, DEFAULT_CURRENTS_A,
                                                  DEFAULT_MAX_NRMSE_PERCENT, DEFAULT_REL_TOL,
                                                  DEFAULT_STROKE_M, DEFAULT_VELOCITIES_MPS)
from mr_damper_model.io.data import DataError
from mr_damper_model.tools.cli import MODEL_CHOICES

#: Options of the single-record tool that mean nothing in a batch.
_NOT_IN_BATCH = (('--per-current', 'per_current'), ('--compare', 'compare'),
                 ('--validate', 'validate'), ('--plot', 'plot'), ('--out', 'out'))


def add_arguments(p):
    """Add the batch options to the ``mr-damper-identify`` parser."""
    g = p.add_argument_group('batch: one model per damper of an archive (docs/batch.md)')
    g.add_argument('--batch', metavar='ROOT',
                   help='identify every damper under ROOT: one per sub-directory (its records '
                   'fitted together), or one per file with --serial-pattern')
    g.add_argument('--serial-pattern', metavar='REGEX',
                   help='one damper test per record file under ROOT (recursive) whose '
                   'relative path matches; group "serial" (or the first group, or the '
                   'match) is the serial number, optional group "date" the test time')
    g.add_argument('--folder-pattern', metavar='REGEX',
                   help='one damper per sub-directory, its name matched as with '
                   '--serial-pattern')
    g.add_argument('--master', metavar='PARAMS.json',
                   help='master model (parameter file); each damper passes if its force '
                   'envelope is within tolerance of the master\'s')
    g.add_argument('--velocities', metavar='V,...', type=_floats,
                   default=DEFAULT_VELOCITIES_MPS,
                   help='envelope: peak piston velocities [m/s] (default '
                   f'{",".join(map(str, DEFAULT_VELOCITIES_MPS))})')
    g.add_argument('--currents', metavar='I,...', type=_floats, default=None,
                   help='envelope: coil currents [A] (default: min, middle and max of the '
                   "master's current range, else "
                   f'{",".join(map(str, DEFAULT_CURRENTS_A))})')
    g.add_argument('--stroke', metavar='M', type=float, default=DEFAULT_STROKE_M,
                   help=f'envelope: amplitude of the reference sine [m] (default '
                   f'{DEFAULT_STROKE_M})')
    g.add_argument('--rel-tol', type=float, default=DEFAULT_REL_TOL,
                   help='envelope tolerance, relative to the master force (default '
                   f'{DEFAULT_REL_TOL})')
    g.add_argument('--abs-tol', metavar='N', type=float, default=DEFAULT_ABS_TOL_N,
                   help=f'envelope tolerance, at least this many newtons (default '
                   f'{DEFAULT_ABS_TOL_N})')
    g.add_argument('--max-nrmse', metavar='PERCENT', type=float,
                   default=DEFAULT_MAX_NRMSE_PERCENT,
                   help=f'a damper whose fit NRMSE exceeds this fails (default '
                   f'{DEFAULT_MAX_NRMSE_PERCENT})')
    g.add_argument('--param-range', metavar='NAME=LO:HI', action='append', default=[],
                   type=_param_range, help='a parameter range a passing damper must meet '
                   '(repeatable)')
    g.add_argument('--workers', metavar='N', type=int, default=None,
                   help='local Dask worker processes, one thread each, on 127.0.0.1 '
                   '(default: CPU count; 0: serially in this process)')
    g.add_argument('--scheduler', metavar='ADDRESS',
                   help='run on an existing Dask scheduler (e.g. tcp://127.0.0.1:8786) '
                   'instead of a local cluster')
    g.add_argument('--force', action='store_true',
                   help='redo the dampers already in the table')
    g.add_argument('--table', metavar='FILE.csv', default='batch.csv',
                   help='result table (default batch.csv); the JSON summary goes next to it '
                   '(FILE.json)')
    g.add_argument('--params-dir', metavar='DIR',
                   help='also write each damper\'s end-of-line record as a parameter file, '
                   'DIR/<serial>.json (the format of --out; a failed damper\'s is marked '
                   'invalid), e.g. for a vehicle controller\'s model_files')
    g.add_argument('--trend', action='store_true',
                   help='also write FILE_trend.csv and FILE_trend.png: each parameter and '
                   'envelope force against test time per serial number')


def _floats(text):
    import argparse
    try:
        vals = tuple(float(v) for v in text.split(',') if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a comma-separated list of '
                                         'numbers') from None
    if not vals or not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f'{text!r} is not a list of finite numbers')
    return vals


def _param_range(text):
    import argparse
    try:
        name, rng = text.split('=', 1)
        lo, hi = rng.split(':', 1)
        lo = float(lo) if lo.strip() else -math.inf
        hi = float(hi) if hi.strip() else math.inf
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not NAME=LO:HI') from None
    if not name.strip() or lo > hi:
        raise argparse.ArgumentTypeError(f'{text!r} is not NAME=LO:HI with LO <= HI')
    return name.strip(), lo, hi


def run(args, fail):
    """
    Run ``--batch``; return the exit code.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``mr-damper-identify`` arguments.
    fail : callable
        ``fail(name, message)`` prints the error line and returns the exit code.

    """
    for flag, attr in _NOT_IN_BATCH:
        if getattr(args, attr, None):
            return fail('', f'{flag} cannot be used with --batch (see --help)')
    if args.files:
        return fail('', '--batch takes its records from ROOT; no FILE arguments (see --help)')
    if args.serial_pattern and args.folder_pattern:
        return fail('', '--serial-pattern (one damper per file) and --folder-pattern (one per '
                    'directory) exclude each other')
    if args.workers is not None and args.workers < 0:
        return fail('', '--workers must be >= 0')
    if args.scheduler and args.workers is not None:
        return fail('', '--workers and --scheduler exclude each other')
    if args.method not in ('separable', 'full'):
        return fail('', f'unknown method {args.method!r}; expected separable or full')
    if args.model is not None and args.model not in MODEL_CHOICES:
        return fail('', f'unknown model {args.model!r}; expected one of '
                    f'{", ".join(MODEL_CHOICES)}')
    root = Path(args.batch)
    if not root.is_dir():
        return fail(args.batch, 'not a directory')
    master = None
    if args.master:
        try:
            master = batch.load_master(args.master)
        except DataError as exc:
            return fail('', exc)
    currents = args.currents or (batch.master_currents(master) if master
                                 else batch.DEFAULT_CURRENTS_A)
    try:
        settings = batch.BatchSettings(
            model=args.model, method=args.method, unbounded=args.unbounded, topic=args.topic,
            seed=args.seed, master=master, velocities_mps=args.velocities,
            currents_a=currents, stroke_m=args.stroke, rel_tol=args.rel_tol,
            abs_tol_n=args.abs_tol, max_nrmse_percent=args.max_nrmse,
            param_ranges=tuple(args.param_range))
    except ValueError as exc:
        return fail('', exc)
    workers = (os.cpu_count() or 1) if args.workers is None else args.workers
    table = Path(args.table)
    try:
        out = batch.run_batch(root, settings, table=table,
                              per_file=bool(args.serial_pattern),
                              pattern=args.serial_pattern or args.folder_pattern,
                              workers=workers, scheduler=args.scheduler, force=args.force)
        trend_rows = None
        if args.params_dir:
            out['params_files'] = batch.write_params_files(batch.read_table(table),
                                                           args.params_dir, master)
        if args.trend:
            rows = batch.read_table(table)
            trend_rows = batch.write_trend(
                rows, table.with_name(f'{table.stem}_trend.csv'),
                table.with_name(f'{table.stem}_trend.png'))
    except ValueError as exc:          # the message names the directory or the scheduler
        return fail('', exc)
    except OSError as exc:
        return fail(args.table, f'cannot write output ({exc.strerror or exc})')
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    c = out['counts']
    what = ', '.join(f'{c[k]} {k}' for k in ('pass', 'fail', 'error', 'fitted') if c[k])
    rate = out['dampers_per_s']
    print(f'{args.batch}: {out["dampers"]} damper(s) in the table ({what or "none"}); '
          f'{out["processed"]} identified, {out["skipped"]} already done'
          + (f', {rate:.2f} dampers/s' if rate else '') + f'; table {table}, summary '
          f'{table.with_suffix(".json")}')
    if out['ignored']:
        print(f'ignored (not a damper / no pattern match): {len(out["ignored"])}: '
              + ', '.join(out['ignored'][:5]) + (' ...' if len(out['ignored']) > 5 else ''))
    for e in out['errors'][:10]:
        print(f'error {e["record"]}: {e["error"]}')
    for f in out['failed'][:10]:
        print(f'fail  {f["record"]}: {f["reason"]}')
    if out.get('params_files'):
        print(f'parameter files: {len(out["params_files"])} in {args.params_dir}')
    if trend_rows is not None:
        print(f'trend: {len({r["serial"] for r in trend_rows})} serial(s) with dated records; '
              f'{table.stem}_trend.csv / .png')
    sys.stdout.flush()
    return 0
