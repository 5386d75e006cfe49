"""
Full-car (7-DOF) dynamics: linear matrices and the stepwise simulator with four damper plants.

Generalised coordinates ``q = [z, theta, phi, z_u_fl, z_u_fr, z_u_rl, z_u_rr]`` and velocities
``v`` (conventions of :mod:`semi_active_control.car.full_car`). With ``S = [T, -I]`` the map from
``q`` to the four suspension travels and ``P = [0, I]`` the map to the wheels::

    M qdd = -S' (Ks S q + Cs S v) + S' F_d + P' (F_t - W)
    F_t,i = max(0, W_i + k_t (z_r,i - z_u,i) + c_t (zdot_r,i - v_u,i))     (tyre cannot pull)

``Ks`` holds the springs and the anti-roll bars, ``F_d`` the four damper forces on the body
(+ up), ``W`` the static tyre loads. Integration is that of the quarter car
(:mod:`quarter_car_sim.dynamics`): the linear 14-state part advanced exactly over each
(sub)step (matrix exponential of the augmented system, cached per step size and per pattern of
wheels in contact), road heights first-order hold, damper forces held; each damper plant is
then stepped to its end-of-step travel and velocity.
"""
import dataclasses
import math

import numpy as np
from scipy.linalg import expm

from mr_damper_common.contract import CornerState
from semi_active_control.car.full_car import FullCarParams

N_Q = 7
N_X = 14
#: Inputs of :func:`state_matrices`: road heights (4), road velocities (4), damper forces (4),
#: a constant 1 (carries -W of an airborne wheel).
N_U = 13


def corner_maps(params):
    """
    Return the maps ``T`` (4, 3), ``S = [T, -I]`` (4, 7) and ``P = [0, I]`` (4, 7).

    ``T`` takes the body's ``[z, theta, phi]`` to the four body points, ``S`` the coordinates
    ``q`` to the suspension travels and ``P`` to the wheels.
    """
    T = params.geometry
    S = np.hstack([T, -np.eye(4)])
    P = np.hstack([np.zeros((4, 3)), np.eye(4)])
    return T, S, P


def state_matrices(params, contact=(True, True, True, True)):
    """
    Continuous-time matrices of the linear full car (dampers as force inputs).

    Parameters
    ----------
    params : FullCarParams
        Car parameters.
    contact : sequence of 4 bool
        Wheels in contact (an airborne wheel has no tyre force; its static load acts on it).

    Returns
    -------
    A : ndarray with shape (14, 14)
        State matrix of ``[q, v]``.
    B : ndarray with shape (14, 13)
        Input matrix of ``[z_r (4), zdot_r (4), F_d (4), 1]``.

    """
    p = params
    _, S, P = corner_maps(p)
    m = np.asarray(contact, dtype=float)
    kt = np.diag(p.k_t * m)
    ct = np.diag(p.c_t * m)
    K = S.T @ p.spring_matrix() @ S + P.T @ kt @ P
    C = S.T @ np.diag(p.c_s) @ S + P.T @ ct @ P
    minv = np.diag(1.0 / np.diag(p.mass_matrix))
    A = np.zeros((N_X, N_X))
    A[:N_Q, N_Q:] = np.eye(N_Q)
    A[N_Q:, :N_Q] = -minv @ K
    A[N_Q:, N_Q:] = -minv @ C
    B = np.zeros((N_X, N_U))
    B[N_Q:, 0:4] = minv @ P.T @ kt
    B[N_Q:, 4:8] = minv @ P.T @ ct
    B[N_Q:, 8:12] = minv @ S.T
    B[N_Q:, 12] = minv @ P.T @ (-p.static_tyre_loads * (1.0 - m))
    return A, B


def natural_frequencies(params):
    """
    Undamped natural frequencies [Hz] of the linear car (all wheels in contact), ascending.

    With the damper plants removed (``c_s`` of the parameters kept).

    Returns
    -------
    ndarray with shape (7,)

    """
    A, _ = state_matrices(params.replace(c_s_f=0.0, c_s_r=0.0, c_t=0.0))
    w = np.sqrt(np.abs(np.linalg.eigvals(A[N_Q:, :N_Q])))
    return np.sort(w) / (2.0 * math.pi)


def discretise(params, h, contact=(True, True, True, True)):
    """
    Exact discretisation over a step ``h`` [s]: road heights first-order hold, the rest held.

    Returns
    -------
    ndarray with shape (14, 31)
        Maps ``[x (14), z_r start (4), z_r end (4), zdot_r (4), F_d (4), 1]`` to the state at
        the end of the step.

    """
    A, B = state_matrices(params, contact)
    n, m = N_X, N_U
    big = np.zeros((n + 2 * m, n + 2 * m))
    big[:n, :n] = A * h
    big[:n, n:n + m] = B * h
    big[n:n + m, n + m:] = np.eye(m)
    E = expm(big)
    phi, g1, g2 = E[:n, :n], E[:n, n:n + m], E[:n, n + m:]
    return np.hstack([phi, g1[:, 0:4] - g2[:, 0:4], g2[:, 0:4], g1[:, 4:13]])


@dataclasses.dataclass(frozen=True)
class FullCarState:
    """
    Full-car state at one instant (SI, conventions of :mod:`semi_active_control.car.full_car`).

    Attributes
    ----------
    t : float
        Time [s].
    q, v, acc : ndarray with shape (7,)
        Coordinates ``[z, theta, phi, z_u x4]`` [m, rad], their rates and accelerations.
    z_r, zdot_r : ndarray with shape (4,)
        Road height [m] and vertical road velocity [m/s] under each wheel.
    travel, v_rel : ndarray with shape (4,)
        Suspension travel [m] (extension +) and its rate [m/s] per corner.
    tyre_force : ndarray with shape (4,)
        Total tyre contact force per wheel [N] (>= 0).
    damper_force : ndarray with shape (4,)
        Damper force on the body per corner [N] (+ up).
    coil_current : ndarray with shape (4,)
        Actual coil current of each plant [A] (nan with forces applied directly).
    body_v, body_a : ndarray with shape (4,)
        Vertical velocity [m/s] and acceleration [m/s^2] of the body above each wheel.

    """

    t: float
    q: np.ndarray
    v: np.ndarray
    acc: np.ndarray
    z_r: np.ndarray
    zdot_r: np.ndarray
    travel: np.ndarray
    v_rel: np.ndarray
    tyre_force: np.ndarray
    damper_force: np.ndarray
    coil_current: np.ndarray
    body_v: np.ndarray
    body_a: np.ndarray

    def corner(self, i):
        """
        Corner ``i`` as a :class:`~mr_damper_common.contract.CornerState` (the laws' contract).

        The body point above the wheel is ``z_s = travel + z_u``, its velocity and acceleration
        ``body_v`` / ``body_a``; the rest is the corner's column (NaN where the state has none,
        e.g. the tyre force of an estimate).
        """
        z_u = self.q.item(3 + i)
        travel = self.travel.item(i)
        return CornerState(self.t, travel + z_u, self.body_v.item(i), self.body_a.item(i), z_u,
                           self.v.item(3 + i), self.acc.item(3 + i), self.z_r.item(i), travel,
                           self.v_rel.item(i), self.tyre_force.item(i),
                           self.damper_force.item(i), self.coil_current.item(i))


class FullCar:
    """
    Stepwise nonlinear full car with four damper plants (one "true" damper per corner).

    Parameters
    ----------
    params : FullCarParams
        Car parameters.
    plants : sequence of 4 DamperPlant or None
        Streaming damper plants (``mr_damper_model.models.plant``) of ``fl, fr, rl, rr``; may
        differ. None: only :meth:`step_force` can be used.
    road : quarter_car_sim.full_car.road.TwoTrackRoad
        Road; ``road.at(t)`` gives the four wheel heights and velocities.
    substeps : int
        Integration sub-steps per control step (plants stepped each sub-step).
    t0 : float
        Initial time [s] (negative to settle before the road starts).

    Notes
    -----
    The car starts at rest in static equilibrium on the road's initial heights. The tyres'
    contact is decided per wheel at the start of each (sub)step, as in the quarter car.

    """

    def __init__(self, params, plants, road, *, substeps=1, t0=0.0):
        if not isinstance(params, FullCarParams):
            raise TypeError('`params` must be a FullCarParams')
        if plants is not None:
            plants = list(plants)
            if len(plants) != 4:
                raise ValueError(f'`plants` must hold 4 plants (fl, fr, rl, rr), got '
                                 f'{len(plants)}')
        if int(substeps) < 1:
            raise ValueError(f'`substeps` must be >= 1, got {substeps}')
        self.params = params
        self.plants = plants
        self.road = road
        self.substeps = int(substeps)
        self._t0 = float(t0)
        self._coef = {}
        T, S, P = corner_maps(params)
        self._T, self._S = T, S
        self._ks = params.spring_matrix()
        self._cs = params.c_s
        self._w = params.static_tyre_loads
        self._kt, self._ct = params.k_t, params.c_t
        self._minv_b = 1.0 / np.array([params.m_s, params.i_pitch, params.i_roll])
        self._mu = params.m_u
        self.reset()

    def reset(self):
        """Return to rest in static equilibrium at ``t0`` (resets the plants too)."""
        zr, zd = self.road.at(self._t0)
        self.t = self._t0
        q = np.zeros(N_Q)
        q[3:] = zr
        # body on the mean road plane under the wheels (exact for a flat, tilted start)
        q[:3] = np.linalg.lstsq(self._T, zr, rcond=None)[0]
        self._x = np.concatenate([q, np.zeros(N_Q)])
        self._f = np.zeros(4)
        self._cur = np.full(4, math.nan)
        if self.plants is not None:
            for pl in self.plants:
                pl.reset()
            self._cur = np.array([float(pl.current) for pl in self.plants])
        self._state = self._make_state(self._x, self._f, zr, zd)

    @property
    def state(self):
        """Current :class:`FullCarState`."""
        return self._state

    def set_state(self, q, v=None, damper_force=None):
        """
        Set the mechanical state (e.g. an initial condition for free vibration).

        Parameters
        ----------
        q : array_like with shape (7,)
            Coordinates [m, rad].
        v : array_like with shape (7,), optional
            Rates (default 0).
        damper_force : array_like with shape (4,), optional
            Damper forces on the body [N] held over the next step (default 0).

        Returns
        -------
        FullCarState

        """
        q = np.asarray(q, dtype=float).reshape(N_Q)
        v = np.zeros(N_Q) if v is None else np.asarray(v, dtype=float).reshape(N_Q)
        self._x = np.concatenate([q, v])
        self._f = (np.zeros(4) if damper_force is None
                   else np.asarray(damper_force, dtype=float).reshape(4).copy())
        zr, zd = self.road.at(self.t)
        self._state = self._make_state(self._x, self._f, zr, zd)
        return self._state

    def _coefs(self, h, key):
        c = self._coef.get((h, key))
        if c is None:
            c = discretise(self.params, h, key)
            self._coef[(h, key)] = c
        return c

    def _tyre(self, x, zr, zd):
        u, ud = x[3:N_Q], x[N_Q + 3:]
        return self._w + self._kt * (zr - u) + self._ct * (zd - ud)

    def _make_state(self, x, f, zr, zd):
        q, v = x[:N_Q], x[N_Q:]
        travel = self._S @ q
        v_rel = self._S @ v
        ft = np.maximum(self._tyre(x, zr, zd), 0.0)
        fs = f - self._ks @ travel - self._cs * v_rel        # on the body, per corner
        acc = np.empty(N_Q)
        acc[:3] = self._minv_b * (self._T.T @ fs)
        acc[3:] = (ft - self._w - fs) / self._mu
        return FullCarState(self.t, q.copy(), v.copy(), acc, np.asarray(zr, float).copy(),
                            np.asarray(zd, float).copy(), travel, v_rel, ft, f.copy(),
                            self._cur.copy(), self._T @ v[:3], self._T @ acc[:3])

    def _advance(self, dt, currents, force):
        if not dt > 0.0:
            raise ValueError(f'`dt` must be > 0, got {dt}')
        h = dt / self.substeps
        x = self._x
        f = self._f
        t = self.t
        zr0, zd0 = self.road.at(t)
        plants = self.plants
        vec = np.empty(N_X + 17)
        vec[-1] = 1.0
        S = self._S
        for _ in range(self.substeps):
            t1 = t + h
            zr1, zd1 = self.road.at(t1)
            key = tuple(bool(c) for c in self._tyre(x, zr0, zd0) > 0.0)
            g = self._coefs(h, key)
            vec[:N_X] = x
            vec[N_X:N_X + 4] = zr0
            vec[N_X + 4:N_X + 8] = zr1
            vec[N_X + 8:N_X + 12] = (np.asarray(zr1) - zr0) / h
            vec[N_X + 12:N_X + 16] = f
            x = g @ vec
            if force is None:
                tr = S @ x[:N_Q]
                vr = S @ x[N_Q:]
                f = np.array([-pl.step(h, tr[i], vr[i], currents[i])
                              for i, pl in enumerate(plants)])
            else:
                f = force
            t, zr0, zd0 = t1, zr1, zd1
        self.t = t
        self._x = x
        self._f = f
        if force is None:
            self._cur = np.array([pl.current for pl in plants], dtype=float)
        else:
            self._cur = np.full(4, math.nan)
        self._state = self._make_state(x, f, zr0, zd0)
        return self._state

    def step(self, dt, currents):
        """
        Advance by ``dt`` [s] with the four coil current commands [A] held.

        Returns
        -------
        FullCarState

        """
        if self.plants is None:
            raise RuntimeError('FullCar has no damper plants: use step_force()')
        cur = [float(c) for c in currents]
        if len(cur) != 4:
            raise ValueError('`currents` must hold 4 values (fl, fr, rl, rr)')
        return self._advance(dt, cur, None)

    def step_force(self, dt, forces):
        """
        Advance by ``dt`` [s] with four forces on the body [N] (+ up) applied directly.

        The plants are bypassed (ideal actuators); each force acts equal and opposite on its
        wheel.

        Returns
        -------
        FullCarState

        """
        f = np.asarray(forces, dtype=float).reshape(4).copy()
        self._f = f
        return self._advance(dt, None, f)


def mechanical_energy(params, state):
    """
    Mechanical energy [J] about the static equilibrium (all tyres in contact).

    Kinetic energy plus the strain energy of springs, anti-roll bars and tyres; the static
    preloads cancel gravity, so this is the energy a passive car can only lose on a flat road.
    """
    M = params.mass_matrix
    v = state.v
    tyre = state.q[3:] - state.z_r
    return float(0.5 * v @ M @ v + 0.5 * state.travel @ params.spring_matrix() @ state.travel
                 + 0.5 * params.k_t * tyre @ tyre)
