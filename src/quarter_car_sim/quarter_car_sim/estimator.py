"""
State estimator of a quarter-car corner from vehicle sensors: a Kalman filter, no ROS.

Model (the linear car of :mod:`quarter_car_sim.linear_analysis`, nominal parameters): state ::

    x = [travel, v_s, z_u - z_r, v_u, d, b_body (, b_wheel)]

suspension travel [m], body and wheel absolute velocity [m/s], tyre deflection [m] (negative
when compressed), a force error ``d`` [N] (random walk: what the identified damper model and the
nominal car parameters miss, acting between body and wheel like the damper) and the bias of each
accelerometer [m/s^2] (random walk). Inputs: the damper force on the body ``F`` of the live
identified model at the estimated travel and piston velocity and the coil current (a *known*
input), and the road velocity ``zdot_r`` (unknown: white process noise whose intensity follows
from the ISO 8608 class and the speed, since a road of waviness 2 has a flat velocity spectrum:
``S = 2 pi^2 Gd(n0) n0^2 V`` two-sided [m^2/s]). Measurements: body acceleration (the
accelerometer reads specific force; the filter removes gravity), optionally the wheel
acceleration, and the suspension travel. A sensor with latency ``L`` control periods is modelled
exactly by ``L`` shift-register states that carry its output to the time it arrives.

Design (:func:`design_estimator`): exact discretisation at the control period (Van Loan for the
process noise), the observability of the chosen sensor set checked (PBH test; an unobservable
set raises :class:`EstimatorError` naming the states that cannot be seen), and the steady-state
filter from ``control.dlqe`` (the discrete algebraic Riccati equation). Runtime
(:class:`QuarterCarEstimator`): the time-varying Kalman filter started at that steady state;
each step predicts with the known force, then takes each reading that arrived (scalar
sequential updates, exact for the independent sensor errors), so missing samples, slower
sensors and dropouts only widen the covariance. Faults make the estimate invalid with a named,
counted reason: a stuck sensor (``stuck_<sensor>``: the same reading for ``stuck_s``), a
dropped-out sensor (``dropout_<sensor>``: no reading for ``dropout_s``), a diverging
innovation (``innovation_<sensor>``: the mean normalised innovation squared over the last
``nis_window_s`` above ``nis_threshold``, a chi-square test with each sample capped) and a
non-finite estimate (``diverged``: the filter restarts).

Longer than the project's ~600 lines on purpose: the filter's design (the discrete model and
``control.dlqe``) and its step (innovation gating, the steady-gain fast path, the fault
checks) share the state layout and must change together.
"""
from collections import deque
import dataclasses
import math

import numpy as np
from scipy.linalg import expm

from quarter_car_sim.sensors import G0, SENSOR_NAMES

#: States of the car part of the estimate, in order.
CAR_STATES = ('travel', 'v_s', 'tyre_def', 'v_u')

#: Reasons an estimate is invalid (``<sensor>`` is a name of ``SENSOR_NAMES``).
INVALID_REASONS = ('no_data_yet', 'diverged') + tuple(
    f'{kind}_{s}' for kind in ('dropout', 'stuck', 'innovation') for s in SENSOR_NAMES)


class EstimatorError(ValueError):
    """Invalid estimator setting or an unobservable sensor set (the message says which)."""


def road_velocity_intensity(road_class='C', speed_m_s=20.0):
    """
    Two-sided spectral density [m^2/s] of the road velocity under the tyre (ISO 8608).

    ``Gd(n) = Gd(n0) (n / n0)^-2`` gives the one-sided time-domain velocity PSD
    ``(2 pi)^2 Gd(n0) n0^2 V`` [(m/s)^2/Hz], flat in frequency; the white-noise intensity is
    half of it.
    """
    from quarter_car_sim.road import ISO8608_GD_N0, ISO8608_N0
    if road_class not in ISO8608_GD_N0:
        raise EstimatorError(f'`road_class` must be one of {"".join(ISO8608_GD_N0)}, got '
                             f'{road_class!r}')
    if not (math.isfinite(speed_m_s) and speed_m_s > 0):
        raise EstimatorError(f'`speed_m_s` must be > 0, got {speed_m_s}')
    return 2.0 * math.pi ** 2 * ISO8608_GD_N0[road_class] * ISO8608_N0 ** 2 * speed_m_s


@dataclasses.dataclass
class EstimatorDesign:
    """
    Discrete Kalman filter design of :func:`design_estimator`.

    Attributes
    ----------
    dt : float
        Control period [s].
    states : tuple of str
        State names (car states, force error, biases, sensor delay registers).
    sensors : tuple of str
        Measured sensors, in the order of the rows of ``H``.
    latency_steps : dict
        Sensor -> delay [control periods].
    Ad, Bd : ndarray
        ``x_{k+1} = Ad x_k + Bd F_k`` (``F_k``: damper force on the body over the period).
    Qd : ndarray
        Process noise covariance per period.
    H, Dm : ndarray
        Measurement ``y = H x + Dm F`` (gravity removed from accelerometers).
    R : ndarray
        Measurement noise variance per sensor (diagonal).
    L : ndarray
        Predictor gain of ``control.dlqe``.
    P : ndarray
        Steady-state prior (predicted) error covariance: the DARE solution of ``control.dlqe``.
    P_post : ndarray
        Steady-state posterior covariance (all sensors read every period).
    M : ndarray
        Steady-state filter gain ``P H' (H P H' + R)^-1``.
    A, G, W : ndarray
        Continuous model of the base states (``dx/dt = A x + B F + G w``, ``E ww' = W``).
    params : QuarterCarParams
        Car parameters the filter assumes.

    """

    dt: float
    states: tuple
    sensors: tuple
    latency_steps: dict
    Ad: np.ndarray
    Bd: np.ndarray
    Qd: np.ndarray
    H: np.ndarray
    Dm: np.ndarray
    R: np.ndarray
    L: np.ndarray
    P: np.ndarray
    P_post: np.ndarray
    M: np.ndarray
    A: np.ndarray
    G: np.ndarray
    W: np.ndarray
    params: object


#: Typical magnitudes of the base states (scaling of the observability test).
_SCALES = {'travel': 0.01, 'v_s': 0.1, 'tyre_def': 0.002, 'v_u': 0.3, 'force_error': 100.0,
           'bias_body_accel': 0.1, 'bias_wheel_accel': 0.1}


def _continuous(params, sensors, estimate_force, estimate_bias, q_road, q_force, q_bias,
                force_tau_s):
    p = params
    ms, mu, ks, kt, cs, ct = p.m_s, p.m_u, p.k_s, p.k_t, p.c_s, p.c_t
    names = list(CAR_STATES)
    if estimate_force:
        names.append('force_error')
    accels = [s for s in ('body_accel', 'wheel_accel') if s in sensors]
    if estimate_bias:
        names += [f'bias_{s}' for s in accels]
    n = len(names)
    ix = {nm: i for i, nm in enumerate(names)}
    A = np.zeros((n, n))
    A[0, 1], A[0, 3] = 1.0, -1.0
    A[1, :4] = [-ks / ms, -cs / ms, 0.0, cs / ms]
    A[2, 3] = 1.0
    A[3, :4] = [ks / mu, cs / mu, -kt / mu, -(cs + ct) / mu]
    B = np.zeros(n)
    B[1], B[3] = 1.0 / ms, -1.0 / mu
    noises = [('road', q_road)]
    G = np.zeros((n, 1 + (1 if estimate_force else 0) + (len(accels) if estimate_bias else 0)))
    G[2, 0], G[3, 0] = -1.0, ct / mu
    j = 1
    if estimate_force:
        i = ix['force_error']
        A[1, i], A[3, i] = 1.0 / ms, -1.0 / mu
        if math.isfinite(force_tau_s):
            A[i, i] = -1.0 / force_tau_s
        G[i, j] = 1.0
        noises.append(('force_error', q_force))
        j += 1
    if estimate_bias:
        for s in accels:
            G[ix[f'bias_{s}'], j] = 1.0
            noises.append((f'bias_{s}', q_bias))
            j += 1
    W = np.diag([q for _, q in noises])
    # outputs of the base states: y = C x + D F
    C, D = {}, {}
    for s in sensors:
        row = np.zeros(n)
        if s == 'travel':
            row[0] = 1.0
            d = 0.0
        else:
            k = 1 if s == 'body_accel' else 3
            row[:] = A[k]
            d = B[k]
            if estimate_bias:
                row[ix[f'bias_{s}']] = 1.0
        C[s], D[s] = row, d
    return names, A, B, G, W, C, D


def unobserved_states(names, A, C_rows, scales=None):
    """
    PBH test of a continuous model: the states a sensor set cannot see (empty: observable).

    Parameters
    ----------
    names : sequence of str
        State names (their order in ``A``).
    A : ndarray with shape (n, n)
        State matrix.
    C_rows : sequence of ndarray with shape (n,)
        Measurement rows of the sensor set.
    scales : dict, optional
        Typical size of each state by name (SI) to scale the test; default this filter's.

    Returns
    -------
    list of str
        The states of the first unobservable mode, largest part first; ``mode`` of the
        error message is in :func:`_check_observable`.

    """
    found = _unobservable_mode(names, A, C_rows, _SCALES if scales is None else scales)
    return [] if found is None else found[0]


def _unobservable_mode(names, A, C_rows, scales):
    n = len(names)
    T = np.diag([scales.get(nm, 1.0) for nm in names])
    As = np.linalg.solve(T, A @ T)
    Cs = (np.vstack(C_rows) @ T) if len(C_rows) else np.zeros((0, n))
    scale = max(np.linalg.norm(As, 2), np.linalg.norm(Cs, 2) if Cs.size else 0.0, 1.0)
    for lam in np.linalg.eigvals(As):
        M = np.vstack([lam * np.eye(n) - As, Cs])
        _, sv, vh = np.linalg.svd(M)
        if sv[-1] < 1e-9 * scale:
            v = np.abs(vh[-1])
            return [names[i] for i in np.argsort(-v) if v[i] > 0.1 * v.max()], lam
    return None


def _check_observable(names, A, C_rows):
    """PBH test on the scaled continuous model; raise EstimatorError naming unseen states."""
    found = _unobservable_mode(names, A, C_rows, _SCALES)
    if found is not None:
        seen, lam = found
        raise EstimatorError(
            f'the sensor set cannot observe the state(s) {", ".join(seen)} (mode '
            f'{complex(lam):.3g} rad/s); add a sensor (e.g. the suspension position '
            'sensor) or drop the state (estimate_force / estimate_bias)')


def design_estimator(params, dt, sensors, *, road_class='C', speed_m_s=20.0,
                     estimate_force=True, estimate_bias=True, q_force=1.0e7, q_bias=1.0e-4,
                     force_tau_s=0.05):
    """
    Design the Kalman filter of a corner (``control.dlqe`` on the exactly discretised car).

    Parameters
    ----------
    params : QuarterCarParams
        Car parameters the filter assumes (nominal).
    dt : float
        Control period [s].
    sensors : dict
        ``{name: SensorSpec}`` with names of :data:`quarter_car_sim.sensors.SENSOR_NAMES`; the
        spec gives the noise variance (``variance``) and the latency (``latency_s``, rounded to
        whole periods).
    road_class : str
        ISO 8608 class of the design road (process noise of the road velocity).
    speed_m_s : float
        Design speed [m/s].
    estimate_force : bool
        Include the force-error state ``d`` (random walk of intensity ``q_force`` [N^2/s]).
    estimate_bias : bool
        Include an accelerometer bias state per accelerometer (random walk, ``q_bias``
        [(m/s^2)^2/s]).
    q_force, q_bias : float
        Driving white-noise intensities of the force error and of the biases.
    force_tau_s : float
        Correlation time [s] of the force error (first-order Gauss-Markov: what the damper
        model misses comes and goes with the motion; a lasting offset is an accelerometer bias
        or a fault); ``math.inf``: a random walk.

    Returns
    -------
    EstimatorDesign

    Raises
    ------
    EstimatorError
        Bad settings, an unknown sensor, or a sensor set that cannot observe every state.

    """
    import control
    if not (math.isfinite(dt) and dt > 0):
        raise EstimatorError(f'`dt` must be > 0, got {dt}')
    sensors = dict(sensors)
    unknown = sorted(set(sensors) - set(SENSOR_NAMES))
    if unknown:
        raise EstimatorError(f'unknown sensor(s) {", ".join(unknown)} (use '
                             f'{", ".join(SENSOR_NAMES)})')
    if not sensors:
        raise EstimatorError('no sensors: nothing to estimate from')
    if not force_tau_s > 0:
        raise EstimatorError(f'`force_tau_s` must be > 0, got {force_tau_s}')
    for name, q in (('q_force', q_force), ('q_bias', q_bias)):
        if not (math.isfinite(q) and q > 0):
            raise EstimatorError(f'`{name}` must be > 0, got {q}')
    order = tuple(s for s in SENSOR_NAMES if s in sensors)
    q_road = road_velocity_intensity(road_class, speed_m_s)
    names, A, B, G, W, C, D = _continuous(params, order, estimate_force, estimate_bias,
                                          q_road, q_force, q_bias, force_tau_s)
    _check_observable(names, A, [C[s] for s in order])
    n0 = len(names)
    # exact discretisation: F held over the period; Van Loan for the process noise
    M = np.zeros((2 * n0 + 1, 2 * n0 + 1))
    M[:n0, :n0] = -A * dt
    M[:n0, n0:2 * n0] = G @ W @ G.T * dt
    M[n0:2 * n0, n0:2 * n0] = A.T * dt
    E = expm(M[:2 * n0, :2 * n0])
    ad0 = E[n0:, n0:].T
    qd0 = ad0 @ E[:n0, n0:]
    qd0 = (qd0 + qd0.T) / 2.0
    Mb = np.zeros((n0 + 1, n0 + 1))
    Mb[:n0, :n0], Mb[:n0, n0] = A * dt, B * dt
    bd0 = expm(Mb)[:n0, n0]
    lat = {s: int(round(sensors[s].latency_s / dt)) for s in order}
    n = n0 + sum(lat.values())
    Ad = np.zeros((n, n))
    Ad[:n0, :n0] = ad0
    Bd = np.zeros(n)
    Bd[:n0] = bd0
    Qd = np.zeros((n, n))
    Qd[:n0, :n0] = qd0
    H = np.zeros((len(order), n))
    Dm = np.zeros(len(order))
    states = list(names)
    for r, s in enumerate(order):
        if lat[s] == 0:
            H[r, :n0], Dm[r] = C[s], D[s]
            continue
        first = len(states)
        for j in range(lat[s]):
            states.append(f'{s}_delay{j + 1}')
        Ad[first, :n0], Bd[first] = C[s], D[s]
        for j in range(1, lat[s]):
            Ad[first + j, first + j - 1] = 1.0
        H[r, first + lat[s] - 1] = 1.0
    R = np.diag([max(sensors[s].variance, 1e-18) for s in order])
    try:
        L, P, _ = control.dlqe(Ad, np.eye(n), H, Qd, R)
    except Exception as exc:      # noqa: B902 - python-control raises several types
        raise EstimatorError(f'control.dlqe found no steady-state filter: {exc}') from None
    L, P = np.asarray(L), np.asarray(P)
    P = (P + P.T) / 2.0
    S = H @ P @ H.T + R
    Mg = P @ H.T @ np.linalg.inv(S)
    P_post = P - Mg @ S @ Mg.T
    return EstimatorDesign(dt=float(dt), states=tuple(states), sensors=order,
                           latency_steps=lat, Ad=Ad, Bd=Bd, Qd=Qd, H=H, Dm=Dm, R=R, L=L, P=P,
                           P_post=(P_post + P_post.T) / 2.0, M=Mg, A=A, G=G, W=W,
                           params=params)


def _std(P):
    """Return the standard deviations of the car states and of ``v_rel`` from a covariance."""
    var_rel = P[1, 1] + P[3, 3] - 2.0 * P[1, 3]
    return tuple(math.sqrt(max(float(P[j, j]), 0.0)) for j in range(4)) + (
        math.sqrt(max(float(var_rel), 0.0)),)


@dataclasses.dataclass(slots=True)
class Estimate:
    """
    Estimated state of a corner at one control step (SI, conventions of ``params``).

    Duck-types the fields a control law reads (``t, v_s, a_s, v_u, travel, v_rel, z_u, z_r``,
    with ``z_u`` the tyre deflection and ``z_r`` 0), so a law and the inverse model run on it.

    Attributes
    ----------
    t : float
        Time [s].
    travel, v_s, v_u, v_rel, a_s : float
        Suspension travel [m], body and wheel velocity [m/s], piston velocity [m/s], body
        acceleration [m/s^2] (gravity and bias removed).
    tyre_def : float
        Tyre deflection ``z_u - z_r`` [m].
    damper_force : float
        Known input: model damper force on the body [N] at this estimate.
    force_error : float
        Estimated force error ``d`` [N] (0 without that state).
    std : tuple of float
        Standard deviations of ``CAR_STATES`` and of ``v_rel``.
    valid : bool
        False when a fault makes the estimate unusable.
    reason : str
        ``''`` or the reason of :data:`INVALID_REASONS`.

    """

    t: float
    travel: float
    v_s: float
    tyre_def: float
    v_u: float
    v_rel: float
    a_s: float
    damper_force: float
    force_error: float
    std: tuple
    valid: bool
    reason: str

    @property
    def z_u(self):
        """Tyre deflection, as the ``z_u`` of a state with ``z_r`` 0 [m]."""
        return self.tyre_def

    @property
    def z_r(self):
        """Zero: the road height is folded into ``z_u`` (tyre deflection)."""
        return 0.0


class QuarterCarEstimator:
    """
    Time-varying Kalman filter of a corner with fault detection (one call per control step).

    Parameters
    ----------
    design : EstimatorDesign
        From :func:`design_estimator`.
    force_model : callable
        ``force_model(current_a, travel, v_rel) -> F`` damper force on the body [N] of the
        identified model (e.g. ``lambda i, x, v: -inverse.force(i, x, v)``).
    stuck_s : dict or float
        Time [s] a reading may repeat exactly before its sensor counts as stuck (per sensor
        or one for all); default 0.05 s for accelerometers, 0.25 s for the position sensor.
    dropout_s : float
        Longest time [s] without a reading of a sensor before the estimate is invalid.
    nis_window_s : float
        Window [s] of the normalised innovation squared (NIS) test.
    nis_threshold : float
        Limit on the window's mean NIS per sensor (about 1 when the filter is consistent; the
        default filter is deliberately loose on the accelerometer, whose mean NIS is about
        0.1-0.4 on the road, the travel sensor's 0.8-1).
    nis_cap : float
        Each sample's NIS enters the window mean capped at this value (a robust test: a
        force jump of the damper model, e.g. the ``sign(x)`` term of Kwok's model when the
        travel crosses zero a sample apart in the estimate and in the car, gives single-sample
        spikes; a diverging filter keeps the mean high).
    gravity : float
        Gravity removed from accelerometer readings [m/s^2].
    coil_tau_s : float
        Time constant [s] of the coil's first-order lag between the current given to
        :meth:`step` (the command) and the current that makes the force (0: none). The
        simulated dampers lag by 1/190 s (``mr_damper_model.models.plant``).
    travel_deadband_m : float or None
        The force model gets travel 0 while the estimated travel is within this band [m]
        (None: 3 steady-state standard deviations of the travel estimate): the sign of the
        travel is not known there, and a model with a ``sign(x)`` term (Kwok's) would flip
        its force with the noise of a car at rest; at 0 the term takes its mean, 0.
    steady_tol : float
        After a step without every reading the filter propagates its covariance; it returns to
        the steady-state gain once every element of the covariance is within this fraction
        (of the product of the two standard deviations) of the DARE posterior, checked every
        100 steps. At 1e-6 a single lost reading of the default design keeps it off the
        steady gain for about 7,500 steps, at 1e-3 for 17 (a time-varying step costs about
        twice a steady one).

    Attributes
    ----------
    x, P : ndarray
        State estimate and its covariance (posterior after :meth:`step`).
    invalid_entries : dict
        ``{reason: count}`` of entries into an invalid estimate.
    invalid_steps : int
        Steps answered invalid.
    samples_missing : dict
        ``{sensor: count}`` of expected readings that were NaN.
    steps : int

    """

    def __init__(self, design, force_model, *, stuck_s=None, dropout_s=0.02,
                 nis_window_s=0.5, nis_threshold=3.0, nis_cap=25.0, gravity=G0,
                 coil_tau_s=0.0, travel_deadband_m=None, steady_tol=1e-6):
        self.d = design
        self.force_model = force_model
        dt = design.dt
        for name, v in (('dropout_s', dropout_s), ('nis_window_s', nis_window_s),
                        ('nis_threshold', nis_threshold), ('nis_cap', nis_cap),
                        ('steady_tol', steady_tol)):
            if not (math.isfinite(v) and v > 0):
                raise EstimatorError(f'`{name}` must be > 0, got {v}')
        if not (math.isfinite(coil_tau_s) and coil_tau_s >= 0):
            raise EstimatorError(f'`coil_tau_s` must be >= 0, got {coil_tau_s}')
        self._coil_a = math.exp(-dt / coil_tau_s) if coil_tau_s > 0 else 0.0
        default_stuck = {'body_accel': 0.05, 'wheel_accel': 0.05, 'travel': 0.25}
        if stuck_s is None:
            stuck_s = default_stuck
        elif not isinstance(stuck_s, dict):
            stuck_s = dict.fromkeys(SENSOR_NAMES, float(stuck_s))
        self._stuck_n = {s: max(2, int(round(stuck_s.get(s, default_stuck[s]) / dt)))
                         for s in design.sensors}
        self.dropout_s = float(dropout_s)
        self._nis_n = max(1, int(round(nis_window_s / dt)))
        self.nis_threshold = float(nis_threshold)
        self.nis_cap = float(nis_cap)
        self.steady_tol = float(steady_tol)
        self.gravity = float(gravity)
        self._rows = [(s, design.H[r].copy(), float(design.Dm[r]), float(design.R[r, r]),
                       s != 'travel') for r, s in enumerate(design.sensors)]
        self._ix = {nm: i for i, nm in enumerate(design.states)}
        self._ifd = self._ix.get('force_error')
        p = design.params
        self._ms = p.m_s
        self._row_as = design.A[1]     # body acceleration from the base states (+ F / m_s)
        self._n0 = design.A.shape[0]
        self._n_rows = len(self._rows)
        S = design.H @ design.P @ design.H.T + design.R
        self._s_diag = [float(S[r, r]) for r in range(self._n_rows)]
        dp = np.sqrt(np.abs(np.diag(design.P_post)))
        self._p_scale = np.maximum(np.outer(dp, dp), 1e-300)
        self._std_post = _std(design.P_post)
        if travel_deadband_m is None:
            travel_deadband_m = 3.0 * self._std_post[0]
        if not (math.isfinite(travel_deadband_m) and travel_deadband_m >= 0):
            raise EstimatorError(f'`travel_deadband_m` must be >= 0, got {travel_deadband_m}')
        self.travel_deadband_m = float(travel_deadband_m)
        self.invalid_entries = dict.fromkeys(INVALID_REASONS, 0)
        self.reset()

    def reset(self):
        """Return to rest at static equilibrium with the steady-state covariance."""
        n = len(self.d.states)
        self.x = np.zeros(n)
        self.P = self.d.P.copy()
        self._steady = False
        self._tv_steps = 0
        self._f = 0.0
        self._i_coil = math.nan
        self._started = False
        self._last_seen = {}
        self._last_val = {s: math.nan for s in self.d.sensors}
        self._same = dict.fromkeys(self.d.sensors, 0)
        self._nis = {s: deque() for s in self.d.sensors}
        self._nis_sum = dict.fromkeys(self.d.sensors, 0.0)
        self.samples_missing = dict.fromkeys(self.d.sensors, 0)
        self.nis_mean = dict.fromkeys(self.d.sensors, 0.0)
        self.reason = 'no_data_yet'
        self.valid = False
        self.invalid_steps = 0
        self.steps = 0
        self.restarts = 0

    def _force(self):
        x = self.x
        travel = x[0] if abs(x[0]) > self.travel_deadband_m else 0.0
        return float(self.force_model(self._i_coil, travel, x[1] - x[3]))

    def step(self, t, readings, current_a):
        """
        Advance one control period and take the readings that arrived.

        Parameters
        ----------
        t : float
            Time [s] of this step.
        readings : dict
            ``{sensor: value}``: a float (a new reading, accelerometers as specific force with
            gravity), NaN (a lost sample) or None / absent (no sample due at this step).
        current_a : float
            Coil current [A] that makes the damper force from ``t`` on (the last command).

        Returns
        -------
        Estimate

        """
        d = self.d
        i = float(current_a)
        if self._i_coil != self._i_coil or not self._started:
            self._i_coil = i
        else:
            self._i_coil = i + (self._i_coil - i) * self._coil_a
        if self._started:
            self.x = d.Ad @ self.x + d.Bd * self._f
            if not self._steady:
                self.P = d.Ad @ self.P @ d.Ad.T + d.Qd
        else:
            self._started = True
            self._last_seen = dict.fromkeys(d.sensors, t)
        f_prior = self._force()
        # readings to use: (row, innovation) of each finite, not stuck sensor
        used = []
        for r, (s, h, dm, _, is_acc) in enumerate(self._rows):
            y = readings.get(s)
            if y is None:
                continue
            if y != y:
                self.samples_missing[s] += 1
                continue
            self._last_seen[s] = t
            if y == self._last_val[s]:
                self._same[s] += 1
            else:
                self._same[s] = 0
                self._last_val[s] = y
            if self._same[s] + 1 >= self._stuck_n[s]:
                continue                      # a stuck sensor is not used
            if is_acc:
                y -= self.gravity
            used.append((r, y - float(h @ self.x) - dm * f_prior))
        if self._steady and len(used) != self._n_rows:
            self._steady = False              # P was the steady posterior: now the prior
            self.P = d.P.copy()
        if self._steady:
            # every sensor read: the steady-state filter (the DARE's gain and covariance)
            e = np.array([v for _, v in used])
            self.x = self.x + d.M @ e
            s_diag = self._s_diag
        else:
            s_diag = [float(self._rows[r][1] @ self.P @ self._rows[r][1]) + self._rows[r][3]
                      for r, _ in used]
            s_diag = dict(zip((r for r, _ in used), s_diag))
            for r, _ in used:
                s_name, h, dm, rr, is_acc = self._rows[r]
                ph = self.P @ h
                sv = float(h @ ph) + rr
                y = readings[s_name] - (self.gravity if is_acc else 0.0)
                k = ph / sv
                self.x = self.x + k * (y - float(h @ self.x) - dm * f_prior)
                self.P = self.P - np.outer(k, ph)
            self.P = (self.P + self.P.T) * 0.5
            self._tv_steps += 1
            if self._tv_steps % 100 == 0 and len(used) == self._n_rows:
                dev = np.abs(self.P - d.P_post) / self._p_scale
                if float(dev.max()) < self.steady_tol:
                    self._steady = True
                    self.P = d.P_post.copy()
        # normalised innovation squared of each sensor (innovation of the predicted state)
        for r, e in used:
            s = self._rows[r][0]
            nis = min(e * e / s_diag[r], self.nis_cap)
            win = self._nis[s]
            win.append(nis)
            self._nis_sum[s] += nis
            if len(win) > self._nis_n:
                self._nis_sum[s] -= win.popleft()
            self.nis_mean[s] = self._nis_sum[s] / len(win)
        faults = []
        for s in d.sensors:
            if t - self._last_seen[s] > self.dropout_s:
                faults.append(f'dropout_{s}')
            if self._same[s] + 1 >= self._stuck_n[s]:
                faults.append(f'stuck_{s}')
            if len(self._nis[s]) >= self._nis_n and self.nis_mean[s] > self.nis_threshold:
                faults.append(f'innovation_{s}')
        if not math.isfinite(float(self.x.sum())) or (
                not self._steady and not math.isfinite(float(self.P.sum()))):
            faults.insert(0, 'diverged')
            self.restarts += 1
            self.x = np.zeros(len(d.states))
            self.P = d.P.copy()
            self._steady = False
        self._f = self._force()
        reason = faults[0] if faults else ''
        if reason and reason != self.reason:
            self.invalid_entries[reason] += 1
        valid = not reason
        if not valid:
            self.invalid_steps += 1
        self.reason, self.valid = reason, valid
        self.steps += 1
        return self._estimate(t)

    @property
    def steady(self):
        """Whether the filter runs on the steady-state gain (covariance = DARE posterior)."""
        return self._steady

    def _estimate(self, t):
        x = self.x
        fd = x[self._ifd] if self._ifd is not None else 0.0
        x0, x1, x2, x3 = x[0], x[1], x[2], x[3]
        ra = self._row_as
        a_s = float(ra[0] * x0 + ra[1] * x1 + ra[3] * x3 + (self._f + fd) / self._ms)
        if self._steady:
            std = self._std_post
        else:
            std = _std(self.P)
        return Estimate(t=float(t), travel=float(x0), v_s=float(x1), tyre_def=float(x2),
                        v_u=float(x3), v_rel=float(x1 - x3), a_s=a_s,
                        damper_force=self._f, force_error=float(fd), std=std,
                        valid=self.valid, reason=self.reason)

    def status(self):
        """Return the counters and the last NIS means as a JSON-ready dict."""
        return {'valid': self.valid, 'reason': self.reason, 'steps': self.steps,
                'invalid_steps': self.invalid_steps,
                'invalid_entries': {k: v for k, v in self.invalid_entries.items() if v},
                'samples_missing': dict(self.samples_missing),
                'nis_mean': dict(self.nis_mean), 'restarts': self.restarts}
