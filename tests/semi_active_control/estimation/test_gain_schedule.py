"""GainSchedule: the Riccati recursion from the start worked out once, and taken up anywhere."""
import numpy as np
import pytest

from semi_active_control.estimation.gain_schedule import CHECKPOINT_STEPS, GainSchedule


def _system(n=4, m=2, seed=3):
    """Return a stable random system: transition, process noise, measurement rows, noise."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 0.999 / max(abs(np.linalg.eigvals(A)))
    B = rng.normal(size=(n, n))
    return A, B @ B.T * 1e-6, rng.normal(size=(m, n)), np.full(m, 1.0)


def _recursion(A, Q, H, r, P0, steps):
    """Return the gains and posteriors of a Kalman covariance recursion (the general step)."""
    out, P = [], P0.copy()
    for k in range(steps):
        if k:
            P = A @ P @ A.T + Q
        PH = P @ H.T
        K = np.linalg.solve(H @ PH + np.diag(r), PH.T).T
        P = P - K @ PH.T
        P = (P + P.T) * 0.5
        out.append((K, P))
    return out


def test_the_schedule_is_the_recursion_and_ends_within_the_tolerance_of_the_steady_one():
    A, Q, H, r = _system()
    P0 = np.eye(4) * 10.0
    ref = _recursion(A, Q, H, r, P0, 3000)
    P_post = ref[-1][1]                     # converged by then
    scale = np.outer(np.sqrt(np.diag(P_post)), np.sqrt(np.diag(P_post)))
    s = GainSchedule(A, Q, H, r, P0, P_post, scale, steady_tol=1e-3)
    n = s.n_steps
    assert s.steady_after == n and n % CHECKPOINT_STEPS == 0 and 300 < n < 3000
    # the first checkpoint where it is within the tolerance, not before
    dist = [float((np.abs(ref[k - 1][1] - P_post) / scale).max())
            for k in range(CHECKPOINT_STEPS, n + 1, CHECKPOINT_STEPS)]
    assert dist[-1] < 1e-3 and all(d >= 1e-3 for d in dist[:-1])
    for k in (0, 1, 57, n - 1):
        np.testing.assert_array_equal(s.gains[k], ref[k][0])
        np.testing.assert_array_equal(s.std[k], np.sqrt(np.diag(ref[k][1])))
    # the covariance after any number of updates: the same numbers, from its checkpoint
    for done in (1, 2, 99, 100, 101, 250, n - 1, n):
        np.testing.assert_array_equal(s.covariance(done), ref[done - 1][1])
    with pytest.raises(ValueError):
        s.covariance(0)
    with pytest.raises(ValueError):
        s.covariance(n + 1)


def test_a_schedule_that_does_not_reach_the_tolerance_stops_at_its_most_steps():
    A, Q, H, r = _system()
    P0 = np.eye(4) * 10.0
    far = np.eye(4) * 1e6                   # a 'steady' posterior the recursion never nears
    s = GainSchedule(A, Q, H, r, P0, far, np.ones((4, 4)), steady_tol=1e-3, max_steps=250)
    assert s.steady_after is None and s.n_steps == 250
    np.testing.assert_array_equal(s.covariance(250), _recursion(A, Q, H, r, P0, 250)[-1][1])
    assert not s.gains.flags.writeable and not s.std.flags.writeable
