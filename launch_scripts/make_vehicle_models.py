"""
Regenerate the vehicle configuration's four damper models with ``mr-damper-identify --batch``.

The files are ``src/semi_active_control/config/models/<corner>.json``, made from the
repository's data.

Usage: ``.venv/bin/python launch_scripts/make_vehicle_models.py [--out DIR]``

The repository holds one real MR damper's tests (``data/quiroz_mr_damper``, six sine tests at
0-1 A). Each corner's "end-of-line test" is two of those tests at all five currents, a
different pair per corner, so the four records (and their kwok-current fits) differ as four
dampers of one type do: fl 10 mm 1 Hz + 2 mm 5 Hz, fr 25 mm 0.5 Hz + 5 mm 3 Hz, rl 25 mm
0.25 Hz + 10 mm 1 Hz, rr 25 mm 0.1 Hz + 5 mm 3 Hz. The archive (one folder per corner, links
to the data files) is built in a temporary folder; the batch fits kwok-current serially
(``--workers 0``, seed 1) and writes each damper's parameter file (``--params-dir``), named by
the corner.
"""
import argparse
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / 'data' / 'quiroz_mr_damper'
OUT = REPO / 'src' / 'semi_active_control' / 'config' / 'models'
#: The tests of each corner's record (file name stems before the current).
RECORDS = {'fl': ('quiroz_sine_10mm1Hz_*_preproc', 'quiroz_sine_2mm5Hz_*A'),
           'fr': ('quiroz_sine_25mm0x5Hz_*A', 'quiroz_sine_5mm3Hz_*A'),
           'rl': ('quiroz_sine_25mm0x25Hz_*A', 'quiroz_sine_10mm1Hz_*_preproc'),
           'rr': ('quiroz_sine_25mm0x1Hz_*_preproc', 'quiroz_sine_5mm3Hz_*A')}


def main(argv=None):
    """Build the archive, run the batch, return its exit status."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--out', default=str(OUT), help=f'output folder (default {OUT})')
    args = p.parse_args(argv)
    tool = Path(sys.executable).with_name('mr-damper-identify')
    with tempfile.TemporaryDirectory() as tmp:
        archive = Path(tmp) / 'eol'
        for corner, patterns in RECORDS.items():
            folder = archive / corner
            folder.mkdir(parents=True)
            for pattern in patterns:
                files = sorted(DATA.glob(pattern + '.csv.gz'))
                if len(files) != 5:
                    print(f'{pattern}: expected 5 files (0..1 A), found {len(files)}',
                          file=sys.stderr)
                    return 1
                for f in files:
                    os.symlink(f, folder / f.name)
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        cmd = [str(tool), '--batch', str(archive), '--model', 'kwok-current', '--workers', '0',
               '--seed', '1', '--table', str(Path(tmp) / 'eol.csv'), '--params-dir', str(out)]
        print(' '.join(cmd), flush=True)
        rc = subprocess.call(cmd)
        shutil.rmtree(archive, ignore_errors=True)
    return rc


if __name__ == '__main__':
    sys.exit(main())
