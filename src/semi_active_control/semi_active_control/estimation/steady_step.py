"""
The full-car filter's steady step compiled (numba): a clean cycle in microseconds.

On a vehicle, nearly every cycle is the same: every sensor read, none stuck or out of range,
the filter on its steady gain. :class:`~semi_active_control.estimation.full_car.FullCarEstimator`
then does what :func:`steady_step` does, in a dozen small numpy operations whose interpreter
overhead is most of the cycle's estimate. :func:`steady_step` runs that cycle over scalars,
compiled with :func:`mr_damper_model.models.compiled.kernel` (disk cache), and tells the caller
whether the cycle was such a clean one:

1. predict: ``x = Ad x + Bd f`` (the previous cycle's forces, held);
2. innovation ``e = y - gravity - H x - Dm f_now``;
3. screen, as ``FullCarEstimator._screen`` does: a reading equal to its sensor's previous one
   extends that sensor's run of repeats; the run reaching ``stuck_n`` readings, or a repeat
   more than ``sqrt(gate2)`` innovation standard deviations off (``s_steady``), is stuck; a
   reading at or beyond either end of its range is out;
4. every reading finite and used: ``x = x + M e``.

It changes nothing and returns False when the cycle is not clean (a reading missing, stuck or
out of range, or a state that would not be finite): the caller then runs the general step
from the same state, which names and counts what happened. Otherwise it writes the new state,
the sensors' last-seen times, last readings and runs of repeats, and returns True. The tests
run both on the same sensor streams, faults included, and compare the states.
"""
import math

import numpy as np

from mr_damper_model.models import compiled

__all__ = ['steady_step', 'steady_step_kernel']


def steady_step(x, f, f_now, y, t, gravity, Ad, Bd, H, Dm, M, seen, last_val, same, same_out,
                stuck_n, gate2, s_steady, lo, hi, work):
    """
    One steady cycle in place, or nothing (see the module docstring); return whether it ran.

    Parameters
    ----------
    x : ndarray (n,)
        Posterior state of the last cycle; the new posterior on success.
    f, f_now : ndarray (4,)
        Forces of the last cycle (held over the period) and of this one [N].
    y : ndarray (m,)
        Readings (NaN: none).
    gravity : ndarray (m,)
        Subtracted from each reading.
    t : float
        The cycle's time [s] (each sensor's last-seen time on success).
    Ad, Bd, H, Dm, M : ndarray
        The design's transition, force input, measurement, force feedthrough and steady gain.
    seen, last_val : ndarray (m,)
        Each sensor's last-seen time and last reading (updated on success).
    same, same_out : ndarray (m,) of int
        Each sensor's run of repeats before the cycle; its runs after it (on success; may be
        ``same`` itself).
    stuck_n : ndarray (m,) of int
        Repeats that make a sensor stuck.
    gate2 : float
        Squared repeat gate (NaN: none).
    s_steady : ndarray (m,)
        The steady gain's innovation variances.
    lo, hi : ndarray (m,)
        Ends of each sensor's range (a reading at or beyond one is out).
    work : ndarray (n + m,)
        Scratch: the new state, then the new runs of repeats.

    Returns
    -------
    bool

    """
    n, m = x.shape[0], y.shape[0]
    for k in range(m):
        if not (lo[k] < y[k] < hi[k]):       # NaN, or at or beyond an end of the range
            return False
    repeats = False
    for k in range(m):
        if y[k] == last_val[k]:
            repeats = True
            break
    # the prediction, then the innovation per reading (each kept in the scratch's state part)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += Ad[i, j] * x[j]
        for j in range(f.shape[0]):
            acc += Bd[i, j] * f[j]
        work[i] = acc
    e = np.empty(m)
    for k in range(m):
        acc = y[k] - gravity[k]
        for j in range(n):
            acc -= H[k, j] * work[j]
        for j in range(f_now.shape[0]):
            acc -= Dm[k, j] * f_now[j]
        e[k] = acc
        if repeats:
            run = same[k] + 1 if y[k] == last_val[k] else 0
            if run + 1 >= stuck_n[k]:
                return False
            if run > 0 and not math.isnan(gate2) and acc * acc > gate2 * s_steady[k]:
                return False
            work[n + k] = run
        else:
            work[n + k] = 0
    for i in range(n):
        acc = work[i]
        for k in range(m):
            acc += M[i, k] * e[k]
        if not math.isfinite(acc):
            return False
        work[i] = acc
    for i in range(n):
        x[i] = work[i]
    for k in range(m):
        seen[k] = t
        last_val[k] = y[k]
        same_out[k] = int(work[n + k])
    return True


def steady_step_kernel():
    """Return :func:`steady_step` compiled (loaded from the disk cache after the first time)."""
    return compiled.kernel(steady_step)
