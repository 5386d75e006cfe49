"""
Linear quarter-car analysis with python-control: state space, frequency responses, LQR.

Road-velocity formulation (used for the frequency responses and the LQR): state
``x = [z_s - z_u, v_s, z_u - z_r, v_u]`` (suspension travel [m], body velocity [m/s], tyre
deflection [m], wheel velocity [m/s]), inputs ``[zdot_r, F]`` (road velocity [m/s], force on the
body [N], positive up), outputs ``[a_s, travel, tyre_deflection, dynamic_tyre_load]``
([m/s^2], [m], [m], [N], tyre deflection positive when compressed is ``-(z_u - z_r)``, so the
dynamic tyre load is ``-k_t (z_u - z_r) - c_t (v_u - zdot_r)``). A linear damper ``c`` [N s/m]
can be included; the tyre is always in contact.

Responses to road *displacement* follow from road velocity by multiplying by ``j w``.

``control`` (python-control, seconds to import: it loads ``scipy.signal``) is imported by the
functions that use it, so a node whose law needs no design starts without it.
"""
import dataclasses
import math

import numpy as np

OUTPUT_NAMES = ('a_s', 'travel', 'tyre_deflection', 'dynamic_tyre_load')


def linear_model(params, c=0.0):
    """
    Linear quarter car as a ``control.StateSpace``.

    Parameters
    ----------
    params : QuarterCarParams
        Car parameters (``c_s`` is added to ``c``).
    c : float
        Linear suspension damping [N s/m].

    Returns
    -------
    control.StateSpace
        Inputs ``[zdot_r, F]``, outputs :data:`OUTPUT_NAMES`, states
        ``[travel, v_s, z_u - z_r, v_u]``.

    """
    import control
    p = params
    cs = float(c) + p.c_s
    ms, mu, ks, kt, ct = p.m_s, p.m_u, p.k_s, p.k_t, p.c_t
    A = np.array([
        [0.0, 1.0, 0.0, -1.0],
        [-ks / ms, -cs / ms, 0.0, cs / ms],
        [0.0, 0.0, 0.0, 1.0],
        [ks / mu, cs / mu, -kt / mu, -(cs + ct) / mu],
    ])
    B = np.array([
        [0.0, 0.0],
        [0.0, 1.0 / ms],
        [-1.0, 0.0],
        [ct / mu, -1.0 / mu],
    ])
    C = np.array([
        A[1],
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, -1.0, 0.0],
        [0.0, 0.0, -kt, -ct],
    ])
    D = np.array([
        B[1],
        [0.0, 0.0],
        [0.0, 0.0],
        [ct, 0.0],
    ])
    return control.ss(A, B, C, D, inputs=['zdot_r', 'F'], outputs=list(OUTPUT_NAMES),
                      states=['travel', 'v_s', 'tyre_def', 'v_u'])


def natural_frequencies(params, c=0.0):
    """
    Natural frequencies of the linear model [Hz], sorted: (body bounce, wheel hop).

    With ``c`` > 0 these are the undamped natural frequencies ``|lambda| / (2 pi)`` of the
    damped modes.
    """
    ev = np.linalg.eigvals(linear_model(params, c).A)
    w = np.sort(np.abs(ev[np.abs(ev) > 1e-9]))
    # complex pairs: take one of each pair
    w = w[::2] if w.size == 4 else w
    return tuple(float(x) / (2.0 * math.pi) for x in w[:2])


def analytic_frequencies(params):
    """
    Undamped 2-DOF natural frequencies from the characteristic equation [Hz].

    ``m_s m_u w^4 - (m_s (k_s + k_t) + m_u k_s) w^2 + k_s k_t = 0``.
    """
    p = params
    a = p.m_s * p.m_u
    b = -(p.m_s * (p.k_s + p.k_t) + p.m_u * p.k_s)
    c = p.k_s * p.k_t
    disc = math.sqrt(b * b - 4 * a * c)
    w1 = math.sqrt((-b - disc) / (2 * a))
    w2 = math.sqrt((-b + disc) / (2 * a))
    return w1 / (2 * math.pi), w2 / (2 * math.pi)


def transmissibility(params, c_values, f_hz):
    """
    Road-displacement frequency responses for linear dampers.

    Parameters
    ----------
    params : QuarterCarParams
        Car parameters.
    c_values : sequence of float
        Damping values [N s/m].
    f_hz : array_like
        Frequencies [Hz].

    Returns
    -------
    dict
        ``c -> {'a_s': |a_s / z_r| [1/s^2], 'travel': |travel / z_r| [-],
        'tyre_deflection': |tyre def / z_r| [-]}`` (magnitudes, arrays like ``f_hz``).

    """
    import control
    f = np.asarray(f_hz, dtype=float)
    w = 2.0 * np.pi * f
    out = {}
    for c in c_values:
        sys = linear_model(params, c)
        resp = control.frequency_response(sys[:3, 0], w)
        mag = np.abs(resp.complex) * w          # velocity -> displacement input: times j w
        mag = mag.reshape(3, -1)
        out[float(c)] = {'a_s': np.asarray(mag[0]), 'travel': np.asarray(mag[1]),
                         'tyre_deflection': np.asarray(mag[2])}
    return out


@dataclasses.dataclass
class LqrDesign:
    """
    Result of :func:`lqr_design`.

    Attributes
    ----------
    gain : ndarray (4 + n_w,)
        Feedback ``F = -gain @ [travel, v_s, z_u - z_r, v_u, w]`` [N per state unit], ``w``
        the ``n_w`` states of ``filter`` (none without a weighting).
    Q, R, N : ndarray
        Weights of ``integral X'QX + F'RF + 2X'NF`` for the design state ``X`` (from the output
        weights).
    poles : ndarray
        Closed-loop poles [rad/s] (fully active).
    weights : dict
        Output weights used.
    filter : control.StateSpace or None
        Frequency weighting on the body acceleration (None: none).
    A, B : ndarray
        Design model ``dX/dt = A X + B F``: the car without damper, then the filter states
        driven by its body acceleration.

    """

    gain: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    N: np.ndarray
    poles: np.ndarray
    weights: dict
    filter: object = None
    A: np.ndarray = None
    B: np.ndarray = None


def lqr_design(params, *, q_accel=1.0, q_travel=1.0e3, q_tyre=1.0e4, r_force=1.0e-6,
               weighting=None, q_wk=0.0):
    """
    LQR on the linear model (``control.lqr``): the one quarter-car LQR cost.

    Minimises ``integral( q_wk a_wk^2 + q_accel a_s^2 + q_travel travel^2 + q_tyre tyre_def^2
    + r_force F^2 )`` with ``a_s = (-k_s travel + F)/m_s`` (so the cost has a cross term); the
    actuator replaces the damper (spring kept). With a ``weighting`` filter the car is augmented
    with its states ``w``, driven by ``a_s``, and ``a_wk = C_w w + D_w a_s`` (cross terms from
    the feedthroughs of ``F``); without one ``a_wk = a_s``. Weights in SI units (accelerations
    in m/s^2, travel and tyre deflection in m, F in N). The defaults (fully active reference)
    were chosen on ISO 8608 class C at 20 m/s (bench/bench_ride.py) so that the active car is
    better than the softest passive MR setting on all three of Wk body acceleration, suspension
    travel and dynamic tyre load.

    Parameters
    ----------
    params : QuarterCarParams
        Car parameters.
    q_accel, q_travel, q_tyre, r_force, q_wk : float
        Output weights (SI).
    weighting : control.StateSpace, optional
        SISO stable filter on the body acceleration (e.g.
        ``semi_active_control.laws.wk_state_space``).

    Returns
    -------
    LqrDesign

    """
    import control
    sys = linear_model(params, 0.0)
    A, B = sys.A, sys.B[:, 1]
    ca, da = sys.C[0], sys.D[0, 1]
    if weighting is None:
        aw, bw, cw, dw = np.zeros((0, 0)), np.zeros(0), np.zeros(0), 1.0
    else:
        aw, bw = np.asarray(weighting.A, float), np.asarray(weighting.B, float).ravel()
        cw = np.asarray(weighting.C, float).ravel()
        dw = float(np.asarray(weighting.D, float).ravel()[0])
    nw = aw.shape[0]
    n = 4 + nw
    Aa = np.zeros((n, n))
    Aa[:4, :4] = A
    Aa[4:, :4] = np.outer(bw, ca)
    Aa[4:, 4:] = aw
    Ba = np.concatenate([B, bw * da]).reshape(n, 1)
    # cost outputs z = Cz X + Dz F: a_wk, a_s, travel, tyre deflection, force
    Cz = np.zeros((5, n))
    Cz[0, :4], Cz[0, 4:] = dw * ca, cw
    Cz[1, :4] = ca
    Cz[2, 0] = 1.0
    Cz[3, 2] = -1.0
    Dz = np.array([dw * da, da, 0.0, 0.0, 1.0])
    W = np.diag([q_wk, q_accel, q_travel, q_tyre, r_force])
    Q = Cz.T @ W @ Cz
    R = np.array([[Dz @ W @ Dz]])
    N = (Cz.T @ W @ Dz).reshape(n, 1)
    K, _, E = control.lqr(Aa, Ba, Q, R, N)
    weights = {'q_accel': q_accel, 'q_travel': q_travel, 'q_tyre': q_tyre, 'r_force': r_force}
    if weighting is not None or q_wk:
        weights['q_wk'] = q_wk
    return LqrDesign(gain=np.asarray(K).ravel(), Q=Q, R=R, N=N, poles=np.asarray(E),
                     weights=weights, filter=weighting, A=Aa, B=Ba)
