"""
The one rule for a parameter set's values: finite, inside the model's box, not pinned at a bound.

The live identifier applies it to every fitted set (:mod:`mr_damper_model.live`) and the car's
supervisor (``semi_active_control.supervision.failsafe.ModelSupervisor``) to every set it receives,
with the same tolerances, so a set the identifier publishes as valid is not refused by the car for
its values (the car adds its own checks on the current range it needs).

- **finite**: every parameter finite (``non_finite``);
- **in the box**: every parameter inside the model's bounds, within :data:`BOUND_TOL` of the
  bound span (rounding in a message or a JSON file moves no set out; ``out_of_bounds``);
- **not pinned**: no parameter within ``pinned_fraction`` of the bound span from a bound that is
  not zero (``pinned_at_bound``). Zero bounds (the lower bound of a non-negative coefficient:
  no viscous term, no hysteresis, no loop shift) are values a physical damper can take; a fit
  stopped at the end of the search box (``f0`` at 500 N, ``beta0`` at 0.1 or 1000 s/m,
  ``beta1`` at +-3) is one the data pushed out of the physical range, typically by a sensor
  fault.
"""
from dataclasses import dataclass

import numpy as np

from mr_damper_model.models.base import get_model

#: Tolerance of the box check, as a fraction of each parameter's bound span.
BOUND_TOL = 1e-9
#: Default ``pinned_fraction`` of the identifier and the car's supervisor.
PINNED_FRACTION = 1e-3
#: Reasons of :func:`check_parameter_values`, in the order they are checked.
VALUE_REASONS = ('non_finite', 'out_of_bounds', 'pinned_at_bound')


@dataclass(frozen=True)
class ValueCheck:
    """Result of :func:`check_parameter_values`: ``reason`` '' when the set passes."""

    reason: str = ''
    names: tuple = ()

    def __bool__(self):
        return not self.reason


def pinned_parameters(names, values, lo, hi, fraction):
    """
    Return the names of parameters pinned at a non-zero bound of their box.

    Parameters
    ----------
    names : sequence of str
        Parameter names.
    values, lo, hi : array_like with shape (n,)
        Values and bounds (infinite bounds are never reached).
    fraction : float
        Fraction of ``hi - lo``.

    Returns
    -------
    list of str

    """
    x = np.asarray(values, dtype=float)
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    span = np.where(np.isfinite(hi - lo), hi - lo, np.inf)
    tol = fraction * span
    at_lo = np.isfinite(lo) & (lo != 0) & (x <= lo + tol)
    at_hi = np.isfinite(hi) & (hi != 0) & (x >= hi - tol)
    return [n for n, a, b in zip(names, at_lo, at_hi) if a or b]


def check_parameter_values(names, values, lo, hi, *, pinned_fraction=PINNED_FRACTION,
                           exempt=()):
    """
    Check a parameter set's values against its box (the module's rule).

    Parameters
    ----------
    names : sequence of str
        Parameter names.
    values, lo, hi : array_like with shape (n,)
        Values and box bounds.
    pinned_fraction : float or None
        See the module docstring; None: the pinned check is left out.
    exempt : iterable of str
        Parameters left out of the pinned check.

    Returns
    -------
    ValueCheck
        ``reason`` one of :data:`VALUE_REASONS` or '', ``names`` the parameters concerned.

    """
    x = np.asarray(values, dtype=float)
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    bad = ~np.isfinite(x)
    if bad.any():
        return ValueCheck('non_finite', tuple(n for n, b in zip(names, bad) if b))
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    tol = BOUND_TOL * span
    bad = (x < lo - tol) | (x > hi + tol)
    if bad.any():
        return ValueCheck('out_of_bounds', tuple(n for n, b in zip(names, bad) if b))
    if pinned_fraction is not None:
        pinned = [n for n in pinned_parameters(names, x, lo, hi, pinned_fraction)
                  if n not in set(exempt)]
        if pinned:
            return ValueCheck('pinned_at_bound', tuple(pinned))
    return ValueCheck()


def check_model_parameters(model, params, *, unbounded=False, i_ref_a=None,
                           pinned_fraction=PINNED_FRACTION, exempt=()):
    """
    :func:`check_parameter_values` of a ``{name: value}`` set of a registered model.

    ``i_ref_a`` is the reference current of ``kwok-current``; ``unbounded`` takes the model's
    wide search box instead of its physical one.
    """
    options = {'i_ref_a': i_ref_a} if model == 'kwok-current' and i_ref_a else {}
    mdl = get_model(model, **options)
    lo, hi = mdl.default_bounds(unbounded=unbounded)
    return check_parameter_values(mdl.param_names, [params[n] for n in mdl.param_names], lo, hi,
                                  pinned_fraction=pinned_fraction, exempt=exempt)
