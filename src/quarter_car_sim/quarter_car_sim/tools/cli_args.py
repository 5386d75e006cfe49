"""
Command-line helpers of the offline studies (``quarter-car-sim``, ``full-car-sim``).

One home for the argument parser whose errors are one line on stderr with exit status 2, and
for the positive-number argument type.
"""
import argparse
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
