"""
The full-car filter's time-varying gains from its start, worked out once when it is designed.

While every sensor is read at every step, a Kalman filter's covariance and gain follow the
Riccati recursion alone: they do not depend on the readings. The vehicle's full-car filter
(:class:`~semi_active_control.estimation.full_car.FullCarEstimator`) starts on wide
accelerometer-bias variances (a MEMS part's turn-on bias) and needs about 12 s of road
(5,900 cycles of 2 ms) to come within ``steady_tol`` of its steady posterior. Until then its
general step predicts the covariance, solves for the gain and updates the covariance on every
cycle, about four times the CPU of the steady gain's step; on the vehicle computer that made
the first seconds after configure the slowest of a run.

:class:`GainSchedule` runs that recursion once, when the filter is designed, with the same
operations in the same order as the general step, and keeps each step's gain and state
standard deviations, and the covariance every :data:`CHECKPOINT_STEPS` steps. While the
filter follows it (every sensor used on every step since its start), each clean cycle runs the
compiled steady step (:mod:`~.steady_step`) with that step's gain instead of the steady one,
and the filter goes over to the steady gain on the step the general path would. A cycle that
leaves the schedule (a reading missing, stuck or out of range) takes the covariance from the
schedule (:meth:`GainSchedule.covariance`: the checkpoint before and at most
``CHECKPOINT_STEPS - 1`` steps of the recursion) and runs the general step from there, as
before. No ROS.
"""
import time

import numpy as np

__all__ = ['CHECKPOINT_STEPS', 'GainSchedule', 'kalman_update', 'MAX_STEPS', 'near_steady',
           'predict_covariance', 'STEADY_CHECK_STEPS']

#: Time-varying updates between two comparisons of the covariance with the steady one.
STEADY_CHECK_STEPS = 100
#: Steps between two covariances kept (a cycle leaving the schedule recomputes at most this
#: many less one).
CHECKPOINT_STEPS = 100
#: The most steps a schedule covers (40 s at 2 ms); a filter not steady by then goes on with
#: the general step.
MAX_STEPS = 20000


# The filter's covariance recursion, one home for the general step and the schedule: the same
# operations in the same order give the same numbers.

def predict_covariance(P, Ad, Qd):
    """Return the prior one period on from posterior ``P``."""
    return Ad @ P @ Ad.T + Qd


def _posterior(P, K, PH):
    P = P - K @ PH.T
    return (P + P.T) * 0.5


def kalman_update(P, H, r):
    """Return the gain and the (symmetric) posterior of prior ``P`` on rows ``H``, noise ``r``."""
    PH = P @ H.T
    K = np.linalg.solve(H @ PH + np.diag(r), PH.T).T
    return K, _posterior(P, K, PH)


def near_steady(P, P_post, p_scale, steady_tol):
    """Whether posterior ``P`` is within ``steady_tol`` of the steady one (element-wise)."""
    return float((np.abs(P - P_post) / p_scale).max()) < steady_tol


class GainSchedule:
    """
    The gains of a filter that starts at ``P_start`` and reads every sensor on every step.

    Step ``k`` (0-based) predicts the covariance (``Ad P Ad' + Qd``; not on the first step),
    then updates it with all ``m`` readings; after every :data:`STEADY_CHECK_STEPS` updates
    the posterior is compared with the steady one, as the filter's general step does.

    Parameters
    ----------
    Ad, Qd : ndarray (n, n)
        Transition and process noise of the period.
    H : ndarray (m, n)
        Measurement rows.
    r : ndarray (m,)
        Measurement noise variances.
    P_start : ndarray (n, n)
        The start covariance (the prior of the first step).
    P_post : ndarray (n, n)
        The steady posterior.
    p_scale : ndarray (n, n)
        The scale of each element in the comparison (``|P - P_post| / p_scale``).
    steady_tol : float
        The relative distance at which the filter goes over to the steady gain.
    max_steps : int
        The most steps kept (:data:`MAX_STEPS`).

    Attributes
    ----------
    gains : ndarray (n_steps, n, m)
        The gain of each step.
    std : ndarray (n_steps, n)
        The state standard deviations after each step.
    steady_after : int or None
        The updates after which the filter runs on the steady gain (None: not within
        ``max_steps``).
    build_s : float
        Seconds it took to work the schedule out.

    """

    def __init__(self, Ad, Qd, H, r, P_start, P_post, p_scale, steady_tol,
                 max_steps=MAX_STEPS):
        t0 = time.perf_counter()
        self.Ad, self.Qd, self.H, self.r = Ad, Qd, H, np.asarray(r, dtype=float)
        gains, std = [], []
        self._after = {}                       # step -> its prior covariance (checkpoints)
        self.steady_after = None
        P = np.array(P_start, dtype=float)
        for k in range(int(max_steps)):
            if k:
                P = predict_covariance(P, Ad, Qd)
            if k % CHECKPOINT_STEPS == 0:
                self._after[k] = P            # the prior of step k (k updates done, predicted)
            K, P = kalman_update(P, H, self.r)
            gains.append(K)
            std.append(np.sqrt(np.maximum(np.diag(P), 0.0)))
            if ((k + 1) % STEADY_CHECK_STEPS == 0
                    and near_steady(P, P_post, p_scale, steady_tol)):
                self.steady_after = k + 1
                break
        self._last_post = P
        self.gains = np.ascontiguousarray(np.array(gains))
        self.std = np.ascontiguousarray(np.array(std))
        for a in (self.gains, self.std):
            a.setflags(write=False)
        self.build_s = time.perf_counter() - t0

    @property
    def n_steps(self):
        """Steps the schedule covers."""
        return len(self.gains)

    @property
    def nbytes(self):
        """Memory of the schedule's arrays [bytes]."""
        return (self.gains.nbytes + self.std.nbytes + self._last_post.nbytes
                + sum(P.nbytes for P in self._after.values()))

    def covariance(self, done):
        """
        Return the posterior covariance after ``done`` updates (1..:attr:`n_steps`), a copy.

        From the prior kept at the checkpoint before, the recursion with the kept gains: the
        same operations as when the schedule was made, so the same numbers.
        """
        done = int(done)
        if not 1 <= done <= self.n_steps:
            raise ValueError(f'`done` must be 1..{self.n_steps}, got {done}')
        if done == self.n_steps:
            return self._last_post.copy()
        k = (done - 1) // CHECKPOINT_STEPS * CHECKPOINT_STEPS
        P = self._after[k]
        H = self.H
        while True:
            P = _posterior(P, self.gains[k], P @ H.T)
            k += 1
            if k == done:
                return P
            P = predict_covariance(P, self.Ad, self.Qd)
