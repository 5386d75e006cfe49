"""
``mr-damper-rig-test``: write a simulated thesis-like rig test as a ``t,x,v,f,i`` CSV.

Usage::

    mr-damper-rig-test --out FILE.csv [--duration S] [--plant spencer|kwok-current] [--seed N]
        [--excitation cam|multisine|chirp|random] [--currents 0,0.5,1,1.5,2]
        [--hold S] [--truth-out TRUE.json]

Default: Spencer plant scaled to the thesis damper, cam 1.1 Hz / 30 mm, current steps 0, 0.5, 1,
1.5, 2 A held 4 cam periods each (18.2 s), 1 kHz, load-cell noise 2 N, 16-bit DAQ.
Bad arguments: exit code 2 and one line on stderr.
"""
import argparse
import json
import math
import sys

from mr_damper_model.io.data import write_csv
from mr_damper_model.models.plant import make_plant, PLANT_NAMES
from mr_damper_rig.excitation import EXCITATION_NAMES, make_excitation, StepSchedule
from mr_damper_rig.virtual_rig import VirtualRig


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        sys.stderr.write(f'{self.prog}: error: {message}\n')
        sys.exit(2)


def _parser():
    p = _Parser(prog='mr-damper-rig-test',
                description='Simulate an MR damper rig test and write a t,x,v,f,i CSV.')
    p.add_argument('--out', required=True, help='output CSV file')
    p.add_argument('--duration', type=float, default=None,
                   help='record length [s] (default: one hold per current level)')
    p.add_argument('--plant', choices=PLANT_NAMES, default='spencer')
    p.add_argument('--seed', type=int, default=None, help='noise / random-excitation seed')
    p.add_argument('--excitation', choices=EXCITATION_NAMES, default='cam')
    p.add_argument('--currents', default='0,0.5,1,1.5,2',
                   help='comma-separated current levels [A]')
    p.add_argument('--hold', type=float, default=4 / 1.1,
                   help='time per current level [s] (default 4 cam periods)')
    p.add_argument('--noise', type=float, default=2.0, help='load-cell noise std [N]')
    p.add_argument('--truth-out', default=None, help='JSON file for the true parameters')
    return p


def main(argv=None):
    """Run the command line tool; returns the exit code."""
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        levels = [float(s) for s in args.currents.split(',') if s.strip()]
    except ValueError:
        parser.error(f'--currents: not a comma-separated list of numbers: {args.currents!r}')
    if not levels or not all(math.isfinite(c) and 0.0 <= c <= 5.0 for c in levels):
        parser.error('--currents: give one or more currents between 0 and 5 A')
    if args.duration is not None and not (math.isfinite(args.duration) and
                                          0 < args.duration <= 3600):
        parser.error(f'--duration must be in (0, 3600] s, got {args.duration}')
    if not (math.isfinite(args.hold) and args.hold > 0):
        parser.error(f'--hold must be positive, got {args.hold}')
    if not (math.isfinite(args.noise) and args.noise >= 0):
        parser.error(f'--noise must be >= 0, got {args.noise}')
    excitation = make_excitation(args.excitation, rng=args.seed)
    options = {'y0_m': excitation.center_m} if args.plant == 'spencer' else {}
    rig = VirtualRig(make_plant(args.plant, **options), excitation,
                     StepSchedule(levels, hold_s=args.hold), force_noise_n=args.noise,
                     rng=args.seed)
    data = rig.run(args.duration)
    try:
        write_csv(args.out, data)
        if args.truth_out:
            with open(args.truth_out, 'w') as fh:
                json.dump(dict(rig.true_parameters(), source=args.out), fh, indent=2)
    except OSError as exc:
        sys.stderr.write(f'mr-damper-rig-test: error: cannot write {exc.filename}: '
                         f'{exc.strerror}\n')
        return 2
    print(f'wrote {data.n} samples ({data.duration + 1 / rig.sample_rate_hz:.2f} s, '
          f'{args.plant} plant, {args.excitation}, currents {levels} A) to {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
