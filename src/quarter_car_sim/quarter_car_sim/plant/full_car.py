"""
Full-car (7-DOF) dynamics: the stepwise simulator with four damper plants.

Generalised coordinates ``q = [z, theta, phi, z_u_fl, z_u_fr, z_u_rl, z_u_rr]`` and velocities
``v`` (conventions of :mod:`semi_active_control.car.full_car`). With ``S = [T, -I]`` the map from
``q`` to the four suspension travels and ``P = [0, I]`` the map to the wheels::

    M qdd = -S' (Ks S q + Cs S v) + S' F_d + P' (F_t - W)
    F_t,i = max(0, W_i + k_t (z_r,i - z_u,i) + c_t (zdot_r,i - v_u,i))     (tyre cannot pull)

``Ks`` holds the springs and the anti-roll bars, ``F_d`` the four damper forces on the body
(+ up), ``W`` the static tyre loads (the linear matrices and the state type:
:mod:`semi_active_control.car.full_car_linear`). Integration is that of the quarter car
(:mod:`quarter_car_sim.plant.quarter_car`): the linear 14-state part advanced exactly over each
(sub)step (matrix exponential of the augmented system, cached per step size and per pattern of
wheels in contact), road heights first-order hold, damper forces held; each damper plant is
then stepped to its end-of-step travel and velocity.
"""
import math

import numpy as np
from scipy.linalg import expm

from semi_active_control.car.full_car import FullCarParams
from semi_active_control.car.full_car_linear import (corner_maps, FullCarState, N_Q, N_U, N_X,
                                                     state_matrices)


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
    road : quarter_car_sim.plant.two_track_road.TwoTrackRoad
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
