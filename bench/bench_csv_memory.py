"""
Peak memory of reading a large DAQ CSV: ``read_csv`` (block parser) vs a list of rows.

The alternative is the previous reader's approach (``list(csv.reader(fh))`` then one float
array). Generates a CSV of ``--rows`` samples in a temporary folder, reads it with each method
in a fresh process and prints the peak of the memory it allocates (tracemalloc: Python objects
and numpy arrays) and its ratio to the final arrays (5 columns x 8 bytes x rows).

    .venv/bin/python bench/bench_csv_memory.py [--rows 1000000]
"""
import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

CHILD = r'''
import csv, json, sys, tracemalloc
import numpy as np
from mr_damper_model.data import read_csv
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--rows', type=int, default=1_000_000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / 'large.csv'
        t = np.arange(args.rows) * 1e-3
        arr = np.column_stack([t, 0.01 * np.sin(t), 0.01 * np.cos(t), 500 * np.sin(t),
                               0.5 + 0 * t])
        np.savetxt(path, arr, delimiter=',', header='t,x,v,f,i', comments='', fmt='%.10g')
        size_mb = path.stat().st_size / 1e6
        final_mb = 5 * 8 * args.rows / 1e6
        print(f'CSV {size_mb:.0f} MB, {args.rows} rows, final arrays {final_mb:.0f} MB')
        results = {}
        for method in ('read_csv', 'list_of_rows'):
            out = subprocess.run([sys.executable, '-c', CHILD, str(path), method],
                                 capture_output=True, text=True, check=True)
            r = json.loads(out.stdout)
            results[method] = r['peak_kb'] / 1e3
            print(f'{method:14s} peak +{results[method]:7.0f} MB = '
                  f'{results[method] / final_mb:4.1f}x the arrays')
        print(f'ratio list_of_rows / read_csv: '
              f'{results["list_of_rows"] / results["read_csv"]:.1f}x')


if __name__ == '__main__':
    main()
