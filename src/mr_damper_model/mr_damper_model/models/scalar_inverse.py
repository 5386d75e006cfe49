"""
The scalar inverse's algorithm: plain functions over floats, compiled with numba.

:class:`~mr_damper_model.models.inverse.KwokCurrentInverse` and
:class:`~mr_damper_model.models.inverse.KwokCurrentLagInverse` (their docstrings describe the
algorithm) run :func:`scalar_current` compiled by :func:`scalar_kernels`
(:func:`mr_damper_model.models.compiled.kernel`, disk cache): a call costs microseconds where
the interpreted one cost tens, in every control cycle of every corner. The functions are
plain Python in numba's subset, on a model vector ``q`` (the ten kwok-current parameters, the
lag's constants and state: the ``Q_*`` slots) and a range vector (``L_*``), and give the same
answers interpreted (the tests compare the two).
"""
import math

import numpy as np

from mr_damper_model.models.kwok_current import (_coefficients, kwok_current_force_scalar,
                                                 kwok_current_force_slope_at,
                                                 kwok_current_terms_scalar)

__all__ = ['scalar_current', 'scalar_kernels', 'lagged_velocity']

MAX_ITER = 100
#: Dense check grid of the lag model's scalar inverse (a demand first found out of reach).
N_DENSE = 65

#: Slots of the scalar inverse's model vector ``q``: the ten kwok-current parameters, then the
#: lag's time constants [s], its lagged velocity before this sample [m/s] and the sample
#: interval [s] (0: the first sample), and the kind (0 kwok-current, 1 kwok-current-lag).
Q_TAU0, Q_TAU1, Q_U_PREV, Q_DT, Q_LAG = range(10, 15)
Q_N = 15
#: Slots of the scalar inverse's range vector: normalised ends, i_ref_a, i_min, i_max [A],
#: the normalised bracket tolerance.
L_S_LO, L_S_HI, L_I_REF, L_I_MIN, L_I_MAX, L_TOL_S = range(6)


def lagged_velocity(q, s, v):
    """Lagged velocity [m/s] after this sample at normalised current s (lag model)."""
    if q[Q_DT] <= 0.0:             # first sample
        return q[Q_U_PREV]
    tau = q[Q_TAU0] + q[Q_TAU1] * max(s, 0.0)
    if tau <= 0.0:
        return v
    a = math.exp(-q[Q_DT] / tau)
    return a * q[Q_U_PREV] + (1.0 - a) * v


def model_params(q):
    """Return the ten kwok-current parameters of a model vector, as a tuple."""
    return (q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7], q[8], q[9])


def scalar_force(q, s, x, v):
    """Model force [N] at normalised current s (kwok-current, or with the lag)."""
    p = model_params(q)
    if q[Q_LAG] == 0.0:
        return kwok_current_force_scalar(p, s, x, v)
    u = lagged_velocity(q, s, v)
    return kwok_current_force_scalar(p, s, x, u) + (q[0] + q[1] * s) * (v - u)


def scalar_force_slope(q, s, x, v):
    """Force [N] and slope dF/ds [N] (closed form; the lag's a central difference)."""
    if q[Q_LAG] == 0.0:
        p = model_params(q)
        return kwok_current_force_slope_at(kwok_current_terms_scalar(p, s), p, x, v)
    h = 1e-6
    return (scalar_force(q, s, x, v),
            (scalar_force(q, s + h, x, v) - scalar_force(q, s - h, x, v)) / (2.0 * h))


def scalar_solve(q, lim, a, b, fa, fb, f_des, x, v):
    """Illinois regula falsi on [a, b] (normalised currents) with fa, fb of opposite sign."""
    if fa == 0.0:
        b, fb = a, 0.0
    ftol = 1e-9 * (1.0 + abs(f_des))
    for _ in range(MAX_ITER):
        if abs(fb) <= ftol or abs(b - a) <= lim[L_TOL_S]:
            break
        c = b - fb * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
        if not min(a, b) < c < max(a, b):
            c = 0.5 * (a + b)
        fc = scalar_force(q, c, x, v) - f_des
        if fc * fb < 0.0:
            a, fa = b, fb
        else:
            fa *= 0.5
        b, fb = c, fc
    return min(max(b * lim[L_I_REF], lim[L_I_MIN]), lim[L_I_MAX])


def scalar_extremum(q, a, b, ga, gb, f_des, x, v):
    """
    Interior extremum of F on [a, b] (slopes ga, gb of opposite sign), by Illinois.

    Returns the normalised current of the extremum and ``F - f_des`` [N] there.
    """
    for _ in range(MAX_ITER):
        if abs(b - a) <= 1e-12:
            break
        c = b - gb * (b - a) / (gb - ga) if gb != ga else 0.5 * (a + b)
        if not min(a, b) < c < max(a, b):
            c = 0.5 * (a + b)
        gc = scalar_force_slope(q, c, x, v)[1]
        if gc == 0.0:
            b = c
            break
        if gc * gb < 0.0:
            a, ga = b, gb
        else:
            ga *= 0.5
        b, gb = c, gc
    return b, scalar_force(q, b, x, v) - f_des


def scalar_grid_scan(q, lim, grid, f_des, x, v, nearest):
    """
    Solve in the first bracket of ``f_des`` on a grid of normalised currents: ``(current, 0)``.

    Without one: with ``nearest`` the grid current of the nearest force and its flag (+1: the
    demand is above it), else ``(nan, 0)``.
    """
    n = len(grid)
    d_prev = scalar_force(q, grid[0], x, v) - f_des
    j_near, d_near = 0, d_prev
    for j in range(n - 1):
        d = scalar_force(q, grid[j + 1], x, v) - f_des
        if d_prev * d <= 0.0:
            return scalar_solve(q, lim, grid[j], grid[j + 1], d_prev, d, f_des, x, v), 0
        if abs(d) < abs(d_near):
            j_near, d_near = j + 1, d
        d_prev = d
    if not nearest:
        return math.nan, 0
    return grid[j_near] * lim[L_I_REF], (1 if d_near < 0.0 else -1)


def scalar_current(q, lim, grid, dense, f_des, x, v):
    """
    Return the current [A] and flag of one model force ``f_des`` [N] (the scalar inverse).

    The algorithm of :class:`KwokCurrentInverse` (its docstring); ``dense`` is the lag
    model's dense check grid (empty: none).
    """
    s_lo, s_hi = lim[L_S_LO], lim[L_S_HI]
    f_lo, g_lo = scalar_force_slope(q, s_lo, x, v)
    f_hi, g_hi = scalar_force_slope(q, s_hi, x, v)
    d_lo = f_lo - f_des
    d_hi = f_hi - f_des
    if d_lo == 0.0 or (d_lo < 0.0) != (d_hi < 0.0):
        return scalar_solve(q, lim, s_lo, s_hi, d_lo, d_hi, f_des, x, v), 0
    # the demand is beyond both end forces (on the same side): reachable only at an
    # interior extremum of F(i); the slopes at the ends say whether there is one
    above = d_lo < 0.0
    i_min, i_max = lim[L_I_MIN], lim[L_I_MAX]
    cur, flag = math.nan, 0
    if g_lo * g_hi < 0.0:
        # one interior extremum (a maximum when F rises from i_min)
        if (g_lo > 0.0) != above:       # it lies away from the demand: nearest end
            cur, flag = (i_min, -1) if abs(d_lo) <= abs(d_hi) else (i_max, 1)
        else:
            s_x, d_x = scalar_extremum(q, s_lo, s_hi, g_lo, g_hi, f_des, x, v)
            if d_x == 0.0 or (d_x < 0.0) != above:
                return scalar_solve(q, lim, s_lo, s_x, d_lo, d_x, f_des, x, v), 0
            cur, flag = (min(max(s_x * lim[L_I_REF], i_min), i_max), 1 if d_x < 0.0 else -1)
    elif g_lo * g_hi > 0.0 and (g_lo > 0.0) == (d_hi > d_lo):
        # F(i) runs the same way at both ends as from end to end: monotone unless it has
        # two interior extrema, which a mid-range force outside the end forces shows
        d_mid = scalar_force(q, 0.5 * (s_lo + s_hi), x, v) - f_des
        if min(d_lo, d_hi) <= d_mid <= max(d_lo, d_hi):
            cur, flag = (i_min, -1) if abs(d_lo) <= abs(d_hi) else (i_max, 1)
    if math.isnan(cur):
        cur, flag = scalar_grid_scan(q, lim, grid, f_des, x, v, True)
        if flag == 0:
            return cur, 0
    if len(dense):
        # the lag's narrow peak that the end test and the coarse grid step over
        c_dense, _ = scalar_grid_scan(q, lim, dense, f_des, x, v, False)
        if not math.isnan(c_dense):
            return c_dense, 0
    return cur, flag


def scalar_kernels():
    """
    Return the compiled scalar inverse and force: ``(scalar_current, scalar_force)``.

    Compiled (numba, disk cache: :func:`mr_damper_model.models.compiled.kernel`) and run once
    on the first call in a process, so that the first control cycle does not pay for either.
    """
    global _SCALAR_KERNELS
    if _SCALAR_KERNELS is None:
        from mr_damper_model.models import compiled
        helpers = ('lagged_velocity', 'model_params', 'scalar_force', 'scalar_force_slope',
                   'scalar_solve', 'scalar_extremum', 'scalar_grid_scan',
                   kwok_current_force_scalar, kwok_current_force_slope_at,
                   kwok_current_terms_scalar, _coefficients)
        current = compiled.kernel(scalar_current, helpers=helpers, inline='never')
        force = compiled.kernel(scalar_force, helpers=helpers, inline='never')
        q = np.zeros(Q_N)
        q[6] = 1.0
        lim = np.array([0.0, 1.0, 2.0, 0.0, 2.0, 1e-12])
        grid = np.linspace(0.0, 1.0, 3)
        current(q, lim, grid, np.zeros(0), 1.0, 0.01, 0.1)
        force(q, 0.5, 0.01, 0.1)
        _SCALAR_KERNELS = (current, force)
    return _SCALAR_KERNELS


_SCALAR_KERNELS = None
