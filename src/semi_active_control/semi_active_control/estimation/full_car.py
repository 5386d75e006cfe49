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

A vehicle computer (``semi_active_control``) designs it on all four body accelerometers of the
chassis bus (``accel_corners``) and runs it with ``degrade=True``: a sensor that dropped out,
repeats one reading (``stuck_<sensor>``) or reads at the end of its range (``range_<sensor>``)
is named, counted and left out, and the estimate stays valid while at least three
accelerometers (three points of the rigid body fix heave, pitch and roll) and three position
sensors are left and that set observes the car (PBH test,
:func:`semi_active_control.estimation.quarter_car.unobserved_states`).

Slightly over the project's ~600 lines: the filter's model, its noise design and the
steady-state gain are one derivation and stay in one module.
"""
from collections import namedtuple
import math

import numpy as np
from scipy.linalg import expm

from semi_active_control.car.full_car import CORNERS
from semi_active_control.car.full_car_linear import FullCarState, N_Q, state_matrices
from semi_active_control.estimation.gain_schedule import (GainSchedule, kalman_update,
                                                          near_steady, predict_covariance,
                                                          STEADY_CHECK_STEPS)
from semi_active_control.estimation.quarter_car import (EstimatorError, road_velocity_intensity,
                                                        unobserved_states)
from semi_active_control.estimation.sensor_specs import accelerometer_spec, G0, ride_height_spec

#: Corners whose body point carries an accelerometer (the offline sensor set).
ACCEL_CORNERS = ('fl', 'fr', 'rl')
#: Sensor names of the offline set, in the order of the measurement rows.
SENSORS = tuple(f'accel_{c}' for c in ACCEL_CORNERS) + tuple(f'travel_{c}' for c in CORNERS)
#: State groups of the estimate (for error statistics).
STATE_GROUPS = {'travel': slice(0, 4), 'tyre_def': slice(4, 8), 'body_rates': slice(8, 11),
                'wheel_v': slice(11, 15)}
#: States of the car part (travels, tyre deflections, the seven rates); then one bias per
#: accelerometer.
N_CAR = 15
N_E = N_CAR + len(ACCEL_CORNERS)
#: Typical size of each state kind [SI] (scaling of the observability test).
STATE_SCALES = {'travel': 0.01, 'tyre_def': 0.002, 'rate': 0.1, 'wheel_v': 0.3, 'bias': 0.1,
                'force': 300.0}


def _diag_std(P):
    """Return the standard deviations of a covariance's states (round-off negatives as 0)."""
    return np.sqrt(np.maximum(np.diag(P), 0.0))


def _accel_rows(params, accel_corners=ACCEL_CORNERS):
    return [CORNERS.index(c) for c in accel_corners]


def state_names(accel_corners=ACCEL_CORNERS, force_states=False):
    """Return the estimator's state names (``travel_fl``, ..., ``bias_accel_<c>``, ...)."""
    return ([f'travel_{c}' for c in CORNERS] + [f'tyre_def_{c}' for c in CORNERS]
            + ['rate_heave', 'rate_pitch', 'rate_roll'] + [f'wheel_v_{c}' for c in CORNERS]
            + [f'bias_accel_{c}' for c in accel_corners]
            + ([f'force_{c}' for c in CORNERS] if force_states else []))


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


def _continuous(params, accel_corners=ACCEL_CORNERS):
    """Return ``A, B (forces), G (road velocity, biases), C, D`` of the estimator's state."""
    A7, B7 = state_matrices(params)
    T = params.geometry
    rows = _accel_rows(params, accel_corners)
    na = len(rows)
    n = N_CAR + na
    S = np.hstack([T, -np.eye(4)])
    P = np.hstack([np.zeros((4, 3)), np.eye(4)])
    kt, ct = params.k_t, params.c_t
    minv = np.diag(1.0 / np.diag(params.mass_matrix))
    acc_v = A7[N_Q:, N_Q:]                      # rate feedback (springs via positions below)
    K_tr = -minv @ S.T @ params.spring_matrix()  # acceleration per travel
    K_td = -minv @ P.T * kt                      # per tyre deflection
    A = np.zeros((n, n))
    A[0:4, 8:15] = S
    A[4:8, 8:15] = P
    A[8:15, 0:4] = K_tr
    A[8:15, 4:8] = K_td
    A[8:15, 8:15] = acc_v
    B = np.zeros((n, 4))
    B[8:15] = B7[N_Q:, 8:12]
    G = np.zeros((n, 4 + na))
    G[4:8, 0:4] = -np.eye(4)
    G[8:15, 0:4] = minv @ P.T * ct
    G[N_CAR:, 4:] = np.eye(na)
    C = np.zeros((na + 4, n))
    D = np.zeros((na + 4, 4))
    C[0:na] = T[rows] @ A[8:11]
    C[0:na, N_CAR:] = np.eye(na)
    D[0:na] = T[rows] @ B[8:11]
    C[na:, 0:4] = np.eye(4)
    return A, B, G, C, D


def _check_accel_corners(params, accel_corners):
    corners = tuple(accel_corners)
    if len(set(corners)) != len(corners) or not set(corners) <= set(CORNERS):
        raise EstimatorError(f'`accel_corners` must be distinct corners of {CORNERS}, got '
                             f'{corners!r}')
    if len(corners) < 3 or np.linalg.matrix_rank(
            params.geometry[_accel_rows(params, corners)]) < 3:
        raise EstimatorError('`accel_corners` must hold three points of the body that are not '
                             f'on one line (heave, pitch and roll), got {corners!r}')
    return corners


class FullCarDesign:
    """Discrete filter of :func:`design_full_car_estimator` (attributes as the quarter car's)."""

    def __init__(self, **kw):
        self.__dict__.update(kw)


def design_full_car_estimator(params, dt, *, accel=None, travel=None, road_class='C',
                              speed_m_s=20.0, q_bias=1.0e-4, accel_corners=ACCEL_CORNERS,
                              force_states=False, q_force=1.0e8, force_tau_s=0.05):
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
    accel_corners : sequence of str
        Corners whose body point carries an accelerometer (at least three, not on one line;
        default :data:`ACCEL_CORNERS`; a vehicle bus may carry all four).
    force_states : bool
        Estimate the four damper forces as states (first-order Gauss-Markov processes of
        correlation time ``force_tau_s`` driven by white noise of intensity ``q_force``
        [N^2/s], seen through the accelerometers and the travels' dynamics) instead of taking
        them as a known input only: for a vehicle, whose damper force is not measured and whose
        identified model, evaluated at the estimate and held over a cycle, is a stiff feedback
        that makes the filter diverge (an MR damper's force changes by tens of kN per m/s near
        zero velocity). The known input (``forces`` of a step) is then added to them.
    q_force : float
        Driving intensity of the force states [N^2/s] (1e8: a 2 ms cycle's force change of
        about 450 N, one standard deviation; 1.6 kN stationary at 0.05 s).
    force_tau_s : float
        Correlation time of the force states [s] (a random walk, the limit of a long one,
        leaves the Riccati equation ill-conditioned: ``dlqe`` then finds no solution).

    Returns
    -------
    FullCarDesign
        With ``sensors`` (the measurement rows' names), ``accel_corners`` and ``names`` (the
        states').

    """
    import control
    if not (math.isfinite(dt) and dt > 0):
        raise EstimatorError(f'`dt` must be > 0, got {dt}')
    accel_corners = _check_accel_corners(params, accel_corners)
    na = len(accel_corners)
    accel = accelerometer_spec() if accel is None else accel
    travel = ride_height_spec() if travel is None else travel
    A, B, G, C, D = _continuous(params, accel_corners)
    W = np.diag([road_velocity_intensity(road_class, speed_m_s)] * 4 + [q_bias] * na)
    n = N_CAR + na
    if force_states:
        A, G, C, W = _with_force_states(A, B, G, C, D, W, q_force, force_tau_s)
        B = np.vstack([B, np.zeros((4, 4))])
        n += 4
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
    R = np.diag([max(accel.variance, 1e-18)] * na + [max(travel.variance, 1e-18)] * 4)
    try:
        L, P, _ = control.dlqe(Ad, np.eye(n), C, Qd, R)
    except Exception as exc:      # noqa: B902 - python-control raises several types
        raise EstimatorError(f'control.dlqe found no steady-state filter: {exc}') from None
    P = np.asarray(P)
    P = (P + P.T) / 2.0
    S = C @ P @ C.T + R
    Mg = P @ C.T @ np.linalg.inv(S)
    sensors = tuple(f'accel_{c}' for c in accel_corners) + tuple(f'travel_{c}' for c in CORNERS)
    return FullCarDesign(dt=float(dt), Ad=Ad, Bd=Bd, Qd=Qd, H=C, Dm=D, R=R, L=np.asarray(L),
                         P=P, M=Mg, A=A, B=B, params=params, accel=accel, travel=travel,
                         sensors=sensors, accel_corners=accel_corners,
                         names=state_names(accel_corners, force_states),
                         force_slice=slice(n - 4, n) if force_states else None)


def _with_force_states(A, B, G, C, D, W, q_force, tau_s):
    """Append four Gauss-Markov force states to ``A, G, C, W`` (they act as ``B`` does)."""
    n = A.shape[0]
    A2 = np.zeros((n + 4, n + 4))
    A2[:n, :n] = A
    A2[:n, n:] = B
    A2[n:, n:] = -np.eye(4) / float(tau_s)
    G2 = np.zeros((n + 4, G.shape[1] + 4))
    G2[:n, :G.shape[1]] = G
    G2[n:, G.shape[1]:] = np.eye(4)
    C2 = np.hstack([C, D])
    W2 = np.diag(np.concatenate([np.diag(W), [float(q_force)] * 4]))
    return A2, G2, C2, W2


def observes_the_car(design, sensors):
    """
    Whether a subset of the design's sensors observes every state (PBH test).

    Parameters
    ----------
    design : FullCarDesign
        The filter's design (its continuous model and measurement rows).
    sensors : iterable of str
        Sensor names of ``design.sensors``.

    Returns
    -------
    bool

    """
    sensors = set(sensors)
    # the bias of an accelerometer left out is a state no output uses: not part of the test
    keep = [i for i, nm in enumerate(design.names)
            if not nm.startswith('bias_') or nm[len('bias_'):] in sensors]
    names = [design.names[i] for i in keep]
    rows = [design.H[design.sensors.index(s)][keep] for s in design.sensors if s in sensors]
    scales = {nm: STATE_SCALES[next(k for k in STATE_SCALES if nm.startswith(k))]
              for nm in names}
    return not unobserved_states(names, design.A[np.ix_(keep, keep)], rows, scales)


#: The compiled steady step of one filter (:mod:`~.steady_step`): the kernel, its fixed model
#: arguments (gravity, Ad, Bd, H, Dm, M), its screen's arguments (stuck runs, gate, steady
#: innovation scale, low and high ranges), and two buffers (repeat runs out, work space).
SteadyStep = namedtuple('SteadyStep', 'kernel fixed screen runs work')


class FullCarEstimator:
    """
    Time-varying Kalman filter of the full car on the readings of ``design.sensors``.

    Parameters
    ----------
    design : FullCarDesign
    dropout_s : float
        A sensor with no reading for this long makes the estimate invalid (with ``degrade``:
        is left out, named ``dropout_<sensor>``).
    delay_steps : int
        Sensor latency in control periods the filter accounts for: 0 (a reading delivered
        now is taken as of now) or 1 (as of the previous step, the default sensors' 1 ms at
        1 kHz: the reading updates the previous step's state with the previous forces, then
        the filter predicts to now; no extra states).
    gravity : float
        Subtracted from each accelerometer reading [m/s^2] (:data:`G0`: readings of specific
        force, as a sensor gives them; 0: readings with gravity removed, as the chassis bus
        carries them).
    stuck_s : dict, optional
        ``{'accel': s, 'travel': s}``: a sensor repeating exactly one reading for this long is
        stuck (``stuck_<sensor>``) and not used (None: no stuck test).
    ranges : dict, optional
        ``{'accel': (lo, hi), 'travel': (lo, hi)}`` in the readings' units: a reading at or
        beyond either end (a saturated sensor or frame signal) is not used
        (``range_<sensor>``; None: no range test).
    degrade : bool
        False: any sensor fault makes the estimate invalid (the offline behaviour). True: a
        faulty sensor is left out and the estimate stays valid while three accelerometers and
        three position sensors are left and they observe the car (:func:`observes_the_car`);
        else invalid with reason ``too_few_sensors``.
    repeat_gate : float, optional
        With ``stuck_s``: a reading equal to its sensor's previous one and more than this many
        innovation standard deviations from the prediction is stuck at once (a sensor that
        froze while the car moves disagrees within a few periods, long before ``stuck_s`` of
        repeats; a frozen reading taken for that long corrupts the accelerometer biases for
        seconds). None: only ``stuck_s``.
    steady_tol : float, optional
        Run on the steady-state gain (the DARE's, a few array operations per step) while
        every sensor is read and the covariance is within this relative distance of the
        steady posterior (checked every 100 steps); None: always the time-varying filter.
        With it, the gains from the start until then are worked out once, at design
        (:class:`~semi_active_control.estimation.gain_schedule.GainSchedule`), and each clean
        cycle that follows them runs compiled with its step's gain (unless
        ``gain_schedule`` is False: the general step on every cycle until then).
    bias_std0 : float, optional
        Standard deviation of each accelerometer's bias at the start [m/s^2] (a MEMS part's
        turn-on bias, e.g. the ADXL313's 15 mg): added to the start covariance's bias
        variances, so the filter learns a turn-on bias within seconds of driving. None: the
        start covariance is the design's steady one, whose bias variance is that of a bias the
        filter has tracked for long: a turn-on bias then takes minutes to learn, and until then
        the body velocities drift (modal skyhook on the vehicle chain, a minute of road, force
        states at 1e8: +3.9 % of a_v against lock-step without, +3.0 % with the ADXL313's;
        ``bench/bench_vehicle_chain.py``).

    Attributes
    ----------
    x : ndarray (n,)
        Posterior state; ``P`` its covariance.
    schedule : GainSchedule or None
        The gains from the start to the steady gain, worked out at design (``steady_tol``
        and the compiled step; None without them or with ``gain_schedule`` False).
    valid : bool
    reason : str
        Why invalid ('' when valid).
    faults : list of str
        Sensors not used at the last step, with their fault (``dropout_accel_fr``, ...).
    n_invalid : dict
        Steps invalid per reason.
    n_steps, n_compiled : int
        Steps, and of them the clean ones run compiled (:mod:`~.steady_step`): on the steady
        gain, or on the gain schedule from the start.
    fault_entries, fault_steps : dict
        Per sensor fault name: entries (the fault appearing) and steps it lasted.

    """

    def __init__(self, design, *, dropout_s=0.02, delay_steps=0, gravity=G0, stuck_s=None,
                 ranges=None, degrade=False, repeat_gate=None, steady_tol=None,
                 bias_std0=None, gain_schedule=True):
        if delay_steps not in (0, 1):
            raise EstimatorError(f'`delay_steps` must be 0 or 1, got {delay_steps!r}')
        self.d = design
        self.sensors = tuple(getattr(design, 'sensors', SENSORS))
        self.dropout_s = float(dropout_s)
        self.delay_steps = int(delay_steps)
        self.degrade = bool(degrade)
        kinds = [s.split('_')[0] for s in self.sensors]
        self._is_acc = np.array([k == 'accel' for k in kinds])
        self._gravity = np.where(self._is_acc, float(gravity), 0.0)
        self._stuck_n = (np.array([max(2, int(round(float(stuck_s[k]) / design.dt)))
                                   for k in kinds]) if stuck_s else None)
        self._lo = self._hi = None
        if ranges:
            self._lo = np.array([float(ranges[k][0]) for k in kinds])
            self._hi = np.array([float(ranges[k][1]) for k in kinds])
        self.steady_tol = None if steady_tol is None else float(steady_tol)
        self._gate2 = None if repeat_gate is None else float(repeat_gate) ** 2
        H = design.H
        self._s_steady = np.einsum('ij,jk,ik->i', H, design.P, H) + np.diag(design.R)
        self._P_post = design.P - design.M @ H @ design.P
        self._P_post = (self._P_post + self._P_post.T) / 2.0
        # the standard deviations while the steady gain runs (the steady posterior): once
        self._std_post = _diag_std(self._P_post)
        self._std_post.setflags(write=False)
        dp = np.sqrt(np.abs(np.diag(self._P_post)))
        self._p_scale = np.maximum(np.outer(dp, dp), 1e-300)
        self._r = np.diag(design.R).copy()
        self._T_pinv = np.linalg.pinv(design.params.geometry)
        self._S = np.hstack([design.params.geometry, -np.eye(4)])
        self._observable = {}
        # the repeat counts and stuck flags of a cycle where no reading repeated (read-only:
        # shared by every such cycle)
        # (not written: replaced when a sensor repeats; writable only so that the compiled
        # steady step takes it as it takes any other)
        self._no_runs = np.zeros(len(self.sensors), dtype=np.int64)
        self._none_stuck = np.zeros(len(self.sensors), dtype=bool)
        self._none_stuck.setflags(write=False)
        self._P_start = design.P.copy()
        if bias_std0 is not None:
            if not (math.isfinite(bias_std0) and bias_std0 >= 0):
                raise EstimatorError(f'`bias_std0` must be >= 0, got {bias_std0}')
            bias = [i for i, nm in enumerate(design.names) if nm.startswith('bias_')]
            self._P_start[bias, bias] += float(bias_std0) ** 2
        self._P_start.setflags(write=False)
        self.fault_entries = {}
        self.fault_steps = {}
        self._fast = self._steady_kernel()
        self.schedule = None
        if self._fast is not None and self.steady_tol is not None and gain_schedule:
            self.schedule = GainSchedule(design.Ad, design.Qd, H, self._r, self._P_start,
                                         self._P_post, self._p_scale, self.steady_tol)
            # the schedule's steps run the steady kernel with their gain in the steady one's
            # place and without the repeat gate (the general path gates repeats only on the
            # steady gain)
            self._tv_fixed = self._fast.fixed[:-1]
            self._tv_screen = (self._fast.screen[0], math.nan) + self._fast.screen[2:]
        self.reset()

    def _steady_kernel(self):
        """
        Return the compiled steady step and its arguments, a :class:`SteadyStep`.

        None: this filter has none (one step of delay, no stuck screen, or a ``dropout_s``
        that drops out every sensor, which the general path names).
        """
        if self.delay_steps or self._stuck_n is None or not self.dropout_s >= 0.0:
            return None
        from semi_active_control.estimation.steady_step import steady_step_kernel
        d, m = self.d, len(self.sensors)
        c = np.ascontiguousarray
        lo = c(self._lo) if self._lo is not None else np.full(m, -np.inf)
        hi = c(self._hi) if self._hi is not None else np.full(m, np.inf)
        fixed = (c(self._gravity, dtype=float), c(d.Ad), c(d.Bd), c(d.H), c(d.Dm), c(d.M))
        screen = (c(self._stuck_n, dtype=np.int64),
                  math.nan if self._gate2 is None else self._gate2, c(self._s_steady), lo, hi)
        kernel, n = steady_step_kernel(), d.Ad.shape[0]
        # compiled (or loaded from the cache) now, not in the first steady cycle: a call with
        # this filter's types that does nothing (no reading)
        kernel(np.zeros(n), np.zeros(4), np.zeros(4), np.full(m, math.nan), 0.0, *fixed,
               np.zeros(m), np.zeros(m), np.zeros(m, dtype=np.int64),
               np.zeros(m, dtype=np.int64), *screen, np.empty(n + m))
        return SteadyStep(kernel, fixed, screen, np.zeros(m, dtype=np.int64), np.empty(n + m))

    def reset(self, x0=None, P0=None):
        """
        Start at ``x0`` (default the static equilibrium) with covariance ``P0``.

        ``P0`` defaults to the steady-state covariance of the design, its bias variances
        widened by ``bias_std0``; a start that may be far off needs a wider one.
        """
        n = self.d.Ad.shape[0]
        m = len(self.sensors)
        self.x = np.zeros(n) if x0 is None else np.asarray(x0, dtype=float).copy()
        self.P = (self._P_start if P0 is None else np.asarray(P0, dtype=float)).copy()
        self._steady = False
        self._tv_steps = 0
        # on the gain schedule: started at P_start, every sensor used on every step since
        self._on_schedule = self.schedule is not None and P0 is None
        self._f = np.zeros(4)
        self._seen = np.full(m, math.nan)       # time of each sensor's last finite reading
        self._ever = np.zeros(m, dtype=bool)    # sensors that gave a reading since the start
        self._all_seen = False
        self._last_val = np.full(m, math.nan)
        self._same = np.zeros(m, dtype=int)
        self._why = None
        self._late = None
        self._t0 = None
        self.valid = False
        self.reason = 'no_data_yet'
        self.faults = []
        self.n_invalid = {}
        self.n_steps = 0
        self.n_compiled = 0

    @property
    def P(self):
        """The posterior covariance (from the gain schedule while its steps run compiled)."""
        if self._P_lag:
            self._P = self.schedule.covariance(self._tv_steps)
            self._P_lag = False
        return self._P

    @P.setter
    def P(self, value):
        self._P = value
        self._P_lag = False

    @property
    def steady(self):
        """Whether the filter runs on the steady-state gain (covariance = DARE posterior)."""
        return self._steady

    def readings_array(self, readings):
        """Return readings as an array in the order of ``sensors`` (NaN: none)."""
        if isinstance(readings, dict):
            return np.array([readings.get(s, math.nan) for s in self.sensors], dtype=float)
        return np.asarray(readings, dtype=float).reshape(len(self.sensors))

    def step(self, t, readings, forces):
        """
        Predict over the period that ends now, then take the readings that arrived.

        The prediction uses the forces of the previous call (held over the period, as the
        plants hold them); the accelerometer rows use ``forces``.

        Parameters
        ----------
        t : float
            Time [s] of the readings.
        readings : dict or array_like
            ``{sensor: value}`` or the values in the order of ``sensors`` (accelerometers:
            specific force unless ``gravity`` is 0); NaN or a missing key: nothing arrived.
        forces : array_like (4,)
            Damper forces on the body [N] now (held over the period that starts now).

        Returns
        -------
        ndarray (n,)

        """
        d = self.d
        y = self.readings_array(readings)
        if self._fast is not None and self.n_steps and self._all_seen and not self.faults:
            if self._steady:
                if self._fast_step(t, y, forces):
                    return self.x
            elif self._scheduled() and self._scheduled_step(t, y, forces):
                return self.x
        if self._t0 is None:
            self._t0 = t
            self._seen[:] = t                  # a sensor never heard of drops out from the start
        if self.n_steps and not self.delay_steps:
            self._predict()
        f_now = np.asarray(forces, dtype=float).reshape(4)
        # with one step of delay the readings are of the previous step (its forces)
        f_meas = self._f if self.delay_steps and self.n_steps else f_now
        got = np.isfinite(y)
        np.copyto(self._seen, t, where=got)
        e = y - self._gravity - d.H @ self.x - d.Dm @ f_meas
        use = got & ~self._screen(y, got, e)
        every = bool(use.all())
        if self._steady and not every:
            self._steady = False             # P was the steady posterior: now the prior
            self.P = d.P.copy()
        if not every:
            self._on_schedule = False
        if self._steady:
            self.x = self.x + d.M @ e
        elif every or use.any():
            K, self.P = kalman_update(self.P, d.H[use], self._r[use])
            self.x = self.x + K @ e[use]
            self._tv_steps += 1
            if (self.steady_tol is not None and every
                    and self._tv_steps % STEADY_CHECK_STEPS == 0
                    and near_steady(self.P, self._P_post, self._p_scale, self.steady_tol)):
                self._steady = True
                self.P = self._P_post.copy()
        if self.delay_steps and self.n_steps:
            self._predict()
        self._f = f_now.copy()
        self.n_steps += 1
        self._judge(t, use, got, every)
        if not np.all(np.isfinite(self.x)):
            self.reason = 'diverged'
            self.x = np.zeros(len(self.x))
            self.P = self._P_start.copy()
            self._steady = False
            self._on_schedule = False        # P restarts, the step count goes on
        self.valid = not self.reason
        if self.reason:
            self.n_invalid[self.reason] = self.n_invalid.get(self.reason, 0) + 1
        return self.x

    def _scheduled(self):
        """Whether the next step is one of the gain schedule's (on it, and within it)."""
        return self._on_schedule and self._tv_steps < self.schedule.n_steps

    def _scheduled_step(self, t, y, forces):
        """Run a clean cycle compiled on the schedule's gain; False: not one, nothing done."""
        schedule = self.schedule
        fixed = self._tv_fixed + (schedule.gains[self._tv_steps],)
        if not self._fast_step(t, y, forces, fixed, self._tv_screen):
            return False
        self._tv_steps += 1
        self._P_lag = True          # P is the schedule's: worked out when it is read
        if self._tv_steps == schedule.steady_after:
            self._steady = True
            self.P = self._P_post.copy()
        return True

    def _fast_step(self, t, y, forces, fixed=None, screen=None):
        """
        Run a clean cycle compiled (:mod:`~.steady_step`); False: not one, nothing done.

        Clean: every reading there, none stuck or out of range, as on the cycle before (the
        caller checks that no sensor is faulty and every one has been seen). What the step's
        general path then does ends with the estimate valid and nothing counted. The steady
        gain's arguments unless ``fixed`` and ``screen`` are given (a scheduled step's).
        """
        fast = self._fast
        runs = fast.runs
        f_now = np.ascontiguousarray(forces, dtype=float).reshape(4)
        x = self.x.copy()           # a new array per step, as the general path's
        if not fast.kernel(x, self._f, f_now, np.ascontiguousarray(y), float(t),
                           *(fixed or fast.fixed), self._seen, self._last_val, self._same,
                           runs, *(screen or fast.screen), fast.work):
            return False
        self.x = x
        self._same = runs
        self._late = self._none_stuck
        self._f = f_now.copy()
        self.n_steps += 1
        self.n_compiled += 1
        self.reason = ''
        self.valid = True
        return True

    def _screen(self, y, got, e):
        """Return the mask of readings not to use (stuck, out of range); ``_why`` says which."""
        bad = None
        if self._stuck_n is not None:
            # a reading equal to the last one extends the run; another (or none) ends it
            same = y == self._last_val
            repeats = bool(same.any())
            np.copyto(self._last_val, y, where=got)
            if not repeats:
                # every run ended (the stuck counts are at least 2: none is stuck now)
                self._same = self._no_runs
                stuck = self._late = self._none_stuck
            else:
                self._same = (self._same + 1) * same
                stuck = self._same + 1 >= self._stuck_n
                # found out only after stuck_s of repeats: its readings were taken until now
                self._late = stuck & (self._same + 1 == self._stuck_n)
            if self._gate2 is not None and self._steady and repeats:
                # the gate needs the converged filter (steady: every sensor read)
                frozen = same & (e * e > self._gate2 * self._s_steady)
                # frozen and disagreeing: stuck now, and for as long as it repeats
                self._same = np.where(frozen, np.maximum(self._same, self._stuck_n),
                                      self._same)
                stuck |= frozen
            bad = stuck
        out = None
        if self._lo is not None:
            out = (y <= self._lo) | (y >= self._hi)       # NaN: False (not a reading)
            bad = out if bad is None else bad | out
        if bad is None:
            return np.zeros(len(y), dtype=bool)
        if bad.any():
            # a saturated reading also repeats: it is named out of range
            self._why = np.where(out, 'range', 'stuck') if out is not None else \
                np.full(len(y), 'stuck')
        return bad

    def _judge(self, t, use, got, every=False):
        """Name the faulty sensors and decide whether the estimate may be used."""
        if self._late is not None and self._late.any():
            self._widen()
        if every and self._all_seen and not self.faults and self.dropout_s >= 0.0:
            # every sensor read and was used, as on the cycle before: none is dropped out
            # (each was seen now), none is out, nothing to name (what follows, shortened)
            self.reason = ''
            return
        if not self._all_seen:
            self._ever |= got
            self._all_seen = bool(self._ever.all())
        dropped = (t - self._seen) > self.dropout_s
        out = dropped | (got & ~use)
        if self.faults or out.any():
            faults = []
            for k in np.flatnonzero(out):
                kind = 'dropout' if dropped[k] or not got[k] else str(self._why[k])
                faults.append(f'{kind}_{self.sensors[k]}')
            for f in faults:
                if f not in self.faults:
                    self.fault_entries[f] = self.fault_entries.get(f, 0) + 1
                self.fault_steps[f] = self.fault_steps.get(f, 0) + 1
            self.faults = faults
        if not self.degrade:
            self.reason = ''
            if not self._all_seen:
                self.reason = 'no_data_yet'
            elif dropped.any():
                self.reason = f'dropout_{self.sensors[int(np.argmax(dropped))]}'
            return
        if not self.faults and self._all_seen:
            self.reason = ''
            return
        live = ~out & self._ever
        if not live.any():
            self.reason = 'no_data_yet'
        else:
            self.reason = '' if self._sufficient(live) else 'too_few_sensors'

    def _widen(self):
        """
        Widen the covariance after a sensor was found stuck by its run of repeats.

        The readings taken before the sensor was found out pulled the estimate; with a wide
        covariance the good sensors take it back within a few tenths of a second instead of
        the seconds the accelerometer biases need at the steady gain.
        """
        self._steady = False
        self._on_schedule = False
        self.P = self.P + np.diag([STATE_SCALES[next(k for k in STATE_SCALES
                                                     if nm.startswith(k))] ** 2
                                   for nm in self.d.names])

    def _sufficient(self, live):
        key = live.tobytes()
        ok = self._observable.get(key)
        if ok is None:
            n_acc = int((live & self._is_acc).sum())
            ok = (n_acc >= 3 and int(live.sum()) - n_acc >= 3
                  and observes_the_car(self.d, [s for s, u in zip(self.sensors, live) if u]))
            self._observable[key] = ok
        return ok

    @property
    def forces(self):
        """Damper forces of the last step on the body [N] (held over the period after it)."""
        return self._f

    def prediction(self):
        """Return the state predicted one period on from the last step, before its readings."""
        d = self.d
        return d.Ad @ self.x + d.Bd @ self._f

    def _predict(self):
        d = self.d
        self.x = d.Ad @ self.x + d.Bd @ self._f
        if not self._steady:
            self.P = predict_covariance(self.P, d.Ad, d.Qd)

    def std(self):
        """Return the standard deviations of the states (read-only while the gain is steady)."""
        if self._steady:
            return self._std_post
        if self._P_lag:
            return self.schedule.std[self._tv_steps - 1]
        return _diag_std(self.P)

    def body_accelerations(self):
        """Return the seven accelerations ``[zdd, thetadd, phidd, wheels x4]`` of the estimate."""
        d = self.d
        return d.A[8:15] @ self.x + d.B[8:15] @ self._f

    def state(self, t):
        """Return the estimate as a :class:`FullCarState` (road heights 0: wheel = tyre_def)."""
        x = self.x
        travel, tyre, v = x[0:4].copy(), x[4:8].copy(), x[8:15].copy()
        T = self.d.params.geometry
        q = np.empty(N_Q)
        q[3:] = tyre
        q[:3] = self._T_pinv @ (travel + tyre)
        acc = self.body_accelerations()
        return FullCarState(float(t), q, v, acc, np.zeros(4), np.zeros(4),
                            travel, self._S @ v, np.full(4, math.nan), self._f.copy(),
                            np.full(4, math.nan), T @ v[:3], T @ acc[:3])
