"""
The linear full car (7-DOF): corner maps, state matrices, natural frequencies, and its state.

Generalised coordinates ``q = [z, theta, phi, z_u_fl, z_u_fr, z_u_rl, z_u_rr]`` and velocities
``v`` (conventions of :mod:`semi_active_control.car.full_car`). With ``S = [T, -I]`` the map
from ``q`` to the four suspension travels and ``P = [0, I]`` the map to the wheels::

    M qdd = -S' (Ks S q + Cs S v) + S' F_d + P' (F_t - W)

``Ks`` holds the springs and the anti-roll bars, ``F_d`` the four damper forces on the body
(+ up), ``W`` the static tyre loads, ``F_t`` the tyre forces (linear here: in contact). The
full-car laws and the full-car estimator are designed on it; the simulator
(:mod:`quarter_car_sim.plant.full_car`) integrates it with tyre lift-off and four damper
plants. :class:`FullCarState` is the whole car's state the full-car laws read.
"""
import dataclasses
import math

import numpy as np

from mr_damper_common.contract import CornerState

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
        return _corner_state(self.t, i, self.q.item, self.v.item, self.acc.item, self.z_r.item,
                             self.travel.item, self.v_rel.item, self.tyre_force.item,
                             self.damper_force.item, self.coil_current.item, self.body_v.item,
                             self.body_a.item)

    def corners(self):
        """
        Return the four corners ``fl, fr, rl, rr`` (``[corner(i) for i in range(4)]``) at once.

        The same :class:`~mr_damper_common.contract.CornerState` values as :meth:`corner` (each
        array read once as Python floats), for a controller that takes all four every cycle.
        """
        cols = tuple(a.tolist().__getitem__ for a in (
            self.q, self.v, self.acc, self.z_r, self.travel, self.v_rel, self.tyre_force,
            self.damper_force, self.coil_current, self.body_v, self.body_a))
        return [_corner_state(self.t, i, *cols) for i in range(4)]


def _corner_state(t, i, q, v, acc, z_r, travel, v_rel, tyre_force, damper_force, coil_current,
                  body_v, body_a):
    """Corner ``i`` of a :class:`FullCarState` whose columns are read by index (``q(3 + i)``)."""
    z_u = q(3 + i)
    x = travel(i)
    return CornerState(t, x + z_u, body_v(i), body_a(i), z_u, v(3 + i), acc(3 + i), z_r(i), x,
                       v_rel(i), tyre_force(i), damper_force(i), coil_current(i))
