"""
Inverse current-dependent Kwok model: desired force -> coil current.

At fixed (x, v) the force F(i) of ``KwokCurrent`` is a smooth function of the current. Method
(vectorised over samples):

1. Pre-scan: F on a grid of ``n_grid`` (33) currents over [i_min, i_max].
2. If the desired force lies between two neighbouring grid forces (the first such interval from
   i_min), the sample is reachable: the root is solved in that bracket, in closed form when
   beta1 == 0 (F is then a quadratic in s = i/i_ref_a) and otherwise by the Illinois
   (modified regula falsi) method, all samples at once, to |F - f_des| <= 1e-9*(1 + |f_des|)
   N or a bracket narrower than ``tol_a``.
3. Otherwise it is not reachable and the grid current whose force is nearest f_des is returned:
   for the usual monotone F(i) that is i_min (``saturated_low``: less force than the minimum
   current makes, including a force of the wrong sign for the motion, which a semi-active damper
   cannot make) or i_max (``saturated_high``: more than the maximum current makes). If F(i) is
   not monotone, a dense local grid (65 points over the two grid cells around the nearest grid
   point) is scanned as well, so a narrow extremum that the coarse grid stepped over is found
   (then the sample is reachable after all, or its nearest force is taken from the dense grid);
   a nearest force at an interior current sets neither flag.
"""
from dataclasses import dataclass
import math

import numpy as np

from mr_damper_model.models.kwok_current import KwokCurrent, kwok_current_coefficients
from mr_damper_model.models import ModelError
from mr_damper_model.models.scalar_inverse import (lagged_velocity, MAX_ITER, N_DENSE, Q_DT,
                                                   Q_LAG, Q_N, Q_TAU0, Q_TAU1, Q_U_PREV,
                                                   scalar_kernels)

_N_GRID = 33


@dataclass
class InverseResult:
    """
    Result of ``inverse_current``.

    Attributes
    ----------
    current : numpy.ndarray
        Coil current [A], within [i_min, i_max].
    force : numpy.ndarray
        Model force at that current [N] (what the damper will make).
    reachable : numpy.ndarray of bool
        The desired force is achievable within the current range.
    saturated_low : numpy.ndarray of bool
        Wanted less than the i_min force (incl. wrong sign); current = i_min.
    saturated_high : numpy.ndarray of bool
        Wanted more than the i_max force; current = i_max.

    """

    current: np.ndarray
    force: np.ndarray
    reachable: np.ndarray
    saturated_low: np.ndarray
    saturated_high: np.ndarray


def _param_vector(params):
    model = KwokCurrent()
    if isinstance(params, dict):
        return model.from_dict(params)
    arr = np.asarray(params, dtype=float).ravel()
    if arr.size != model.n_params:
        raise ModelError(f'`params` must have {model.n_params} values '
                         f'({", ".join(model.param_names)}), got {arr.size}')
    if not np.all(np.isfinite(arr)):
        raise ModelError('`params` contains NaN or inf')
    return arr


def _force(p, s, x, v, sx):
    """Kwok-current force at normalised current s (elementwise, broadcasting)."""
    s = np.asarray(s, dtype=float)
    terms = kwok_current_coefficients(p[None, :], s if s.ndim == 2 else s.reshape(1, -1))
    c, alpha, beta = (t if s.ndim == 2 else t.reshape(s.shape) for t in terms)
    return c * v + p[2] * x + alpha * np.tanh(beta * v + p[8] * sx) + p[9]


def inverse_current(f_des, x, v, params, *, i_ref_a=2.0, i_min=0.0, i_max=2.0, tol_a=1e-6):
    """
    Coil current that makes the current-dependent Kwok damper produce a desired force.

    Parameters
    ----------
    f_des : array_like with shape (n,) or scalar
        Desired damper force [N].
    x : array_like with shape (n,) or scalar
        Piston displacement [m].
    v : array_like with shape (n,) or scalar
        Piston velocity [m/s].
    params : dict or array_like with shape (10,)
        KwokCurrent parameters (``KwokCurrent.param_names``).
    i_ref_a : float
        Reference current of the model [A].
    i_min, i_max : float
        Current range [A], i_min < i_max.
    tol_a : float
        Bracket tolerance of the root finder [A] (the force residual is usually far smaller).

    Returns
    -------
    InverseResult
        Arrays of the broadcast shape of the inputs (1-D).

    Raises
    ------
    ModelError
        NaN/inf inputs, bad current range or tolerance.

    """
    p = _param_vector(params)
    for name, val in (('i_ref_a', i_ref_a), ('i_min', i_min), ('i_max', i_max),
                      ('tol_a', tol_a)):
        if not math.isfinite(float(val)):
            raise ModelError(f'`{name}` must be finite, got {val}')
    if not i_ref_a > 0:
        raise ModelError(f'`i_ref_a` must be positive, got {i_ref_a}')
    if not i_max > i_min:
        raise ModelError(f'`i_max` ({i_max}) must be larger than `i_min` ({i_min})')
    if not tol_a > 0:
        raise ModelError(f'`tol_a` must be positive, got {tol_a}')
    arrs = []
    for name, a in (('f_des', f_des), ('x', x), ('v', v)):
        a = np.atleast_1d(np.asarray(a, dtype=float))
        if not np.all(np.isfinite(a)):
            raise ModelError(f'`{name}` contains NaN or inf')
        arrs.append(a)
    try:
        f, x, v = (a.ravel() for a in np.broadcast_arrays(*arrs))
    except ValueError as exc:
        raise ModelError(f'`f_des`, `x`, `v` shapes do not broadcast: {exc}') from None
    n = f.size
    sx = np.sign(x)
    s_lo, s_hi = i_min / i_ref_a, i_max / i_ref_a
    sg = np.linspace(s_lo, s_hi, _N_GRID)
    fg = _force(p, sg[None, :], x[:, None], v[:, None], sx[:, None])
    d = fg - f[:, None]
    cross = (d[:, :-1] * d[:, 1:]) <= 0.0
    reachable = cross.any(axis=1)
    j = np.argmax(cross, axis=1)
    rows = np.arange(n)
    s_out = np.empty(n)
    # unreachable: nearest grid force
    jn = np.argmin(np.abs(d), axis=1)
    s_out[:] = sg[jn]
    sat_low = ~reachable & (jn == 0)
    sat_high = ~reachable & (jn == _N_GRID - 1)
    a_all = sg[j]
    b_all = sg[np.minimum(j + 1, _N_GRID - 1)]
    fa_all = d[rows, j]
    fb_all = d[rows, np.minimum(j + 1, _N_GRID - 1)]
    # second pass for the unreachable: a dense local grid around the nearest grid point finds
    # a narrow bump of a non-monotone F(i) that the coarse grid stepped over
    far = np.flatnonzero(~reachable)
    if far.size:
        lo_ = sg[np.maximum(jn[far] - 1, 0)]
        hi_ = sg[np.minimum(jn[far] + 1, _N_GRID - 1)]
        sl = lo_[:, None] + (hi_ - lo_)[:, None] * np.linspace(0.0, 1.0, 65)[None, :]
        dl = _force(p, sl, x[far, None], v[far, None], sx[far, None]) - f[far, None]
        cl = (dl[:, :-1] * dl[:, 1:]) <= 0.0
        hit = cl.any(axis=1)
        jl = np.argmax(cl, axis=1)
        rl = np.arange(far.size)
        kn = np.argmin(np.abs(dl), axis=1)
        better = np.abs(dl[rl, kn]) < np.abs(d[far, jn[far]])
        s_out[far] = np.where(better, sl[rl, kn], s_out[far])
        sat_low[far] &= ~hit & ~(better & (sl[rl, kn] > s_lo))
        sat_high[far] &= ~hit & ~(better & (sl[rl, kn] < s_hi))
        reachable[far] = hit
        h = far[hit]
        a_all[h] = sl[hit, jl[hit]]
        b_all[h] = sl[hit, jl[hit] + 1]
        fa_all[h] = dl[hit, jl[hit]]
        fb_all[h] = dl[hit, jl[hit] + 1]
    idx = np.flatnonzero(reachable)
    if idx.size:
        a, b, fa, fb = a_all[idx], b_all[idx], fa_all[idx], fb_all[idx]
        s_out[idx] = _solve(p, a, b, fa, fb, f[idx], x[idx], v[idx], sx[idx],
                            tol_a / i_ref_a)
    force = _force(p, s_out, x, v, sx)
    return InverseResult(current=np.clip(s_out * i_ref_a, i_min, i_max), force=force,
                         reachable=reachable, saturated_low=sat_low, saturated_high=sat_high)


def _solve(p, a, b, fa, fb, f, x, v, sx, tol_s):
    """Root of F(s) = f in the brackets [a, b] (fa, fb: residuals at the ends)."""
    c0, c1, k, a0, a1, a2, b0, b1, delta, f0 = p
    if b1 == 0.0:
        T = np.tanh(b0 * v + delta * sx)
        q2 = (a2 - a1) * T
        q1 = c1 * v + 2.0 * a1 * T
        q0 = c0 * v + a0 * T + k * x + f0 - f
        s = _quadratic_root_in(q2, q1, q0, a, b)
        ok = np.isfinite(s)
        if np.all(ok):
            return s
        out = np.where(ok, s, 0.0)
        bad = ~ok
        out[bad] = _illinois(p, a[bad], b[bad], fa[bad], fb[bad], f[bad], x[bad], v[bad],
                             sx[bad], tol_s)
        return out
    return _illinois(p, a, b, fa, fb, f, x, v, sx, tol_s)


def _quadratic_root_in(q2, q1, q0, a, b):
    """Root of q2 s^2 + q1 s + q0 inside [a, b] (NaN where none is found)."""
    span = b - a
    lo, hi = a - 1e-9 * span, b + 1e-9 * span
    out = np.full(a.shape, np.nan)
    scale = np.abs(q1) + np.abs(q0) + 1e-300
    lin = np.abs(q2) * np.maximum(np.abs(a), np.abs(b)) ** 2 <= 1e-13 * scale
    with np.errstate(divide='ignore', invalid='ignore'):
        r_lin = np.where(q1 != 0.0, -q0 / np.where(q1 != 0.0, q1, 1.0), np.nan)
    disc = q1 * q1 - 4.0 * q2 * q0
    sq = np.sqrt(np.maximum(disc, 0.0))
    qq = -0.5 * (q1 + np.where(q1 >= 0.0, sq, -sq))
    safe_q2 = np.where(q2 != 0.0, q2, 1.0)
    safe_qq = np.where(qq != 0.0, qq, 1.0)
    r1 = np.where(q2 != 0.0, qq / safe_q2, np.nan)
    r2 = np.where(qq != 0.0, q0 / safe_qq, np.nan)
    for r in (r2, r1):
        good = ~lin & (disc >= 0.0) & np.isfinite(r) & (r >= lo) & (r <= hi)
        out = np.where(good & np.isnan(out), r, out)
    good = lin & np.isfinite(r_lin) & (r_lin >= lo) & (r_lin <= hi)
    out = np.where(good, r_lin, out)
    return np.clip(out, a, b)


def _illinois(p, a, b, fa, fb, f, x, v, sx, tol_s):
    """Vectorised Illinois iteration; returns the last iterate."""
    ftol = 1e-9 * (1.0 + np.abs(f))
    at_a = fa == 0.0
    b = np.where(at_a, a, b)
    fb = np.where(at_a, 0.0, fb)
    for _ in range(MAX_ITER):
        done = (np.abs(fb) <= ftol) | (np.abs(b - a) <= tol_s * 1e-6)
        if np.all(done):
            break
        denom = fb - fa
        c = np.where(denom != 0.0, b - fb * (b - a) / np.where(denom != 0.0, denom, 1.0),
                     0.5 * (a + b))
        lo_, hi_ = np.minimum(a, b), np.maximum(a, b)
        c = np.where((c > lo_) & (c < hi_), c, 0.5 * (a + b))
        fc = _force(p, c, x, v, sx) - f
        swap = fc * fb < 0.0
        a = np.where(done, a, np.where(swap, b, a))
        fa = np.where(done, fa, np.where(swap, fb, 0.5 * fa))
        b = np.where(done, b, c)
        fb = np.where(done, fb, fc)
    return b


class KwokCurrentInverse:
    """
    Scalar inverse for 1 kHz control loops (same answers as ``inverse_current``), compiled.

    The algorithm is :func:`scalar_current` (plain functions over floats, compiled with numba
    by :func:`scalar_kernels`: a call costs microseconds, not the tens an interpreted one did).

    Fast path first: the forces at the two ends of the current range bracket the demand
    (Illinois regula falsi between them: reachable, flag 0). Otherwise the demand is beyond
    both end forces, and the slopes dF/di at the ends
    (``mr_damper_model.models.kwok_current.kwok_current_force_slope_at``) say whether F(i) turns
    inside the range: running away from the demand at both ends (monotone), the nearest end
    saturates (flag -1 at ``i_min``, +1 at ``i_max``); with one interior extremum, it is found
    (Illinois on the slope) and either brackets the demand (solved, flag 0) or is the nearest
    force (flag +-1). Only F(i) with two interior extrema is pre-scanned on a grid, as
    ``inverse_current`` does. The one scalar inverse of the suite: the car's control loop uses
    it with ``sign_convention='body'``.

    Parameters
    ----------
    params : dict or array_like with shape (10,)
        KwokCurrent parameters.
    i_ref_a, i_min, i_max : float
        As in ``inverse_current`` [A].
    n_grid : int
        Pre-scan grid size for non-monotone F(i) (default 9).
    tol_a : float or None
        Stop the root search when the bracket is narrower than this [A]; None: only when the
        force matches to 1e-9 relative.
    sign_convention : {'model', 'body'}
        Sign of the demand given to :meth:`current`: ``'model'`` the damper model's force
        (resisting extension positive); ``'body'`` the damper force on a vehicle body, positive
        up, which is the negative of the model force (``x``, ``v`` are then the suspension
        travel and velocity, extension positive).

    Attributes
    ----------
    params : dict
        The parameters by name (``KwokCurrent.param_names``, float).

    """

    def __init__(self, params, *, i_ref_a=2.0, i_min=0.0, i_max=2.0, n_grid=9, tol_a=None,
                 sign_convention='model'):
        p = _param_vector(params)
        if not (i_ref_a > 0 and i_max > i_min):
            raise ModelError('need `i_ref_a` > 0 and `i_max` > `i_min`')
        if sign_convention not in ('model', 'body'):
            raise ModelError(f"`sign_convention` must be 'model' or 'body', "
                             f'got {sign_convention!r}')
        self.sign_convention = sign_convention
        self._body = sign_convention == 'body'
        self._p = tuple(float(q) for q in p)
        self.params = dict(zip(KwokCurrent.param_names, self._p))
        self.i_ref_a, self.i_min, self.i_max = float(i_ref_a), float(i_min), float(i_max)
        self._s_lo, self._s_hi = self.i_min / self.i_ref_a, self.i_max / self.i_ref_a
        tol_s = 1e-12 if tol_a is None else max(float(tol_a) / self.i_ref_a, 1e-12)
        self._q = np.zeros(Q_N)
        self._q[:10] = self._p
        self._lim = np.array([self._s_lo, self._s_hi, self.i_ref_a, self.i_min, self.i_max,
                              tol_s])
        self._grid = np.array([(i_min + (i_max - i_min) * j / (n_grid - 1)) / i_ref_a
                               for j in range(n_grid)])
        self._dense = np.zeros(0)
        self._kernels = scalar_kernels()

    def kernel_arguments(self):
        """
        Return copies of what the scalar kernel takes: ``(q, lim, grid)``.

        The model vector, the range vector and the pre-scan grid of
        :func:`mr_damper_model.models.scalar_inverse.scalar_current` (its arguments before the
        dense scratch), e.g. to run that algorithm interpreted beside the compiled one.
        """
        return self._q.copy(), self._lim.copy(), self._grid.copy()

    def force(self, i, x, v):
        """Model force [N] at current i [A], displacement x [m], velocity v [m/s]."""
        return self._kernels[1](self._q, float(i) / self.i_ref_a, float(x), float(v))

    def body_force_range(self, travel, v_rel):
        """
        Damper forces on the body [N] the model can make at this travel and velocity.

        Parameters
        ----------
        travel, v_rel : float
            Suspension travel [m] and velocity [m/s] (piston displacement and velocity).

        Returns
        -------
        lo, hi : float
            Smallest and largest of ``-force`` at ``i_min`` and ``i_max`` [N].

        """
        f = self._kernels[1]
        x, v = float(travel), float(v_rel)
        a, b = -f(self._q, self._s_lo, x, v), -f(self._q, self._s_hi, x, v)
        return (a, b) if a <= b else (b, a)

    def current(self, f_des, x, v):
        """
        Return ``(current [A], flag)``: flag 0 reachable, -1 saturated low, +1 saturated high.

        A demand out of reach gets the current of the nearest achievable force; the flag says
        whether the demand was below (-1) or above (+1) that force, in the sign of
        ``sign_convention`` (model convention: -1 includes the wrong sign for the motion,
        which a semi-active damper cannot make). Only a reachable demand has flag 0.

        Parameters
        ----------
        f_des : float
            Desired force [N] (model force, or force on the body with ``'body'``).
        x : float
            Displacement (suspension travel) [m].
        v : float
            Velocity [m/s].

        Returns
        -------
        tuple of (float, int)

        """
        f_des, x, v = float(f_des), float(x), float(v)
        if not (math.isfinite(f_des) and math.isfinite(x) and math.isfinite(v)):
            raise ModelError('`f_des`, `x`, `v` must be finite')
        if self._body:
            cur, flag = self._kernels[0](self._q, self._lim, self._grid, self._dense, -f_des,
                                         x, v)
            return cur, -flag
        cur, flag = self._kernels[0](self._q, self._lim, self._grid, self._dense, f_des, x, v)
        return cur, int(flag)


class KwokCurrentLagInverse(KwokCurrentInverse):
    """
    Scalar inverse of ``kwok-current-lag`` for a control loop, one sample at a time.

    The model's lagged velocity ``u`` is a state: at each sample, with the previous ``u`` and
    the sample interval dt, ``u(i) = a(i)*u_prev + (1 - a(i))*v`` with
    ``a(i) = exp(-dt/(tau0 + tau1*s))``, and the force is the kwok-current force with ``u``
    in the tanh (``c(i)*v`` stays on the piston velocity). :meth:`step` solves that force for
    the current exactly as :class:`KwokCurrentInverse` does, then advances ``u`` with the
    current it returns; the first call starts at rest (``u = v``, as the model's first sample).
    Near a velocity reversal the lag can make F(i) rise and fall over the range (u changes
    sign with i), with a narrow peak that the end-point test and the coarse grid step over: a
    demand found out of reach is checked once more on a dense grid (:data:`N_DENSE` points)
    before the current saturates.

    Parameters
    ----------
    params : dict or array_like with shape (12,)
        KwokCurrentLag parameters (``KwokCurrentLag.param_names``).
    i_ref_a, i_min, i_max, n_grid, tol_a, sign_convention
        As in :class:`KwokCurrentInverse`.

    """

    def __init__(self, params, *, i_ref_a=2.0, i_min=0.0, i_max=2.0, n_grid=9, tol_a=None,
                 sign_convention='model'):
        # lazy: scipy.signal, which the car's controller need not load for the plain inverse
        from mr_damper_model.models.kwok_current_lag import KwokCurrentLag
        model = KwokCurrentLag()
        if isinstance(params, dict):
            p = model.from_dict(params)
        else:
            p = np.asarray(params, dtype=float).ravel()
            if p.size != model.n_params or not np.all(np.isfinite(p)):
                raise ModelError(f'`params` must have {model.n_params} finite values '
                                 f'({", ".join(model.param_names)})')
        if p[10] < 0 or p[11] < 0:
            raise ModelError('lag time constants `tau0`, `tau1` must be >= 0')
        super().__init__(p[:10], i_ref_a=i_ref_a, i_min=i_min, i_max=i_max, n_grid=n_grid,
                         tol_a=tol_a, sign_convention=sign_convention)
        self._q[Q_TAU0], self._q[Q_TAU1], self._q[Q_LAG] = float(p[10]), float(p[11]), 1.0
        self._dense = np.array([(self.i_min + (self.i_max - self.i_min) * j / (N_DENSE - 1))
                                / self.i_ref_a for j in range(N_DENSE)])
        self.u = None           # lagged velocity after the last step [m/s]

    def step(self, f_des, x, v, dt):
        """
        Return ``(current [A], flag)`` for one sample and advance the lag state.

        Parameters
        ----------
        f_des, x, v : float
            Desired force [N], displacement [m], velocity [m/s], as in :meth:`current`.
        dt : float
            Time since the previous sample [s] (ignored at the first call).

        Returns
        -------
        tuple of (float, int)
            As :meth:`KwokCurrentInverse.current`.

        """
        if not (math.isfinite(dt) and dt > 0):
            raise ModelError(f'`dt` must be a positive time step [s], got {dt}')
        q = self._q
        if self.u is None:
            q[Q_U_PREV], q[Q_DT] = float(v), 0.0      # first sample: u = v
        else:
            q[Q_U_PREV], q[Q_DT] = self.u, float(dt)
        cur, flag = self.current(f_des, x, v)
        self.u = float(lagged_velocity(q, cur / self.i_ref_a, float(v)))
        return cur, flag
