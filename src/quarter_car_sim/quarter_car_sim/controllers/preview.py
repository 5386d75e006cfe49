"""
LQ preview: today's LQR law plus the optimal feedforward on the road ahead (issue 36).

The design (:func:`lq_preview`) is the continuous-time LQ problem of the LQR laws with the road
as a known exogenous input over a preview horizon ``T``::

    X' = A X + B u + Gv zdot_r + Gh z_r
    J  = integral( X'QX + 2 X'N u + u'R u + 2 X'(Sxv zdot_r + Sxh z_r)
                   + 2 u'(Suv zdot_r + Suh z_r) ) dt

(``z_r`` the road heights under the wheels; ``Gh``, ``S..h`` only where a road height itself
acts, e.g. the full car's road warp, which no force changes). With the Riccati solution ``P``
of the LQR (``K = R^-1 (B'P + N')``, ``Ac = A - B K``) the optimal control is ::

    u(t) = -K X(t) - R^-1 ( B' g(t) + Suv zdot_r(t) + Suh z_r(t) )
    g(t) = integral_0^inf exp(Ac' s) ( Mv zdot_r(t+s) + Mh z_r(t+s) ) ds
    Mv = P Gv + Sxv - K' Suv,   Mh = P Gh + Sxh - K' Suh

(the costate's affine part). The road is known on ``[t, t + T]`` as heights at the times
``t + j h`` (piecewise linear in between) and held after ``t + T`` (zero road velocity: what a
law without preview assumes, so ``T = 0`` gives back the LQR law exactly). The integral is then
exact as a FIR on the heights: ``u_ff(t) = sum_j taps[j] z_r(t + j h)``, the taps from the
matrix exponentials of ``Ac'`` over one step (``int exp(Ac' s) ds`` and ``int exp(Ac' s) s ds``
by one block exponential, Van Loan). A law adds ``u_ff`` to the LQR force before the damper clip
(the force still goes through the corner's inverse and supervisor).

Only height differences enter (a tap sum of zero on each wheel where no height acts by
itself), so a common height offset of the previewed road does not change the feedforward.

The quarter car's law is :class:`ClippedOptimalWkPreview`: ``clipped-optimal-wk`` plus the
feedforward on the road ahead of the wheel from a :class:`~quarter_car_sim.road_preview.
RoadPreview`; without a valid preview window it is ``clipped-optimal-wk`` and the fallback is
counted.
"""
import dataclasses
import math

import numpy as np
from scipy.linalg import expm, solve, solve_continuous_are

from quarter_car_sim.controllers.base import clip_to_damper, Controller

#: Default preview horizon [s] and spacing of the previewed heights [s] of the preview laws.
DEFAULT_PREVIEW_HORIZON_S = 0.3
DEFAULT_PREVIEW_STEP_S = 1e-3


@dataclasses.dataclass
class LqPreview:
    """
    Result of :func:`lq_preview`.

    Attributes
    ----------
    gain : ndarray with shape (m, n)
        LQR gain ``K`` (feedback ``-K X``).
    P : ndarray with shape (n, n)
        Riccati solution.
    taps : ndarray with shape (p + 1, m, w)
        Feedforward per preview sample: ``u_ff = sum_j taps[j] @ z_r(t + j h)`` [N per m].
    step_s : float
        Preview sample spacing ``h`` [s].
    horizon_s : float
        Preview horizon ``T = p h`` [s].

    """

    gain: np.ndarray
    P: np.ndarray
    taps: np.ndarray
    step_s: float
    horizon_s: float

    @property
    def times_s(self):
        """Preview sample times ahead ``j h`` [s], shape (p + 1,)."""
        return np.arange(self.taps.shape[0]) * self.step_s

    def feedforward(self, heights):
        """Return ``u_ff`` [N] of road heights ``heights`` with shape (p + 1, w) [m]."""
        return np.einsum('jmw,jw->m', self.taps, heights)


def _zeros_like(mat, shape):
    return np.zeros(shape) if mat is None else np.asarray(mat, dtype=float).reshape(shape)


def lq_preview(A, B, Q, R, N, Gv, *, Gh=None, Sxv=None, Sxh=None, Suv=None, Suh=None,
               horizon_s, step_s):
    """
    LQ preview design: the LQR gain and the FIR feedforward on the previewed road.

    Parameters
    ----------
    A, B : ndarray with shapes (n, n), (n, m)
        Design model ``X' = A X + B u + ...``.
    Q, R, N : ndarray with shapes (n, n), (m, m), (n, m)
        LQR weights ``X'QX + 2X'Nu + u'Ru``.
    Gv : ndarray with shape (n, w)
        Input of the road velocities under the ``w`` wheels [per m/s].
    Gh, Sxv, Sxh, Suv, Suh : ndarray, optional
        Input of the road heights (n, w) and the cost's cross terms of the state (n, w) and of
        the control (m, w) with road velocities and heights (zero when not given).
    horizon_s : float
        Preview horizon ``T`` [s] (0: no feedforward).
    step_s : float
        Spacing of the previewed heights [s].

    Returns
    -------
    LqPreview

    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    n, m = B.shape
    Gv = np.asarray(Gv, float).reshape(n, -1)
    w = Gv.shape[1]
    Gh = _zeros_like(Gh, (n, w))
    Sxv, Sxh = _zeros_like(Sxv, (n, w)), _zeros_like(Sxh, (n, w))
    Suv, Suh = _zeros_like(Suv, (m, w)), _zeros_like(Suh, (m, w))
    h = float(step_s)
    T = float(horizon_s)
    if not (math.isfinite(h) and h > 0.0):
        raise ValueError(f'`step_s` must be > 0, got {step_s}')
    if not (math.isfinite(T) and T >= 0.0):
        raise ValueError(f'`horizon_s` must be >= 0, got {horizon_s}')
    p = int(round(T / h))
    Q, R, N = np.asarray(Q, float), np.asarray(R, float), np.asarray(N, float).reshape(n, m)
    P = solve_continuous_are(A, B, 0.5 * (Q + Q.T), 0.5 * (R + R.T), s=N)
    K = solve(R, B.T @ P + N.T)
    taps = np.zeros((p + 1, m, w))
    if p == 0:
        return LqPreview(gain=K, P=P, taps=taps, step_s=h, horizon_s=0.0)
    Ac_t = (A - B @ K).T
    Mv = P @ Gv + Sxv - K.T @ Suv
    Mh = P @ Gh + Sxh - K.T @ Suh
    big = np.zeros((3 * n, 3 * n))
    big[:n, :n] = Ac_t * h
    big[:n, n:2 * n] = np.eye(n) * h
    big[n:2 * n, 2 * n:] = np.eye(n) * h
    E = expm(big)
    step = E[:n, :n]                                   # exp(Ac' h)
    phi1 = E[:n, n:2 * n]                              # int_0^h exp(Ac' s) ds
    psi = h * phi1 - E[:n, 2 * n:]                     # int_0^h exp(Ac' s) s ds
    on_next = (phi1 @ Mv + psi @ Mh) / h               # per interval: z_{j+1} ...
    on_this = phi1 @ Mh - on_next                      # ... and z_j
    rinv = -np.linalg.inv(R)
    L = rinv @ B.T                                     # -R^-1 B' exp(Ac' j h)
    for j in range(p):
        taps[j] += L @ on_this
        taps[j + 1] += L @ on_next
        L = L @ step
    # after the horizon the road is held at z_p: int_T^inf exp(Ac' s) ds Mh z_p
    taps[p] += L @ solve(-Ac_t, Mh)
    # the present road velocity and height in the cost's cross terms
    taps[0] += rinv @ (Suh - Suv / h)
    taps[1] += rinv @ Suv / h
    return LqPreview(gain=K, P=P, taps=taps, step_s=h, horizon_s=p * h)


def quarter_car_road_input(params, n_states):
    """
    Road-velocity input ``Gv`` (n, 1) of a quarter-car LQR design model with ``n_states``.

    The car of :func:`quarter_car_sim.linear_analysis.linear_model` (its ``zdot_r`` column),
    zero on the weighting filter's states (the body acceleration does not depend on it).
    """
    from quarter_car_sim.linear_analysis import linear_model
    g = np.zeros((int(n_states), 1))
    g[:4, 0] = np.asarray(linear_model(params).B)[:, 0]
    return g


def quarter_car_lq_preview(design, params, horizon_s, step_s=1e-3):
    """
    LQ preview of a quarter-car LQR design, one wheel.

    Parameters
    ----------
    design : quarter_car_sim.linear_analysis.LqrDesign
        Design (its model ``A``, ``B`` and weights ``Q``, ``R``, ``N``), e.g.
        :func:`~quarter_car_sim.controllers.optimal.wk_lqr_design`.
    params : QuarterCarParams
        The car it was designed on.
    horizon_s, step_s : float
        Preview horizon and sample spacing [s].

    Returns
    -------
    LqPreview
        ``taps`` with shape (p + 1, 1, 1); ``gain`` equals ``design.gain``.

    """
    n = np.asarray(design.A).shape[0]
    return lq_preview(design.A, design.B, design.Q, design.R, design.N,
                      quarter_car_road_input(params, n), horizon_s=horizon_s, step_s=step_s)


class PreviewStats:
    """Counters of a preview law: steps with and without a valid window, dropouts."""

    def __init__(self):
        self.reset()

    def reset(self):
        """Zero the counters."""
        self.steps = self.previewed = self.fallback_steps = self.dropouts = 0
        self._last_ok = True

    def count(self, ok):
        """Count one step (``ok``: the window was valid)."""
        self.steps += 1
        if ok:
            self.previewed += 1
        else:
            self.fallback_steps += 1
            if self._last_ok:
                self.dropouts += 1
        self._last_ok = ok

    def as_dict(self):
        """Return the counters (JSON-ready)."""
        return {'steps': self.steps, 'previewed_steps': self.previewed,
                'fallback_steps': self.fallback_steps, 'dropouts': self.dropouts}


class ClippedOptimalWkPreview(Controller):
    """
    ``clipped-optimal-wk`` with LQ preview: the Wk LQR force plus the road feedforward, clipped.

    Each step the law asks its road preview for the heights under the wheel at the times of the
    design's taps; with a window, ``F = -K X + sum_j taps[j] z_r(t + j h)``, else (a dropout,
    no speed signal yet) the law without preview, counted in ``stats``. The demand is clipped
    like ``clipped-optimal-wk`` (damper range, dissipative), then the loop's inverse and
    supervisor make the current.

    Parameters
    ----------
    base : quarter_car_sim.controllers.optimal.ClippedOptimalWk
        The law without preview (its filter and gain; its design is the preview's).
    preview : LqPreview
        Feedforward taps (:func:`quarter_car_lq_preview` of ``base.design``).
    road : quarter_car_sim.road_preview.RoadPreview
        What the car knows of the road (one track, one wheel at 0); the node or the offline
        loop feeds it speed and frames.
    name : str
        Law name.

    """

    state_fields = ('z_u', 'z_r')

    def __init__(self, base, preview, road, name='clipped-optimal-wk-preview'):
        if np.asarray(preview.taps).shape[1:] != (1, 1):
            raise ValueError('`preview` must be a one-wheel design (taps (p + 1, 1, 1))')
        self.base, self.preview, self.road, self.name = base, preview, road, name
        self.force_range = base.force_range
        self._times = preview.times_s
        self._taps = np.asarray(preview.taps)[:, 0, 0]
        self.stats = PreviewStats()
        self.last_feedforward = 0.0

    def reset(self):
        """Clear the base law's filter, the road preview and the counters."""
        self.base.reset()
        self.road.reset()
        self.stats.reset()
        self.last_feedforward = 0.0

    def feedforward(self):
        """Return the feedforward [N] of the present window, or None without one."""
        if self._taps.size == 1 and not self._taps.any():
            return 0.0
        z = self.road.window(self._times)
        if z is None:
            return None
        return float(self._taps @ z[:, 0])

    def desired(self, state):
        """Unclipped force [N]: the base law's plus the feedforward (steps the filter)."""
        f = self.base.desired(state)
        ff = self.feedforward()
        self.stats.count(ff is not None)
        self.last_feedforward = 0.0 if ff is None else ff
        return f + self.last_feedforward

    def demand(self, state):
        """Desired damper force on the body [N], clipped to the damper (dissipative)."""
        return clip_to_damper(self.desired(state), state, self.force_range)
