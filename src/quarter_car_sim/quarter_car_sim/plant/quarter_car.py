"""
Quarter-car dynamics: linear state-space model and the stepwise nonlinear simulator.

State ``[z_s, v_s, z_u, v_u]`` relative to the static equilibrium on a flat road (see
:mod:`semi_active_control.car.quarter_car` for the sign conventions)::

    m_s a_s = -k_s (z_s - z_u) - c_s (v_s - v_u) + F_d
    m_u a_u = +k_s (z_s - z_u) + c_s (v_s - v_u) - F_d + F_t - W
    F_t = max(0, W + k_t (z_r - z_u) + c_t (zdot_r - v_u))      (tyre cannot pull)

with ``F_d`` the damper force on the body and ``W = (m_s + m_u) g`` the static tyre load.

Integration (:class:`QuarterCar`): the linear 4-state part is advanced **exactly** (matrix
exponential, computed once per step size) with the road height linearly interpolated over the
step (first-order hold, the convention of ``control.forced_response``), the tyre in contact or
airborne as decided at the start of each (sub)step, and the damper force held over the (sub)step
(zero-order hold). The damper plant is then stepped to the end-of-step piston position and
velocity and returns the force for the next (sub)step. Each control step can be split into
``substeps`` for stiff damper characteristics; per-step work is plain Python floats.
"""
import math

import numpy as np
from scipy.linalg import expm

from mr_damper_common.contract import CornerState
from semi_active_control.car.quarter_car import QuarterCarParams


def state_matrices(params, *, contact=True):
    """
    Continuous-time matrices of the linear quarter car (no damper plant, ``c_s`` included).

    Parameters
    ----------
    params : QuarterCarParams
        Car parameters.
    contact : bool
        Tyre in contact (True) or airborne (False: no tyre force, weight acts on the wheel).

    Returns
    -------
    A : ndarray with shape (4, 4)
        State matrix for ``[z_s, v_s, z_u, v_u]``.
    B : ndarray with shape (4, 4)
        Input matrix for ``[z_r, zdot_r, F_d, 1]`` (road height [m], road velocity [m/s], damper
        force on the body [N], constant unit input carrying -W when airborne).

    """
    p = params
    ms, mu, ks, cs = p.m_s, p.m_u, p.k_s, p.c_s
    kt, ct = (p.k_t, p.c_t) if contact else (0.0, 0.0)
    A = np.array([
        [0.0, 1.0, 0.0, 0.0],
        [-ks / ms, -cs / ms, ks / ms, cs / ms],
        [0.0, 0.0, 0.0, 1.0],
        [ks / mu, cs / mu, -(ks + kt) / mu, -(cs + ct) / mu],
    ])
    B = np.zeros((4, 4))
    B[1, 2] = 1.0 / ms
    B[3, 0] = kt / mu
    B[3, 1] = ct / mu
    B[3, 2] = -1.0 / mu
    B[3, 3] = 0.0 if contact else -p.static_tyre_load / mu
    return A, B


def discretise(params, h, *, contact=True):
    """
    Exact discretisation over a step ``h`` [s]: road height first-order hold, others held.

    Returns
    -------
    ndarray with shape (4, 9)
        Rows map ``[z_s, v_s, z_u, v_u, z_r(start), z_r(end), zdot_r, F_d, 1]`` to the state
        at the end of the step.

    """
    A, B = state_matrices(params, contact=contact)
    n, m = 4, 4
    M = np.zeros((n + 2 * m, n + 2 * m))
    M[:n, :n] = A * h
    M[:n, n:n + m] = B * h
    M[n:n + m, n + m:] = np.eye(m)
    E = expm(M)
    phi = E[:n, :n]
    g1 = E[:n, n:n + m]
    g2 = E[:n, n + m:]
    out = np.zeros((4, 9))
    out[:, :4] = phi
    out[:, 4] = g1[:, 0] - g2[:, 0]
    out[:, 5] = g2[:, 0]
    out[:, 6] = g1[:, 1]
    out[:, 7] = g1[:, 2]
    out[:, 8] = g1[:, 3]
    return out


class LinearDamperPlant:
    """
    Linear viscous (+ spring, + offset) damper with the streaming plant interface.

    Model force (resisting extension positive) ``F = c v + k x + f0`` [N]; the current command
    is ignored except that ``current`` reports it (no coil). For tests and as a fallback.

    Parameters
    ----------
    c : float
        Damping [N s/m].
    k : float
        Stiffness [N/m].
    f0 : float
        Offset [N].

    """

    def __init__(self, c=1500.0, k=0.0, f0=0.0):
        self.c, self.k, self.f0 = float(c), float(k), float(f0)
        self.current = 0.0

    def reset(self):
        """Reset (no internal state except the reported current)."""
        self.current = 0.0

    def step(self, dt, x, v, i_cmd):
        """Return the force [N] at piston position ``x`` [m] and velocity ``v`` [m/s]."""
        self.current = i_cmd
        return self.c * v + self.k * x + self.f0


class QuarterCar:
    """
    Stepwise nonlinear quarter car with a damper plant (the API the ROS node uses).

    Parameters
    ----------
    params : QuarterCarParams
        Car parameters.
    plant : DamperPlant or None
        Streaming damper plant (``mr_damper_model.models.plant``); ``step(dt, x, v, i_cmd) -> F``
        with x = travel, v = piston velocity, F the model force (resisting extension positive).
        None: only :meth:`step_force` can be used.
    road : RoadProfile
        Road; before its start the first height is held, after its end the last.
    substeps : int
        Integration sub-steps per control step (plant stepped each sub-step).
    t0 : float
        Initial time [s] (negative to let the car settle before the road starts).

    Notes
    -----
    :meth:`step` and :meth:`step_force` both advance by ``dt`` and return the state at the end
    of the step. The car starts at rest in static equilibrium on the road's initial height.

    """

    def __init__(self, params, plant, road, *, substeps=1, t0=0.0):
        if not isinstance(params, QuarterCarParams):
            raise TypeError('`params` must be a QuarterCarParams')
        if int(substeps) < 1:
            raise ValueError(f'`substeps` must be >= 1, got {substeps}')
        self.params = params
        self.plant = plant
        self.road = road
        self.substeps = int(substeps)
        self._t0 = float(t0)
        self._coef = {}
        self._rt0 = float(road.t[0])
        self._rdt = road.dt
        self._rn = road.n
        self._periodic = bool(getattr(road, 'periodic', False))
        self._rz = road.z.tolist()
        self._rzd = road.zdot.tolist()
        p = params
        self._ms, self._mu, self._ks, self._kt = p.m_s, p.m_u, p.k_s, p.k_t
        self._cs, self._ct, self._w = p.c_s, p.c_t, p.static_tyre_load
        self.reset()

    def reset(self):
        """Return to rest in static equilibrium at ``t0`` (resets the plant too)."""
        zr = self._road_at(self._t0)[0]
        self.t = self._t0
        self._x = [zr, 0.0, zr, 0.0]
        self._f = 0.0
        self._cur = 0.0 if self.plant is None else float('nan')
        if self.plant is not None:
            self.plant.reset()
            self._cur = float(self.plant.current)
        self._state = self._make_state(self._x, self._f, zr, self._road_at(self._t0)[1])

    @property
    def state(self):
        """Return the present :class:`~mr_damper_common.contract.CornerState`."""
        return self._state

    def set_state(self, z_s=0.0, v_s=0.0, z_u=0.0, v_u=0.0, damper_force=0.0):
        """
        Set the mechanical state (e.g. an initial condition for free vibration).

        Parameters
        ----------
        z_s, v_s, z_u, v_u : float
            Body and wheel displacements [m] and velocities [m/s].
        damper_force : float
            Damper force on the body [N] held over the next step.

        Returns
        -------
        CornerState

        """
        self._x = [float(z_s), float(v_s), float(z_u), float(v_u)]
        self._f = float(damper_force)
        zr, zd = self._road_at(self.t)
        self._state = self._make_state(self._x, self._f, zr, zd)
        return self._state

    def _road_at(self, t):
        u = (t - self._rt0) / self._rdt
        if u <= 0.0:
            return self._rz[0], 0.0
        k = int(u)
        z = self._rz
        zd = self._rzd
        if k >= self._rn - 1:
            if not self._periodic:
                return z[-1], 0.0
            # one period is n samples: sample n is sample 0 again
            u = math.fmod(u, self._rn)
            k = int(u)
            k1 = 0 if k >= self._rn - 1 else k + 1
            a = u - k
            return z[k] + a * (z[k1] - z[k]), zd[k] + a * (zd[k1] - zd[k])
        a = u - k
        return z[k] + a * (z[k + 1] - z[k]), zd[k] + a * (zd[k + 1] - zd[k])

    def _coefs(self, h):
        c = self._coef.get(h)
        if c is None:
            c = (discretise(self.params, h, contact=True).tolist(),
                 discretise(self.params, h, contact=False).tolist())
            self._coef[h] = c
        return c

    def _make_state(self, x, f, zr, zdr):
        zs, vs, zu, vu = x
        tr = zs - zu
        vr = vs - vu
        ft = self._w + self._kt * (zr - zu) + self._ct * (zdr - vu)
        if ft < 0.0:
            ft = 0.0
        fs = self._ks * tr + self._cs * vr
        a_s = (f - fs) / self._ms
        a_u = (fs - f + ft - self._w) / self._mu
        return CornerState(self.t, zs, vs, a_s, zu, vu, a_u, zr, tr, vr, ft, f, self._cur)

    def _advance(self, dt, current_cmd, force):
        if not dt > 0.0:
            raise ValueError(f'`dt` must be > 0, got {dt}')
        nsub = self.substeps
        h = dt / nsub
        cc, ca = self._coefs(h)
        zs, vs, zu, vu = self._x
        f = self._f
        plant = self.plant
        t = self.t
        zr0, zd0 = self._road_at(t)
        w, kt, ct = self._w, self._kt, self._ct
        for _ in range(nsub):
            t1 = t + h
            zr1, zd1 = self._road_at(t1)
            slope = (zr1 - zr0) / h
            if w + kt * (zr0 - zu) + ct * (zd0 - vu) > 0.0:
                c = cc
            else:
                c = ca
            r0, r1, r2, r3 = c
            zs, vs, zu, vu = (
                r0[0] * zs + r0[1] * vs + r0[2] * zu + r0[3] * vu + r0[4] * zr0 + r0[5] * zr1
                + r0[6] * slope + r0[7] * f + r0[8],
                r1[0] * zs + r1[1] * vs + r1[2] * zu + r1[3] * vu + r1[4] * zr0 + r1[5] * zr1
                + r1[6] * slope + r1[7] * f + r1[8],
                r2[0] * zs + r2[1] * vs + r2[2] * zu + r2[3] * vu + r2[4] * zr0 + r2[5] * zr1
                + r2[6] * slope + r2[7] * f + r2[8],
                r3[0] * zs + r3[1] * vs + r3[2] * zu + r3[3] * vu + r3[4] * zr0 + r3[5] * zr1
                + r3[6] * slope + r3[7] * f + r3[8])
            if force is None:
                f = -plant.step(h, zs - zu, vs - vu, current_cmd)
            else:
                f = force
            t, zr0, zd0 = t1, zr1, zd1
        self.t = t
        self._x = [zs, vs, zu, vu]
        self._f = f
        self._cur = plant.current if force is None else float('nan')
        self._state = self._make_state(self._x, f, zr0, zd0)
        return self._state

    def step(self, dt, current_cmd):
        """
        Advance by ``dt`` [s] with the coil current command ``current_cmd`` [A] held.

        Returns
        -------
        CornerState
            State at the end of the step; ``damper_force`` is the plant's force there.

        """
        if self.plant is None:
            raise RuntimeError('QuarterCar has no damper plant: use step_force()')
        return self._advance(dt, float(current_cmd), None)

    def step_force(self, dt, force):
        """
        Advance by ``dt`` [s] with a force [N] on the body (positive up) applied directly.

        The damper plant is bypassed (ideal semi-active or fully active actuator references);
        the same force acts equal and opposite on the wheel.

        Returns
        -------
        CornerState

        """
        f = float(force)
        self._f = f
        return self._advance(dt, 0.0, f)
