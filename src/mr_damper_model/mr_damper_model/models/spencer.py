"""
Spencer et al. (1997) modified Bouc-Wen MR damper model with current dependence, SI units.

::

    udot  = -eta*(u - i)                               (coil / MR fluid first-order lag)
    alpha = alpha_a + alpha_b*u,  c0 = c0a + c0b*u,  c1 = c1a + c1b*u
    ydot  = (alpha*z + c0*xdot + k0*(x - y)) / (c0 + c1)
    zdot  = -gamma*|w|*z*|z|**(n-1) - beta*w*|z|**n + A*w,     w = xdot - ydot
    F     = c1*ydot + k1*(x - x0)

with n = 2 (Spencer's value, a fixed model constant here). Spencer used a voltage input
(0-2.25 V); here the input is the coil current i [A] and the b-coefficients are per ampere.

Numerics. The model is stiff: with Spencer's gamma = beta = 363 cm**-2 and A = 301 z saturates
over a relative displacement of about 20 um, i.e. within about 0.1 ms at 0.2 m/s. Each sample
interval is split into sub-steps of at most ``max_substep_s`` (default 0.1 ms). Over a sub-step
the relative displacement ``dr = w*h`` is taken from a Heun (predictor-corrector) estimate of w,
and z is advanced over dr *exactly*: in terms of r, with q = sign(dr)*z,

* q >= 0 (z in the direction of motion): dq/dr = A - (beta + gamma)*q**2, so
  q = zs*tanh(atanh(q0/zs) + sqrt(A*(beta + gamma))*r), zs = sqrt(A/(beta + gamma));
* q < 0: dq/dr = A - (beta - gamma)*q**2: linear for beta == gamma, tanh for beta > gamma,
  tan for beta < gamma, up to the zero crossing, after which the first case continues.

So the fast saturation of z is exact whatever the step, and the 1 kHz grid with 10 sub-steps
matches a 100x finer integration to about 0.1 % of the peak force (tested). u is advanced exactly
(exponential) with the current held over each sample interval. y (time constant
(c0 + c1)/k0, seconds) uses the Heun step.

Over the project's ~600 lines: the exact sub-step of z (its four cases) and its derivation
stay next to the model they integrate, and so does the tanh of the compiled lanes
(:func:`tanh_lanes`), which only that sub-step calls.

Requirements (default bounds enforce them): A > 0, beta + gamma > 0, gamma >= 0.
Initial state of ``force``: y = x[0] (or the option ``y0_m``), z = 0, u = i[0] (coil settled at
the first sample). Note the slow internal mode: y relaxes towards the mean piston position with
the time constant (c0 + c1)/k0 (6.5 s for Spencer's damper), so a test starting at the end of
the stroke with y = x[0] shows a decaying force offset; ``y0_m`` = the centre of the motion
starts in the periodic steady state (the virtual rig does this).
"""
import math

import numpy as np

from mr_damper_model.models import compiled
from mr_damper_model.models import HysteresisModel, ModelError

_EDGE = 1.0 - 1e-12

SPENCER_PARAM_NAMES = ('c0a', 'c0b', 'k0', 'c1a', 'c1b', 'k1', 'x0', 'alpha_a', 'alpha_b',
                       'gamma', 'beta', 'A', 'eta')


def z_step_scalar(z0, dr, A, beta, gamma):
    """
    Advance z exactly over a relative displacement dr (n = 2), plain floats.

    Parameters
    ----------
    z0 : float
        Hysteretic displacement at the start [m].
    dr : float
        Relative displacement x - y travelled [m].
    A : float
        Bouc-Wen A [-], > 0.
    beta, gamma : float
        Bouc-Wen beta, gamma [1/m**2]; beta + gamma > 0, gamma >= 0.

    Returns
    -------
    float

    """
    return z_step_rooted(z0, dr, z_roots(A, beta, gamma))


def z_roots(A, beta, gamma):
    """
    Constants of the exact z update of one parameter set, computed once: plain floats.

    Returns
    -------
    tuple of float
        ``(A, beta - gamma, sqrt(A/(beta + gamma)), sqrt(A*(beta + gamma)), sqrt(A/|bp|),
        sqrt(A*|bp|))`` (the last two 1.0 when ``beta == gamma``), for :func:`z_step_rooted`.

    """
    b = beta + gamma
    bp = beta - gamma
    if bp == 0.0:
        return A, bp, math.sqrt(A / b), math.sqrt(A * b), 1.0, 1.0
    return (A, bp, math.sqrt(A / b), math.sqrt(A * b), math.sqrt(A / abs(bp)),
            math.sqrt(A * abs(bp)))


def z_step_array_zc(z0, dr, zc):
    """``z_step_array`` with ``zc = (A, beta, gamma)`` (the numpy reference's z step)."""
    A, beta, gamma = zc
    return z_step_array(z0, dr, A, beta, gamma)


def z_step_rooted(z0, dr, zc, tanh=math.tanh):
    """
    Advance z exactly over dr (n = 2) with the constants of the parameter set (the loops' step).

    The solution of ``z_step_scalar`` (which calls this) in a form with one tanh (tan for
    beta < gamma) per update: with ``a = tanh(a0)``, ``tanh(a0 + k*r) = (a + T)/(1 + a*T)``,
    ``T = tanh(k*r)``; only the zero crossing of the opposite-direction branch (``T >= a``)
    needs an atanh (atan); the formulae of ``z_step_array`` (the vectorised reference) within
    round-off.

    Parameters
    ----------
    z0, dr : float
        As in ``z_step_scalar``.
    zc : tuple of float
        :func:`z_roots` of the parameter set: ``(A, bp, zs, k, zsp, kp)`` with bp = beta - gamma
        [1/m**2], zs = sqrt(A/(beta + gamma)) [m], k = sqrt(A*(beta + gamma)) [1/m],
        zsp = sqrt(A/|bp|) [m], kp = sqrt(A*|bp|) [1/m] (unused when bp == 0).
    tanh : callable
        The hyperbolic tangent: the C library's (``math.tanh``, the simulator's plant) or
        :func:`tanh_lanes` (the compiled lanes of :func:`heun_substeps_lanes`).

    Returns
    -------
    float

    """
    A, bp, zs, k, zsp, kp = zc
    if dr == 0.0:
        return z0
    s = 1.0 if dr > 0.0 else -1.0
    q = s * z0
    r = abs(dr)
    if q < 0.0:
        if bp == 0.0:
            r0 = -q / A
            if r < r0:
                return s * (q + A * r)
        elif bp > 0.0:
            a = min(-q / zsp, _EDGE)
            tk = tanh(kp * r)
            if tk < a:
                return -s * zsp * (a - tk) / (1.0 - a * tk)
            r0 = math.atanh(a) / kp
        else:
            a = -q / zsp
            kr = kp * r
            if kr < 0.5 * math.pi:
                tk = math.tan(kr)
                if tk < a:
                    return -s * zsp * (a - tk) / (1.0 + a * tk)
            r0 = math.atan(a) / kp
        q = 0.0
        r = max(r - r0, 0.0)
    a = min(q / zs, _EDGE)
    tk = tanh(k * r)
    return s * zs * (a + tk) / (1.0 + a * tk)


def z_step_array(z0, dr, A, beta, gamma):
    """
    Vectorised ``z_step_scalar`` (same formulae, numpy arrays of equal shape).

    Parameters
    ----------
    z0, dr, A, beta, gamma : numpy.ndarray
        As in ``z_step_scalar``, broadcastable.

    Returns
    -------
    numpy.ndarray

    """
    s = np.where(dr >= 0.0, 1.0, -1.0)
    q = s * z0
    r = np.abs(dr)
    opp = q < 0.0
    bp = beta - gamma
    aq = np.where(opp, -q, 0.0)
    # linear case (bp == 0)
    lin = bp == 0.0
    pos = bp > 0.0
    abp = np.where(lin, 1.0, np.abs(bp))
    zsp = np.sqrt(A / abp)
    kp = np.sqrt(A * abp)
    ratio = aq / zsp
    a_pos = np.arctanh(np.minimum(ratio, _EDGE))
    a_neg = np.arctan(ratio)
    a0 = np.where(pos, a_pos, a_neg)
    r0 = np.where(lin, aq / A, a0 / kp)
    r_in = np.minimum(r, r0)
    q_lin = -aq + A * r_in
    q_pos = -zsp * np.tanh(a_pos - kp * r_in)
    q_neg = -zsp * np.tan(a_neg - kp * r_in)
    q_opp = np.where(lin, q_lin, np.where(pos, q_pos, q_neg))
    still_opp = opp & (r < r0)
    r_rest = np.where(opp, np.maximum(r - r0, 0.0), r)
    q_start = np.where(opp, 0.0, q)
    b = beta + gamma
    zs = np.sqrt(A / b)
    k = np.sqrt(A * b)
    q_same = zs * np.tanh(np.arctanh(np.minimum(q_start / zs, _EDGE)) + k * r_rest)
    return s * np.where(still_opp, q_opp, q_same)


def substeps(dt, max_substep_s):
    """Return the number of sub-steps for a sample interval dt [s] (at least one)."""
    return max(1, int(math.ceil(dt / max_substep_s - 1e-9)))


def heun_substeps(z_step, zc, p, y, z, u, x_a, v_a, dx, dv, i_drv, h, decay, m):
    """
    Advance (y, z, u) over m Heun sub-steps with the exact z update.

    Works for plain floats and for numpy arrays alike (one value per parameter set); the
    arithmetic is the same, so the streaming plant and the batch model agree.

    Parameters
    ----------
    z_step : callable
        ``z_step(z, dr, zc)``: :func:`z_step_rooted` for floats, :func:`z_step_array_zc` for
        arrays.
    zc : tuple
        Its constants of the parameter set(s): :func:`z_roots`, or ``(A, beta, gamma)``.
    p : sequence
        Parameters in ``SPENCER_PARAM_NAMES`` order (floats or arrays).
    y, z, u : float or ndarray
        Internal displacement [m], hysteretic displacement [m] and coil current [A].
    x_a, v_a : float
        Displacement [m] and velocity [m/s] at the start of the interval.
    dx, dv : float
        Displacement [m] and velocity [m/s] increments per sub-step.
    i_drv : float
        Current driving the coil filter over the interval [A].
    h : float
        Sub-step [s].
    decay : float or ndarray
        Coil filter factor over one sub-step, ``exp(-eta*h)``.
    m : int
        Number of sub-steps.

    Returns
    -------
    tuple
        (y, z, u) at the end of the interval.

    """
    c0a, c0b, k0, c1a, c1b, k1, x0, aa, ab, gamma, beta, A, eta = p
    xs = x_a
    vs = v_a
    for _ in range(m):
        xe = xs + dx
        ve = vs + dv
        alpha = aa + ab * u
        c0 = c0a + c0b * u
        den = c0 + c1a + c1b * u
        yd_a = (alpha * z + c0 * vs + k0 * (xs - y)) / den
        w_a = vs - yd_a
        z_p = z_step(z, w_a * h, zc)
        u_e = i_drv + (u - i_drv) * decay
        alpha_e = aa + ab * u_e
        c0_e = c0a + c0b * u_e
        den_e = c0_e + c1a + c1b * u_e
        y_p = y + h * yd_a
        yd_p = (alpha_e * z_p + c0_e * ve + k0 * (xe - y_p)) / den_e
        w_p = ve - yd_p
        z = z_step(z, 0.5 * (w_a + w_p) * h, zc)
        yd_e = (alpha_e * z + c0_e * ve + k0 * (xe - y_p)) / den_e
        y = y + 0.5 * h * (yd_a + yd_e)
        u = u_e
        xs = xe
        vs = ve
    return y, z, u


def tanh_lanes(x):
    """
    Return tanh(x) within about an ulp of the C library's, cheaper when compiled by numba.

    The tanh of :func:`heun_substeps_lanes` (the gym's compiled plants); the simulator's plant
    keeps ``math.tanh``. Below |x| = 0.5 an odd polynomial, ``x*(1 + u*P(u))`` with u = x**2
    and P of degree 9 (near-minimax on [0, 0.25], fitted to tanh in 50-digit arithmetic,
    approximation error 4.4e-17; evaluated in Estrin's scheme, which shortens the chain of
    dependent operations); from 0.5 to 19.1 ``1 - 2/(exp(2|x|) + 1)`` with the sign of x
    (libm's exp is about twice as fast as its tanh or expm1 here); beyond, +-1, to which tanh
    rounds in float64 from |x| = 19.06. NaN gives NaN, +-inf +-1, +-0.0 itself; below 1e-8 it
    returns x. Largest relative error against a 40-digit tanh (mpmath, about 300,000 points
    from 1e-300 to 40): 1.6e-16 below 0.5, 3.2e-16 above (``math.tanh`` 3.0e-16 on the same
    points); against ``math.tanh``, 4.4e-16 on 4.8 million points
    (``tests/mr_damper_model/test_tanh_lanes.py`` holds it within 6e-16). Compiled by numba on
    the project's 2-vCPU VM: 3.5-4.3 ns a call below 0.5 and 9-14 ns above, libm's tanh 17-29
    ns (independent calls in a loop; docs/gym.md "Speed").
    """
    ax = abs(x)
    if ax < 0.5:
        u = x * x
        u2 = u * u
        u4 = u2 * u2
        p = (((-0.3333333333333333 + 0.13333333333329825 * u)
              + (-0.05396825396361009 + 0.021869488297234514 * u) * u2)
             + ((-0.008863229270067843 + 0.0035920334653723926 * u)
                + (-0.001454959384380466 + 0.0005849653729022644 * u) * u2) * u4
             + (-0.00022107222975864633 + 5.946956589774769e-05 * u) * (u4 * u4))
        return x * (1.0 + u * p)
    if ax >= 19.1:
        return math.copysign(1.0, x)
    return math.copysign(1.0 - 2.0 / (math.exp(2.0 * ax) + 1.0), x)


def heun_substeps_lanes(z_step, zc, P, h, decay, m, y, z, u, xs, vs, dx, dv, i_drv, w):
    """
    Advance n independent plants (lanes) over m Heun sub-steps: :func:`heun_substeps` per lane.

    The arithmetic of :func:`heun_substeps`, term for term, but for the tanh of the z steps:
    :func:`tanh_lanes` (within about an ulp of ``math.tanh``, three to four times cheaper
    compiled) in the C library's place, so each lane's (y, z, u) is the plant's to round-off
    (tested to 1e-12 relative), no longer bit for bit. Each stage of a sub-step (the
    predictor's rate, its z step, the corrector's rate, its z step, the end) runs lane after
    lane, so a compiled loop keeps the lanes' independent chains of divisions and tanh side
    by side instead of waiting on one lane's. For the compiled loops (plain Python works too).

    Parameters
    ----------
    z_step : callable
        ``z_step(z, dr, zc, tanh)``: :func:`z_step_rooted`.
    zc : ndarray (n, 6)
        Each lane's :func:`z_roots`.
    P : ndarray (n, 13)
        Each lane's parameters in ``SPENCER_PARAM_NAMES`` order.
    h, decay : ndarray (n,)
        Each lane's sub-step [s] and coil filter factor over it, ``exp(-eta*h)``.
    m : int
        Number of sub-steps (the same for every lane).
    y, z, u : ndarray (n,)
        Internal displacement [m], hysteretic displacement [m] and coil current [A]; advanced
        in place.
    xs, vs : ndarray (n,)
        Displacement [m] and velocity [m/s] at the start of the interval; advanced in place to
        the last sub-step's (summed as :func:`heun_substeps` sums them).
    dx, dv, i_drv : ndarray (n,)
        Increments per sub-step and the current driving the coil filter [A], as in
        :func:`heun_substeps`.
    w : ndarray (n, 8)
        Scratch.

    """
    n = y.shape[0]
    for _ in range(m):
        for q in range(n):
            c0a, c0b, k0, c1a, c1b, k1, x0, aa, ab, gamma, beta, A, eta = _row(P, q)
            alpha = aa + ab * u[q]
            c0 = c0a + c0b * u[q]
            den = c0 + c1a + c1b * u[q]
            yd_a = (alpha * z[q] + c0 * vs[q] + k0 * (xs[q] - y[q])) / den
            u_e = i_drv[q] + (u[q] - i_drv[q]) * decay[q]
            w[q, 0] = yd_a
            w[q, 1] = vs[q] - yd_a
            w[q, 2] = u_e
            w[q, 3] = aa + ab * u_e
            w[q, 4] = c0a + c0b * u_e
            w[q, 5] = w[q, 4] + c1a + c1b * u_e
            w[q, 6] = y[q] + h[q] * yd_a
        for q in range(n):
            w[q, 7] = z_step(z[q], w[q, 1] * h[q],
                             (zc[q, 0], zc[q, 1], zc[q, 2], zc[q, 3], zc[q, 4], zc[q, 5]),
                             tanh_lanes)
        for q in range(n):
            k0 = P[q, 2]
            xe = xs[q] + dx[q]
            ve = vs[q] + dv[q]
            yd_p = (w[q, 3] * w[q, 7] + w[q, 4] * ve + k0 * (xe - w[q, 6])) / w[q, 5]
            w[q, 7] = ve - yd_p
        for q in range(n):
            z[q] = z_step(z[q], 0.5 * (w[q, 1] + w[q, 7]) * h[q],
                          (zc[q, 0], zc[q, 1], zc[q, 2], zc[q, 3], zc[q, 4], zc[q, 5]),
                          tanh_lanes)
        for q in range(n):
            k0 = P[q, 2]
            xe = xs[q] + dx[q]
            ve = vs[q] + dv[q]
            yd_e = (w[q, 3] * z[q] + w[q, 4] * ve + k0 * (xe - w[q, 6])) / w[q, 5]
            y[q] = y[q] + 0.5 * h[q] * (w[q, 0] + yd_e)
            u[q] = w[q, 2]
            xs[q] = xe
            vs[q] = ve


def advance_scalar(state, p, x_a, v_a, x_b, v_b, i_drv, dt, m):
    """
    Advance the Spencer state over one sample interval with plain floats.

    Parameters
    ----------
    state : list of float
        [y, z, u], modified in place.
    p : tuple of float
        Parameters in ``SPENCER_PARAM_NAMES`` order.
    x_a, v_a, x_b, v_b : float
        Displacement [m] and velocity [m/s] at the start and the end of the interval.
    i_drv : float
        Current driving the coil filter over the interval [A].
    dt : float
        Interval [s].
    m : int
        Number of sub-steps.

    Returns
    -------
    float
        Force at the end of the interval [N].

    """
    y, z, u, f = advance_step(p, state[0], state[1], state[2], x_a, v_a, x_b, v_b, i_drv, dt, m)
    state[0] = y
    state[1] = z
    state[2] = u
    return f


def advance_step(p, y, z, u, x_a, v_a, x_b, v_b, i_drv, dt, m):
    """
    Advance the Spencer state (y, z, u) over one sample interval: plain floats, no state object.

    The arithmetic of :func:`advance_scalar` (which calls this), in a form numba compiles
    (:func:`advance_step_compiled`: the streaming plant's step).

    Parameters
    ----------
    p : tuple of float
        Parameters in ``SPENCER_PARAM_NAMES`` order.
    y, z, u : float
        Internal displacement [m], hysteretic displacement [m] and coil current [A] at the
        start of the interval.
    x_a, v_a, x_b, v_b, i_drv, dt, m
        As in :func:`advance_scalar`.

    Returns
    -------
    tuple of float
        (y, z, u) at the end of the interval and the force there [N].

    """
    c0a, c0b, k0, c1a, c1b, k1, x0, aa, ab, gamma, beta, A, eta = p
    h = dt / m
    decay = math.exp(-eta * h)
    dx = (x_b - x_a) / m
    dv = (v_b - v_a) / m
    y, z, u = heun_substeps(z_step_rooted, z_roots(A, beta, gamma), p, y, z, u, x_a, v_a, dx,
                            dv, i_drv, h, decay, m)
    c1 = c1a + c1b * u
    yd = ((aa + ab * u) * z + (c0a + c0b * u) * v_b + k0 * (x_b - y)) / (c0a + c0b * u + c1)
    return y, z, u, c1 * yd + k1 * (x_b - x0)


def advance_step_compiled():
    """
    Return :func:`advance_step` compiled by numba (``cache=True``; the same arithmetic).

    The streaming plant calls it once per sample; compiled, one 1 kHz sample with its ten
    sub-steps costs about an eighth of the interpreted step (``bench/bench_car_step.py``).
    """
    return compiled.kernel(advance_step, helpers=('heun_substeps', 'z_roots', 'z_step_rooted'))


def _initial_force(p, x, v, y, u):
    """Force [N] at the start of a record: state (y, z = 0, u), any floats or arrays."""
    c0a, c0b, k0, c1a, c1b, k1, x0, aa, ab, gamma, beta, A, eta = p
    c0 = c0a + c0b * u
    c1 = c1a + c1b * u
    return c1 * (c0 * v + k0 * (x - y)) / (c0 + c1) + k1 * (x - x0)


def _force_loop(P, x, v, i, t, y0, max_substep_s, out):
    """
    Time loop of :func:`spencer_force` over scalars.

    Compiled by :mod:`mr_damper_model.models.compiled`.

    Time outer, sub-steps, then the whole swarm innermost (independent particles in a row keep
    the processor busy while each one's transcendental functions complete); each particle's
    sub-step is ``heun_substeps`` with ``z_step_rooted`` (the constants of ``z_roots``
    computed once per particle) and one step, the sub-step positions
    summed as ``heun_substeps`` sums them: the arithmetic of the streaming plant
    (``advance_scalar``), bit for bit.
    """
    p = P.shape[0]
    y = np.full(p, y0)
    z = np.zeros(p)
    u = np.full(p, i[0])
    decay = np.empty(p)
    zc = [z_roots(P[q, 11], P[q, 10], P[q, 9]) for q in range(p)]     # once per particle
    for q in range(p):
        out[q, 0] = _initial_force(_row(P, q), x[0], v[0], y0, u[q])
    for kk in range(1, x.shape[0]):
        dt = t[kk] - t[kk - 1]
        m = substeps(dt, max_substep_s)
        h = dt / m
        dx = (x[kk] - x[kk - 1]) / m
        dv = (v[kk] - v[kk - 1]) / m
        for q in range(p):
            decay[q] = math.exp(-P[q, 12] * h)
        xs = x[kk - 1]
        vs = v[kk - 1]
        for _ in range(m):
            for q in range(p):
                y[q], z[q], u[q] = heun_substeps(z_step_rooted, zc[q], _row(P, q), y[q], z[q],
                                                 u[q], xs, vs, dx, dv, i[kk], h, decay[q], 1)
            xs = xs + dx
            vs = vs + dv
        for q in range(p):
            c0a, c0b, k0, c1a, c1b, k1, x0, aa, ab, gamma, beta, A, eta = _row(P, q)
            c0 = c0a + c0b * u[q]
            c1 = c1a + c1b * u[q]
            yd = ((aa + ab * u[q]) * z[q] + c0 * v[kk] + k0 * (x[kk] - y[q])) / (c0 + c1)
            out[q, kk] = c1 * yd + k1 * (x[kk] - x0)
    return out


def _row(P, q):
    """Row q of the (p, 13) parameter array as a tuple (for the compiled loop)."""
    return (P[q, 0], P[q, 1], P[q, 2], P[q, 3], P[q, 4], P[q, 5], P[q, 6], P[q, 7], P[q, 8],
            P[q, 9], P[q, 10], P[q, 11], P[q, 12])


def spencer_force(P, x, v, i, t, *, y0_m=None, max_substep_s=1e-4):
    """
    Spencer force for a batch of parameter sets (compiled time loop).

    The same sub-steps as :func:`spencer_force_numpy` (the reference) and the same arithmetic per
    particle as the streaming plant (``advance_scalar``); the loop is compiled by numba
    (:mod:`mr_damper_model.models.compiled`). No validation: see ``Spencer.force``.

    Parameters
    ----------
    P : numpy.ndarray with shape (p, 13)
        Parameter sets in ``SPENCER_PARAM_NAMES`` order.
    x, v, i, t : numpy.ndarray with shape (n,)
        Displacement [m], velocity [m/s], coil current [A], time [s] (strictly increasing).
    y0_m : float or None
        Initial internal displacement [m]; None: x[0].
    max_substep_s : float
        Largest sub-step [s].

    Returns
    -------
    numpy.ndarray with shape (p, n)
        Force [N].

    """
    P = np.ascontiguousarray(P, dtype=float)
    x, v, i, t = (np.ascontiguousarray(a, dtype=float) for a in (x, v, i, t))
    y0 = float(x[0] if y0_m is None else y0_m)
    out = np.empty((P.shape[0], x.size))
    helpers = ('_initial_force', '_row', 'substeps', 'heun_substeps', 'z_roots',
               'z_step_rooted')
    loop = compiled.kernel(_force_loop, helpers=helpers)
    return loop(P, x, v, i, t, y0, float(max_substep_s), out)


def spring_fit(g, x, f, lo, hi):
    """
    Least-squares spring ``k1``, ``x0`` of spring-free Spencer forces, within bounds.

    ``F = g + k1*(x - x0)``, where ``g`` is the force with k1 = x0 = 0 (``c1*ydot``): k1 and x0
    do not act on the states, so given the trajectory they are a 2-column least-squares
    problem in (k1, k1*x0). Bounds: the unconstrained optimum, k1 clipped to its box, then the
    best offset for that k1 gives x0 (clipped), then the best k1 for that x0 (clipped). Exact
    where no bound is active.

    Parameters
    ----------
    g : numpy.ndarray with shape (p, n)
        Spring-free force [N] of p parameter sets.
    x : numpy.ndarray with shape (n,)
        Displacement [m].
    f : numpy.ndarray with shape (n,)
        Measured force [N].
    lo, hi : array_like with shape (2,)
        Bounds of (k1 [N/m], x0 [m]).

    Returns
    -------
    theta : numpy.ndarray with shape (p, 2)
        (k1, x0) per parameter set.
    rss : numpy.ndarray with shape (p,)
        Residual sum of squares [N**2] with that (k1, x0).

    """
    r = f[None, :] - g
    n = x.size
    xx, sx = float(x @ x), float(np.sum(x))
    xr, sr = r @ x, np.sum(r, axis=1)
    rr = np.einsum('ij,ij->i', r, r)
    det = n * xx - sx * sx
    k1 = np.clip((n * xr - sx * sr) / det if det > 0 else np.zeros_like(sr), lo[0], hi[0])
    b = (k1 * sx - sr) / n                          # best k1*x0 for this k1
    pos = k1 > 0
    x0 = np.clip(np.where(pos, b / np.where(pos, k1, 1.0), 0.0), lo[1], hi[1])
    # best k1 for that x0: min over k1 of |r - k1*(x - x0)|**2
    sxx = xx - 2.0 * x0 * sx + n * x0 * x0          # |x - x0|**2
    sxr = xr - x0 * sr                              # (x - x0) . r
    k1 = np.where(sxx > 0, np.clip(sxr / np.where(sxx > 0, sxx, 1.0), lo[0], hi[0]), k1)
    rss = rr - 2.0 * k1 * sxr + k1 * k1 * sxx
    return np.stack([k1, x0], axis=1), rss


def spencer_force_numpy(P, x, v, i, t, *, y0_m=None, max_substep_s=1e-4):
    """
    Spencer force with numpy, vectorised over the parameter sets (reference of ``spencer_force``).

    Parameters and result as :func:`spencer_force`.
    """
    pt = tuple(np.asarray(P, dtype=float).T)
    eta = pt[12]
    p = len(pt[0])
    n = x.size
    out = np.empty((p, n))
    y0 = x[0] if y0_m is None else y0_m
    y = np.full(p, y0)
    z = np.zeros(p)
    u = np.full(p, i[0])
    out[:, 0] = _initial_force(pt, x[0], v[0], y0, u)
    c0a, c0b, k0, c1a, c1b, k1, x0, aa, ab, gamma, beta, A = pt[:12]
    for kk in range(1, n):
        dt = t[kk] - t[kk - 1]
        m = substeps(dt, max_substep_s)
        h = dt / m
        decay = np.exp(-eta * h)
        dx = (x[kk] - x[kk - 1]) / m
        dv = (v[kk] - v[kk - 1]) / m
        y, z, u = heun_substeps(z_step_array_zc, (A, beta, gamma), pt, y, z, u, x[kk - 1],
                                v[kk - 1], dx, dv, i[kk], h, decay, m)
        c0 = c0a + c0b * u
        c1 = c1a + c1b * u
        yd = ((aa + ab * u) * z + c0 * v[kk] + k0 * (x[kk] - y)) / (c0 + c1)
        out[:, kk] = c1 * yd + k1 * (x[kk] - x0)
    return out


class Spencer(HysteresisModel):
    """
    Spencer et al. (1997) modified Bouc-Wen model with coil current dependence.

    Parameters and units: c0a [N s/m], c0b [N s/(m A)], k0 [N/m], c1a [N s/m],
    c1b [N s/(m A)], k1 [N/m], x0 [m], alpha_a [N/m], alpha_b [N/(m A)], gamma [1/m**2],
    beta [1/m**2], A [-], eta [1/s]. Options: ``n`` = 2 (fixed), ``max_substep_s`` = 1e-4.
    Stateful (needs ``t``) and current-dependent (needs ``i``); no linear parameters in the
    ``regressors`` sense, but k1 and x0 do not act on the states (``spring_names``,
    :func:`spring_fit`), which the default identification uses (``identification``); the time
    loop is compiled, see ``spencer_force``.

    Default bounds (around Spencer's published damper, which is the scale of the thesis damper):
    c0a, c1a in [0, 1e5] (c0a, c1a >= 1 N s/m so c0 + c1 > 0), c0b, c1b in [0, 1e5],
    k0 in [0, 1e5], k1 in [0, 5000], x0 in [-0.2, 0.2] m, alpha_a, alpha_b in [0, 1e6],
    gamma, beta in [1e3, 1e8] and [0, 1e8] 1/m**2, A in [1, 1e4], eta in [10, 1000] 1/s.
    Unbounded: the same but x0 in [-1, 1] and the force coefficients up to ten times larger
    (the Spencer model has no sign-free parameters: negative damping would not be a damper).
    """

    name = 'spencer'
    param_names = SPENCER_PARAM_NAMES
    param_units = {'c0a': 'N s/m', 'c0b': 'N s/(m A)', 'k0': 'N/m', 'c1a': 'N s/m',
                   'c1b': 'N s/(m A)', 'k1': 'N/m', 'x0': 'm', 'alpha_a': 'N/m',
                   'alpha_b': 'N/(m A)', 'gamma': '1/m^2', 'beta': '1/m^2', 'A': '-',
                   'eta': '1/s'}
    linear_names = ()
    stateful = True
    needs_current = True
    _bounds = {'c0a': (1.0, 1e5), 'c0b': (0.0, 1e5), 'k0': (0.0, 1e5), 'c1a': (1.0, 1e5),
               'c1b': (0.0, 1e5), 'k1': (0.0, 5000.0), 'x0': (-0.2, 0.2),
               'alpha_a': (0.0, 1e6), 'alpha_b': (0.0, 1e6), 'gamma': (1e3, 1e8),
               'beta': (0.0, 1e8), 'A': (1.0, 1e4), 'eta': (10.0, 1000.0)}
    _bounds_unbounded = {'c0a': (1.0, 1e6), 'c0b': (0.0, 1e6), 'k0': (0.0, 1e6),
                         'c1a': (1.0, 1e6), 'c1b': (0.0, 1e6), 'k1': (0.0, 5e4),
                         'x0': (-1.0, 1.0), 'alpha_a': (0.0, 1e7), 'alpha_b': (0.0, 1e7),
                         'gamma': (1e3, 1e8), 'beta': (0.0, 1e8), 'A': (1.0, 1e4),
                         'eta': (10.0, 1000.0)}

    #: Parameters that do not act on the states (:func:`spring_fit`).
    spring_names = ('k1', 'x0')
    polish_by_default = True
    spring_fit = staticmethod(spring_fit)
    #: Policy of the default identification (``identify`` with method ``'separable'``): the
    #: swarm searches the 11 state parameters on the record from its start to ``swarm_span_s``
    #: after the motion begins, with sub-steps of ``swarm_max_substep_s`` (k1, x0 by
    #: :func:`spring_fit`), for ``maxiter`` iterations (stagnation ``patience``); then at most
    #: ``polish_iterations`` bounded Levenberg-Marquardt iterations on all samples with
    #: sub-steps of ``max_substep_s`` (Jacobian: one batch of 12 parameter sets). The reported
    #: metrics use the model's own sub-step; a coarser one of the model itself is kept.
    identification = {'swarm_span_s': 5.0, 'swarm_max_substep_s': 1e-3, 'maxiter': 20,
                      'patience': 10, 'max_substep_s': 5e-4, 'polish_iterations': 30}

    def __init__(self, n=2, max_substep_s=1e-4, y0_m=None):
        if n != 2:
            raise ModelError('spencer: only n = 2 is implemented (exact z update)')
        max_substep_s = float(max_substep_s)
        if not max_substep_s > 0:
            raise ModelError(f'`max_substep_s` must be positive, got {max_substep_s}')
        if y0_m is not None:
            y0_m = float(y0_m)
            if not math.isfinite(y0_m):
                raise ModelError('`y0_m` must be finite')
        self.options = {'n': 2, 'max_substep_s': max_substep_s, 'y0_m': y0_m}

    def _check(self, P):
        q = self._split(P)
        bad = ((q['A'] <= 0) | (q['gamma'] < 0) | (q['beta'] + q['gamma'] <= 0)
               | (q['eta'] <= 0) | (q['c0a'] + q['c1a'] <= 0))
        if np.any(bad):
            raise ModelError('spencer needs A > 0, gamma >= 0, beta + gamma > 0, eta > 0, '
                             'c0a + c1a > 0')

    def for_identification(self, max_substep_s):
        """Return this model with sub-steps of at most ``max(max_substep_s, own)`` [s]."""
        return Spencer(max_substep_s=max(float(max_substep_s), self.options['max_substep_s']),
                       y0_m=self.options['y0_m'])

    def _jacobian(self, p, x, v, i, t):
        """
        Forward differences of the state parameters in one batch; k1, x0 analytic.

        The base parameter set and the 11 perturbed ones (steps as the base class takes them)
        are one call of the compiled loop.
        """
        names = self.param_names
        ks, kx = names.index('k1'), names.index('x0')
        J = self._fd_jacobian(p, x, v, i, t,
                              cols=[j for j in range(len(names)) if j not in (ks, kx)])
        J[:, ks] = x - p[kx]
        J[:, kx] = -p[ks]
        return J

    def _force(self, P, x, v, i, t):
        self._check(P)
        return spencer_force(P, x, v, i, t, y0_m=self.options['y0_m'],
                             max_substep_s=self.options['max_substep_s'])
