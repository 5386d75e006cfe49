"""
Full-car clipped-optimal control: an LQR on the road-relative 7-DOF car, clipped per damper.

Road-relative model (fully active, the actuators replace the dampers, springs and bars kept):
state ``x = [s (4), d (4), v_b (3), v_u (4)]`` with the corner travels ``s``, the tyre
deflections ``d = z_u - z_r``, the body rates ``v_b = [zdot, thetadot, phidot]`` and the wheel
velocities ``v_u``; input the four corner forces ``F`` on the body::

    sdot = T v_b - v_u          ddot = v_u - zdot_r
    M_b v_b' = T' (-Ks s - Cs sdot + F)
    m_u v_u' = Ks s + Cs sdot - F - k_t d - c_t (v_u - zdot_r)

Eight positions for seven degrees of freedom: ``s + d = T q_b - z_r``, so on a flat road
``s + d`` lies in the range of ``T`` and its component along ``n`` (``T' n = 0``, the road
"warp" of the four wheel points) is a road input no force can change: an uncontrollable
integrator, which ``control.lqr`` refuses. The design therefore runs on the 14-dimensional
subspace ``n . (s + d) = 0`` (invariant when ``zdot_r = 0``), and the gain on the full state
is ``K = K_r V'`` (V an orthonormal basis of the subspace): it ignores the road warp.

Cost (SI)::

    integral( q_heave zdd^2 + q_pitch thetadd^2 + q_roll phidd^2
              + q_travel |s|^2 + q_tyre |d|^2 + r_force |F|^2 ) dt

with the default pitch and roll weights the squares of the ISO 2631-1 axis factors (0.40,
0.63 m/rad), so the acceleration part is the unweighted a_v's integrand. The law
(:class:`FullCarClippedOptimal`) takes ``F = -K x`` and clips each corner to what its damper
can do (dissipative), as the quarter car's clipped-optimal (Dyke et al. 1996) does; the range
clipping is the corner inverse's saturation.
"""
import numpy as np
from scipy.linalg import null_space

from semi_active_control.laws.full_car import ForceLaw

DEFAULT_FULL_LQR_WEIGHTS = {'q_heave': 1.0, 'q_pitch': 0.16, 'q_roll': 0.3969,
                            'q_travel': 0.0, 'q_tyre': 1.0e3, 'r_force': 3.0e-7}
"""Default weights of :func:`full_car_lqr_design` (SI).

The quarter car's clipped-optimal weights (``DEFAULT_CO_WEIGHTS``) with the pitch and roll
accelerations weighted by the ISO 2631-1 axis factors squared and a lighter force weight:
bench/bench_full_car.py on its training roads (ISO 8608 C, 20 m/s, 20 s, seeds 11-13, Spencer
plants) gives median a_v 0.747 / 0.618 / 0.613 m/s^2 at r_force 1e-5 / 1e-6 / 3e-7, and 0.640
with q_tyre 1e4 at 1e-6."""


def relative_model(params):
    """
    Road-relative linear full car (see the module docstring).

    Returns
    -------
    A : ndarray (15, 15)
    B : ndarray (15, 4)
        Corner forces on the body [N].
    Cy, Dy : ndarray (3, 15), (3, 4)
        Body accelerations ``[zdd, thetadd, phidd] = Cy x + Dy F``.
    n : ndarray (4,)
        Unit road-warp direction (``T' n = 0``).

    """
    p = params
    T = p.geometry
    ks = p.spring_matrix()
    cs = np.diag(p.c_s)
    mb_inv = np.diag(1.0 / np.array([p.m_s, p.i_pitch, p.i_roll]))
    mu_inv = np.diag(1.0 / p.m_u)
    A = np.zeros((15, 15))
    B = np.zeros((15, 4))
    i_s, i_d, i_b, i_u = slice(0, 4), slice(4, 8), slice(8, 11), slice(11, 15)
    A[i_s, i_b] = T
    A[i_s, i_u] = -np.eye(4)
    A[i_d, i_u] = np.eye(4)
    # spring-damper force on the body per corner: -Ks s - Cs (T v_b - v_u)
    fs = np.zeros((4, 15))
    fs[:, i_s] = -ks
    fs[:, i_b] = -cs @ T
    fs[:, i_u] = cs
    A[i_b] = mb_inv @ T.T @ fs
    B[i_b] = mb_inv @ T.T
    A[i_u] = -mu_inv @ fs
    A[i_u, i_d] -= mu_inv * p.k_t
    A[i_u, i_u] -= mu_inv * p.c_t
    B[i_u] = -mu_inv
    n = null_space(T.T)[:, 0]
    return A, B, A[i_b].copy(), B[i_b].copy(), n / np.linalg.norm(n)


def checked_weights(defaults, overrides):
    """
    Return ``defaults`` updated by ``overrides``, checked (ValueError).

    Every name must be one of ``defaults``, every weight finite and >= 0, ``r_force`` > 0.
    """
    unknown = sorted(set(overrides) - set(defaults))
    if unknown:
        raise ValueError(f'unknown LQR weight(s): {", ".join(unknown)}')
    w = {**defaults, **overrides}
    for k, v in w.items():
        if not (np.isfinite(v) and v >= 0.0):
            raise ValueError(f'`{k}` must be finite and >= 0, got {v}')
    if not w['r_force'] > 0.0:
        raise ValueError('`r_force` must be > 0')
    return w


class FullCarLqrDesign:
    """
    Result of :func:`full_car_lqr_design`.

    Attributes
    ----------
    gain : ndarray (4, 15)
        ``F = -gain @ [s, d, v_b, v_u]``.
    poles : ndarray (14,)
        Closed-loop poles of the reduced (controllable) model.
    weights : dict
        The weights used.

    """

    def __init__(self, gain, poles, weights):
        self.gain, self.poles, self.weights = gain, poles, weights


def full_car_lqr_design(params, **weights):
    """
    LQR of the fully active road-relative full car on its controllable subspace.

    Parameters
    ----------
    params : FullCarParams
        Car (the dampers' parallel ``c_s`` kept, usually 0).
    **weights
        Overrides of :data:`DEFAULT_FULL_LQR_WEIGHTS`.

    Returns
    -------
    FullCarLqrDesign

    """
    import control
    w = checked_weights(DEFAULT_FULL_LQR_WEIGHTS, weights)
    A, B, Cy, Dy, n = relative_model(params)
    c = np.zeros(15)
    c[0:4], c[4:8] = n, n
    V = null_space(c[None, :])                   # (15, 14), orthonormal
    # cost outputs z = Cz x + Dz F: accelerations, travels, tyre deflections, forces
    Cz = np.vstack([Cy, np.eye(15)[0:8], np.zeros((4, 15))])
    Dz = np.vstack([Dy, np.zeros((8, 4)), np.eye(4)])
    W = np.diag([w['q_heave'], w['q_pitch'], w['q_roll']] + [w['q_travel']] * 4
                + [w['q_tyre']] * 4 + [w['r_force']] * 4)
    Czr = Cz @ V
    Q = Czr.T @ W @ Czr
    R = Dz.T @ W @ Dz
    N = Czr.T @ W @ Dz
    Q, R = 0.5 * (Q + Q.T), 0.5 * (R + R.T)       # exactly symmetric for control.lqr
    K_r, _, E = control.lqr(V.T @ A @ V, V.T @ B, Q, R, N)
    return FullCarLqrDesign(np.asarray(K_r) @ V.T, np.asarray(E), w)


class FullCarClippedOptimal(ForceLaw):
    """
    Full-car clipped-optimal law: ``F = -K x`` of :func:`full_car_lqr_design`, clipped per damper.

    Parameters
    ----------
    design : FullCarLqrDesign
        LQR design.
    name : str
        Law name.

    """

    #: Corner-state fields beyond the common ones (the tyre deflection needs the road height).
    state_fields = ('z_u', 'z_r')

    def __init__(self, design, name='full-car-clipped-optimal'):
        self.design, self.name = design, name
        self.gain = np.asarray(design.gain, dtype=float)
        super().__init__()

    @classmethod
    def from_car(cls, params, name='full-car-clipped-optimal', **weights):
        """Design on ``params`` (weights: :data:`DEFAULT_FULL_LQR_WEIGHTS` overrides)."""
        return cls(full_car_lqr_design(params, **weights), name=name)

    def desired_forces(self, state):
        """Return the LQR forces ``-K [s, d, v_b, v_u]`` [N] (``d`` needs ``z_r``)."""
        return -self.gain @ np.concatenate([state.travel, state.q[3:] - state.z_r, state.v])
