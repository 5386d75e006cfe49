"""
Peak memory of reading and of fitting a large DAQ CSV, before and after, in the same run.

Generates a CSV of ``--rows`` samples (thesis cam, 1 kHz, the kwok-current truth at 0.5 A with
2 N noise: ``mr-damper-identify``'s default fit is then Kwok) in a temporary folder and, each
in a fresh process, reads it (``read_record``: read + validate) and reads and fits it (the
whole ``mr-damper-identify FILE`` run), once with the package as it is in ``--before`` (a git
revision, default :data:`BEFORE`, the last commit before the issue-21 memory work: its
``src/mr_damper_model`` extracted with ``git archive``) and once with this tree. Prints the
peak resident set size (``ru_maxrss``: what the issue's "833 MB RSS" measured; it includes
the interpreter and its imports, printed as the baseline) as a ratio to the CSV size, the peak
above the baseline as a ratio to the final arrays (5 columns x 8 bytes x rows), how much the
fit results differ, and the fit's wall time (``seconds``: noisy on a loaded machine).

With ``--multi``: five files of ``--rows / 5`` samples, one per coil current 0, 0.25, 0.5,
0.75 and 1 A, fitted jointly (``mr-damper-identify FILE...``: the multi-current default,
kwok-current-amp, a stateful model), before = :data:`BEFORE_MULTI` (main before the chunked
polish of the stateful current models).

With ``--read-methods``: also the previous comparison of the reader against a list of the
file's rows (tracemalloc, Python objects and numpy arrays; the list takes about 8x the file).

    .venv/bin/python bench/bench_csv_memory.py [--rows 3000000] [--before REV] [--multi]
"""
import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile

import numpy as np

REPO = Path(__file__).resolve().parents[1]

#: The "before" of the comparison: main before the chunked fit and reader of issue 21.
BEFORE = '91a9a718356aa93d5ec2d80cc492daaa2e2af9ae'
#: The "before" of ``--multi``: main before the chunked fit of the stateful multi-current models.
BEFORE_MULTI = '6cbd700bf56a885d9e4b4d6f5fd46e8f1e5d5ea6'
#: Coil currents [A] of the ``--multi`` records (one file each).
MULTI_CURRENTS = (0.0, 0.25, 0.5, 0.75, 1.0)

CHILD = r'''
import json, resource, sys
def rss_mb():
    for line in open('/proc/self/status'):
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
path, what = sys.argv[1], sys.argv[2]
import numpy, scipy.optimize, scipy.signal   # the imports of the fit, in the baseline
try:
    from mr_damper_model.tools import cli
except ImportError:                 # the layout before the split into sub-packages
    from mr_damper_model import cli
paths = path.split(',')             # several files: one joint (multi-current) fit
out = {'baseline_mb': rss_mb(), 'package': cli.__file__}
if what == 'read':
    out['n'] = sum(cli.read_record(p).n for p in paths)
else:
    import contextlib, io
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = cli.run(paths + ['--json'])
    res = json.loads(buf.getvalue())
    out.update(code=code, parameters=res['parameters'], rmse_n=res['metrics']['rmse_n'],
               model=res['model'], fit_s=res['seconds'])
out['peak_mb'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
'''

CHILD_METHODS = r'''
import csv, json, sys, tracemalloc
import numpy as np
from mr_damper_model.io.data import read_csv
path, method = sys.argv[1], sys.argv[2]
tracemalloc.start()
if method == 'read_csv':
    n = read_csv(path).n
else:
    with open(path, newline='') as fh:
        rows = list(csv.reader(fh))
    values = np.array([[float(c) for c in r] for r in rows[1:]])
    n = len(values)
peak = tracemalloc.get_traced_memory()[1]
print(json.dumps({'n': n, 'peak_kb': peak / 1e3}))
'''


def write_record(path, rows, seed=0, current=0.5):
    """Write a cam record through the kwok-current truth at ``current`` [A] (2 N noise)."""
    from mr_damper_model.identification.presets import thesis_kwok_current
    model, truth = thesis_kwok_current()
    t = np.arange(rows) * 1e-3
    w = 2 * np.pi * 1.1
    x = 0.03 * np.sin(w * t)
    v = 0.03 * w * np.cos(w * t)
    i = np.full(rows, current)
    p = np.array([truth[k] for k in model.param_names])
    f = model.force(p, x, v, i=i) + 2.0 * np.random.default_rng(seed).standard_normal(rows)
    np.savetxt(path, np.column_stack([t, x, v, f, i]), delimiter=',', header='t,x,v,f,i',
               comments='', fmt='%.10g')


def extract(rev, dest):
    """Extract ``src/mr_damper_model`` of git revision ``rev`` into ``dest``; return its path."""
    archive = subprocess.run(['git', '-C', str(REPO), 'archive', rev, 'src/mr_damper_model'],
                             capture_output=True, check=True).stdout
    Path(dest).mkdir(parents=True, exist_ok=True)
    subprocess.run(['tar', '-x', '-C', str(dest)], input=archive, check=True)
    return Path(dest) / 'src' / 'mr_damper_model'


def run_child(code, args, pythonpath=None):
    env = dict(os.environ)
    if pythonpath is not None:
        env['PYTHONPATH'] = str(pythonpath) + os.pathsep + env.get('PYTHONPATH', '')
    out = subprocess.run([sys.executable, '-c', code, *map(str, args)], capture_output=True,
                         text=True, env=env)
    if out.returncode != 0:
        raise SystemExit(f'child failed ({args}):\n{out.stderr[-2000:]}')
    return json.loads(out.stdout.strip().splitlines()[-1])


def write_records(tmp, rows, multi):
    """Write the record(s); return the comma-joined paths and their total size [MB]."""
    if not multi:
        paths = [Path(tmp) / 'large.csv']
        write_record(paths[0], rows)
    else:
        paths = [Path(tmp) / f'large_{c:.2f}A.csv' for c in MULTI_CURRENTS]
        for k, (path, current) in enumerate(zip(paths, MULTI_CURRENTS)):
            write_record(path, rows // len(paths), seed=k, current=current)
    return ','.join(map(str, paths)), sum(p.stat().st_size for p in paths) / 1e6


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--rows', type=int, default=3_000_000,
                    help='samples (3,000,000: a CSV of about 160 MB, the issue-21 file size)')
    ap.add_argument('--before', default=None,
                    help='git revision of the "before" package (default: before issue 21, '
                         'with --multi before the chunked multi-current fit)')
    ap.add_argument('--multi', action='store_true',
                    help='several files, one per current (0 to 1 A), --rows in all: the joint '
                         'multi-current fit (kwok-current-amp) instead of the Kwok fit')
    ap.add_argument('--read-methods', action='store_true',
                    help='also compare read_csv with a list of rows (tracemalloc)')
    args = ap.parse_args()
    before = args.before or (BEFORE_MULTI if args.multi else BEFORE)
    print(f'load average {os.getloadavg()[0]:.1f} (2 cores shared)')
    with tempfile.TemporaryDirectory() as tmp:
        path, size_mb = write_records(tmp, args.rows, args.multi)
        final_mb = 5 * 8 * args.rows / 1e6
        print(f'CSV {size_mb:.0f} MB in {path.count(",") + 1} file(s), {args.rows} rows, final '
              f'arrays {final_mb:.0f} MB; before = {before[:12]}, after = this tree')
        before_src = extract(before, Path(tmp) / 'before')
        results = {}
        print(f'{"":22s}{"peak RSS":>10s}{"/ CSV":>8s}{"baseline":>10s}'
              f'{"(peak-base)/arrays":>20s}')
        for what in ('read', 'read+fit'):
            for label, pp in (('before', before_src), ('after', None)):
                r = run_child(CHILD, [path, 'read' if what == 'read' else 'fit'], pp)
                if pp is not None and not r['package'].startswith(str(before_src)):
                    raise SystemExit(f'the before child imported {r["package"]}')
                results[what, label] = r
                print(f'{what + " " + label:22s}{r["peak_mb"]:8.0f}MB'
                      f'{r["peak_mb"] / size_mb:7.2f}x{r["baseline_mb"]:8.0f}MB'
                      f'{(r["peak_mb"] - r["baseline_mb"]) / final_mb:19.2f}x')
        b, a = results['read+fit', 'before'], results['read+fit', 'after']
        pb, pa = b['parameters'], a['parameters']
        # relative to the value, or to 1e-3 of the bounds' span for a value near 0 (a lag of
        # a record without one: 1e-6 s against 0 is no difference of the fit)
        from mr_damper_model.models import get_model
        mdl = get_model(a['model'])
        span = dict(zip(mdl.param_names, np.subtract(*mdl.default_bounds()[::-1])))
        rel, worst = max((abs(pa[k] - pb[k]) / max(abs(pb[k]), 1e-3 * span[k], 1e-300), k)
                         for k in pb)
        print(f'fit ({a["model"]}): before {b["fit_s"]:.2f} s, after {a["fit_s"]:.2f} s; '
              f'largest relative parameter difference {rel:.1e} ({worst}: {pb[worst]:.4g} -> '
              f'{pa[worst]:.4g}), RMSE {b["rmse_n"]:.6f} -> {a["rmse_n"]:.6f} N')
        if args.read_methods and not args.multi:
            methods = {}
            for method in ('read_csv', 'list_of_rows'):
                r = run_child(CHILD_METHODS, [path, method])
                methods[method] = r['peak_kb'] / 1e3
                print(f'{method:14s} peak +{methods[method]:7.0f} MB = '
                      f'{methods[method] / final_mb:4.1f}x the arrays (tracemalloc)')
            print(f'ratio list_of_rows / read_csv: '
                  f'{methods["list_of_rows"] / methods["read_csv"]:.1f}x')


if __name__ == '__main__':
    main()
