"""
Command-line helpers of the offline studies (``quarter-car-sim``, ``full-car-sim``).

One home for the argument parser whose errors are one line on stderr with exit status 2, for
the positive-number argument type, and for the road-preview rows' options both tools share.
"""
import argparse
import dataclasses
import math


class OneLineParser(argparse.ArgumentParser):
    """Argument parser whose errors are one line on stderr and exit status 2."""

    def error(self, message):
        """Print one line and exit 2."""
        self.exit(2, f'{self.prog}: error: {message}\n')


def positive(name):
    """
    Return an argparse type for a finite number > 0 (the message names the option).

    Parameters
    ----------
    name : str
        Option name used in the error message (e.g. ``'--speed'``).

    """
    def conv(text):
        try:
            val = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'{name} must be a number, got {text!r}') from None
        if not (math.isfinite(val) and val > 0):
            raise argparse.ArgumentTypeError(f'{name} must be > 0, got {text}')
        return val
    return conv


def add_preview_arguments(p):
    """Add the preview rows' options to a parser (``full-car-sim`` and ``quarter-car-sim``)."""
    from quarter_car_sim.preview_rows import PreviewOptions
    from quarter_car_sim.preview_sensor import REALISTIC_LOOK_AHEAD as R
    d = PreviewOptions()
    p.add_argument('--preview-horizon', type=positive('--preview-horizon'),
                   default=d.horizon_s, metavar='S',
                   help=f'preview horizon of the preview laws [s] (default {d.horizon_s:g})')
    p.add_argument('--preview-latency', type=float, default=R.latency_s, metavar='S',
                   help='look-ahead sensor latency of the preview-look-ahead row [s] '
                        f'(default {R.latency_s:g})')
    p.add_argument('--preview-noise', type=float, default=R.height_noise_m, metavar='M',
                   help='RMS height noise of its sensor [m] (default '
                        f'{R.height_noise_m:g})')
    p.add_argument('--preview-range', default=f'{R.range_m[0]:g},{R.range_m[1]:g}',
                   metavar='NEAR,FAR', help='range of its sensor ahead of the front axle [m] '
                                            f'(default {R.range_m[0]:g},{R.range_m[1]:g})')
    p.add_argument('--preview-rate', type=positive('--preview-rate'), default=R.rate_hz,
                   metavar='HZ', help=f'its frames per second (default {R.rate_hz:g})')
    p.add_argument('--speed-error', type=float, default=d.speed_error, metavar='FRACTION',
                   help='scale error of the speed signal of the preview-look-ahead and '
                        f'preview-wheelbase rows (default {d.speed_error:g})')


def preview_options(args):
    """Return the :class:`~quarter_car_sim.preview_rows.PreviewOptions` of parsed ``args``."""
    from quarter_car_sim.preview_rows import PreviewOptions
    from quarter_car_sim.preview_sensor import REALISTIC_LOOK_AHEAD
    try:
        near, far = (float(v) for v in str(args.preview_range).split(','))
    except ValueError:
        raise ValueError('--preview-range must be NEAR,FAR, got '
                         f'{args.preview_range!r}') from None
    spec = dataclasses.replace(REALISTIC_LOOK_AHEAD, range_m=(near, far),
                               latency_s=args.preview_latency,
                               height_noise_m=args.preview_noise, rate_hz=args.preview_rate)
    if not (math.isfinite(args.speed_error) and abs(args.speed_error) < 0.5):
        raise ValueError(f'--speed-error must be within +-0.5, got {args.speed_error}')
    return PreviewOptions(horizon_s=args.preview_horizon, sensor=spec,
                          speed_error=args.speed_error, seed=args.seed)
