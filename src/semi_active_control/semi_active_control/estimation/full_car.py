"""
State estimator of the full car (7 DOF) from the production sensor set: a Kalman filter, no ROS.

Sensors (the usual production set of a semi-active car): three body vertical accelerometers
at the body points above the front-left, front-right and rear-left wheels
(:data:`ACCEL_CORNERS`; three non-collinear points fix the rigid body's heave, pitch and roll
accelerations, so the fourth corner adds nothing but cost; the front pair sits near the front
dampers' top mounts where the controller needs the body velocity most) and four suspension
position sensors (travel, one per corner). Each sensor has the error model of
:mod:`semi_active_control.estimation.sensor_specs`
(:func:`~semi_active_control.estimation.sensor_specs.accelerometer_spec`,
:func:`~semi_active_control.estimation.sensor_specs.ride_height_spec`); the simulator samples them
(:class:`quarter_car_sim.plant.sensors.FullCarSensors`).

Model (the linear car of :func:`semi_active_control.car.full_car_linear.state_matrices`, all
wheels in contact), state ::

    x = [travel (4), tyre_def (4), v (7), b_acc (3)]

suspension travels [m] (extension +), tyre deflections ``z_u - z_r`` [m], the seven rates
``[zdot, thetadot, phidot, v_u x4]`` and the bias of each accelerometer [m/s^2] (random walk).
Travels and tyre deflections are the 8 independent position coordinates relative to the road
(the car's absolute height is not observable and no law needs it). Inputs: the four damper
forces on the body (a *known* input, as in the quarter-car filter
:mod:`semi_active_control.estimation.quarter_car`) and the four road velocities, unknown: white
process noise of the ISO 8608 intensity
:func:`semi_active_control.estimation.quarter_car.road_velocity_intensity` (the two tracks
taken independent). Measurements: body specific force at the three points (gravity
removed), the four travels.

Design (:func:`design_full_car_estimator`): exact discretisation at the control period (Van
Loan for the process noise) and the steady-state filter from ``control.dlqe``. Runtime
(:class:`FullCarEstimator`): the time-varying filter started at that steady state, scalar
sequential updates of the readings that arrived (a missing or lost one only widens the
covariance); a sensor with no reading for ``dropout_s`` makes the estimate invalid
(``dropout_<sensor>``, counted).
"""
import math

import numpy as np
from scipy.linalg import expm

from semi_active_control.car.full_car import CORNERS
from semi_active_control.car.full_car_linear import FullCarState, N_Q, state_matrices
from semi_active_control.estimation.quarter_car import EstimatorError, road_velocity_intensity
from semi_active_control.estimation.sensor_specs import accelerometer_spec, G0, ride_height_spec

#: Corners whose body point carries an accelerometer.
ACCEL_CORNERS = ('fl', 'fr', 'rl')
#: Sensor names, in the order of the measurement rows.
SENSORS = tuple(f'accel_{c}' for c in ACCEL_CORNERS) + tuple(f'travel_{c}' for c in CORNERS)
#: State groups of the estimate (for error statistics).
STATE_GROUPS = {'travel': slice(0, 4), 'tyre_def': slice(4, 8), 'body_rates': slice(8, 11),
                'wheel_v': slice(11, 15)}
N_E = 18


def _accel_rows(params):
    return [CORNERS.index(c) for c in ACCEL_CORNERS]


def body_accelerations(params, accel):
    """
    Heave, pitch and roll accelerations from the three body accelerometers (rigid body).

    Parameters
    ----------
    params : FullCarParams
        Car (its corner geometry).
    accel : array_like with shape (3,)
        Vertical accelerations [m/s^2] at the points of :data:`ACCEL_CORNERS`.

    Returns
    -------
    ndarray with shape (3,)
        ``[zdd, thetadd, phidd]``.

    """
    T3 = params.geometry[_accel_rows(params)]
    return np.linalg.solve(T3, np.asarray(accel, dtype=float).reshape(3))


def _continuous(params):
    """Return ``A, B (forces), G (road velocity), C, D`` of the estimator's state."""
    A7, B7 = state_matrices(params)
    T = params.geometry
    S = np.hstack([T, -np.eye(4)])
    P = np.hstack([np.zeros((4, 3)), np.eye(4)])
    kt, ct = params.k_t, params.c_t
    minv = np.diag(1.0 / np.diag(params.mass_matrix))
    acc_v = A7[N_Q:, N_Q:]                      # rate feedback (springs via positions below)
    K_tr = -minv @ S.T @ params.spring_matrix()  # acceleration per travel
    K_td = -minv @ P.T * kt                      # per tyre deflection
    A = np.zeros((N_E, N_E))
    A[0:4, 8:15] = S
    A[4:8, 8:15] = P
    A[8:15, 0:4] = K_tr
    A[8:15, 4:8] = K_td
    A[8:15, 8:15] = acc_v
    B = np.zeros((N_E, 4))
    B[8:15] = B7[N_Q:, 8:12]
    G = np.zeros((N_E, 7))
    G[4:8, 0:4] = -np.eye(4)
    G[8:15, 0:4] = minv @ P.T * ct
    G[15:18, 4:7] = np.eye(3)
    rows = _accel_rows(params)
    C = np.zeros((7, N_E))
    D = np.zeros((7, 4))
    C[0:3] = T[rows] @ A[8:11]
    C[0:3, 15:18] = np.eye(3)
    D[0:3] = T[rows] @ B[8:11]
    C[3:7, 0:4] = np.eye(4)
    return A, B, G, C, D


class FullCarDesign:
    """Discrete filter of :func:`design_full_car_estimator` (attributes as the quarter car's)."""

    def __init__(self, **kw):
        self.__dict__.update(kw)


def design_full_car_estimator(params, dt, *, accel=None, travel=None, road_class='C',
                              speed_m_s=20.0, q_bias=1.0e-4):
    """
    Design the full-car Kalman filter (``control.dlqe`` on the exactly discretised model).

    Parameters
    ----------
    params : FullCarParams
        Car the filter assumes.
    dt : float
        Control period [s].
    accel, travel : SensorSpec, optional
        Error models of the accelerometers and the position sensors (default the automotive
        parts of :mod:`quarter_car_sim.plant.sensors`); ``variance`` sets the measurement noise.
    road_class, speed_m_s
        Design road (ISO 8608 class) and speed: intensity of the road velocity noise.
    q_bias : float
        Random-walk intensity of the accelerometer biases [(m/s^2)^2/s].

    Returns
    -------
    FullCarDesign

    """
    import control
    if not (math.isfinite(dt) and dt > 0):
        raise EstimatorError(f'`dt` must be > 0, got {dt}')
    accel = accelerometer_spec() if accel is None else accel
    travel = ride_height_spec() if travel is None else travel
    A, B, G, C, D = _continuous(params)
    W = np.diag([road_velocity_intensity(road_class, speed_m_s)] * 4 + [q_bias] * 3)
    n = N_E
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A * dt
    M[:n, n:] = G @ W @ G.T * dt
    M[n:, n:] = A.T * dt
    E = expm(M)
    Ad = E[n:, n:].T
    Qd = Ad @ E[:n, n:]
    Qd = (Qd + Qd.T) / 2.0
    Mb = np.zeros((n + 4, n + 4))
    Mb[:n, :n], Mb[:n, n:] = A * dt, B * dt
    Bd = expm(Mb)[:n, n:]
    R = np.diag([max(accel.variance, 1e-18)] * 3 + [max(travel.variance, 1e-18)] * 4)
    try:
        L, P, _ = control.dlqe(Ad, np.eye(n), C, Qd, R)
    except Exception as exc:      # noqa: B902 - python-control raises several types
        raise EstimatorError(f'control.dlqe found no steady-state filter: {exc}') from None
    P = np.asarray(P)
    P = (P + P.T) / 2.0
    S = C @ P @ C.T + R
    Mg = P @ C.T @ np.linalg.inv(S)
    return FullCarDesign(dt=float(dt), Ad=Ad, Bd=Bd, Qd=Qd, H=C, Dm=D, R=R, L=np.asarray(L),
                         P=P, M=Mg, A=A, B=B, params=params, accel=accel, travel=travel)


class FullCarEstimator:
    """
    Time-varying Kalman filter of the full car on the readings of :data:`SENSORS`.

    Parameters
    ----------
    design : FullCarDesign
    dropout_s : float
        A sensor with no reading for this long makes the estimate invalid.
    delay_steps : int
        Sensor latency in control periods the filter accounts for: 0 (a reading delivered
        now is taken as of now) or 1 (as of the previous step, the default sensors' 1 ms at
        1 kHz: the reading updates the previous step's state with the previous forces, then
        the filter predicts to now; no extra states).

    Attributes
    ----------
    x : ndarray (18,)
        Posterior state; ``P`` its covariance.
    valid : bool
    reason : str
        Why invalid ('' when valid).
    n_invalid : dict
        Steps invalid per reason.

    """

    def __init__(self, design, *, dropout_s=0.02, delay_steps=0):
        if delay_steps not in (0, 1):
            raise EstimatorError(f'`delay_steps` must be 0 or 1, got {delay_steps!r}')
        self.d = design
        self.dropout_s = float(dropout_s)
        self.delay_steps = int(delay_steps)
        self.reset()

    def reset(self, x0=None, P0=None):
        """
        Start at ``x0`` (default the static equilibrium) with covariance ``P0``.

        ``P0`` defaults to the steady-state covariance of the design (right for a start at
        rest); a start that may be far off needs a wider one.
        """
        self.x = np.zeros(N_E) if x0 is None else np.asarray(x0, dtype=float).copy()
        self.P = self.d.P.copy() if P0 is None else np.asarray(P0, dtype=float).copy()
        self._f = np.zeros(4)
        self._last_seen = {s: None for s in SENSORS}
        self.valid = False
        self.reason = 'no_data_yet'
        self.n_invalid = {}
        self.n_steps = 0

    def step(self, t, readings, forces):
        """
        Predict over the period that ends now, then take the readings that arrived.

        The prediction uses the forces of the previous call (held over the period, as the
        plants hold them); the accelerometer rows use ``forces``.

        Parameters
        ----------
        t : float
            Time [s] of the readings.
        readings : dict
            ``{sensor: value}`` (accelerometers: specific force, gravity included; NaN: lost;
            a missing key: nothing arrived).
        forces : array_like (4,)
            Damper forces on the body [N] now (held over the period that starts now).

        Returns
        -------
        ndarray (18,)

        """
        d = self.d
        if self.n_steps and not self.delay_steps:
            self._predict()
        f_now = np.asarray(forces, dtype=float).reshape(4).copy()
        # with one step of delay the readings are of the previous step (its forces)
        f_meas = self._f if self.delay_steps and self.n_steps else f_now
        for r, name in enumerate(SENSORS):
            y = readings.get(name)
            if y is None or not math.isfinite(y):
                continue
            self._last_seen[name] = t
            if r < 3:
                y = y - G0
            h = d.H[r]
            ph = self.P @ h
            s = h @ ph + d.R[r, r]
            k = ph / s
            self.x = self.x + k * (y - h @ self.x - d.Dm[r] @ f_meas)
            self.P = self.P - np.outer(k, ph)
        self.P = (self.P + self.P.T) / 2.0
        if self.delay_steps and self.n_steps:
            self._predict()
        self._f = f_now
        self.n_steps += 1
        self.reason = ''
        for name, seen in self._last_seen.items():
            if seen is None:
                self.reason = 'no_data_yet'
                break
            if t - seen > self.dropout_s:
                self.reason = f'dropout_{name}'
                break
        if not np.all(np.isfinite(self.x)):
            self.reason = 'diverged'
            self.x = np.zeros(N_E)
            self.P = d.P.copy()
        self.valid = not self.reason
        if self.reason:
            self.n_invalid[self.reason] = self.n_invalid.get(self.reason, 0) + 1
        return self.x

    def _predict(self):
        d = self.d
        self.x = d.Ad @ self.x + d.Bd @ self._f
        self.P = d.Ad @ self.P @ d.Ad.T + d.Qd

    def std(self):
        """Return the standard deviations of the 18 states."""
        return np.sqrt(np.maximum(np.diag(self.P), 0.0))

    def state(self, t):
        """Return the estimate as a :class:`FullCarState` (road heights 0: wheel = tyre_def)."""
        x = self.x
        d = self.d
        travel, tyre, v = x[0:4], x[4:8], x[8:15]
        T = d.params.geometry
        q = np.zeros(N_Q)
        q[3:] = tyre
        q[:3] = np.linalg.lstsq(T, travel + tyre, rcond=None)[0]
        dx = d.A @ x + d.B @ self._f
        acc = dx[8:15]
        S = np.hstack([T, -np.eye(4)])
        return FullCarState(float(t), q, v.copy(), acc, np.zeros(4), np.zeros(4),
                            travel.copy(), S @ v, np.full(4, math.nan), self._f.copy(),
                            np.full(4, math.nan), T @ v[:3], T @ acc[:3])
