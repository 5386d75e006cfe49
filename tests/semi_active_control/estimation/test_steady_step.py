"""
The full-car filter's compiled steps against its general path, faults included.

Two vehicle estimators take the same chassis-bus stream: one as shipped (clean cycles
compiled, :mod:`semi_active_control.estimation.steady_step`: on the steady gain, or from the
start on the gain schedule, :mod:`semi_active_control.estimation.gain_schedule`), one with the
compiled step switched off (every cycle through the general numpy path). Dropouts, stuck and
frozen sensors, readings out of range and NaN are injected after the filter has reached its
steady gain, or while it is on the schedule; the two must agree on every cycle: state to
round-off, validity, reason, faults, counts, and the covariance where it is read.
"""
import numpy as np
import pytest

from conftest import REPO
from mr_damper_model.io.params_file import load_plant
from quarter_car_sim.plant.full_car import FullCar
from quarter_car_sim.plant.two_track_road import make_two_track_road
from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.estimation.vehicle_estimator import (EstimatorSettings,
                                                              VehicleEstimatorCore)

MODELS = REPO / 'src' / 'semi_active_control' / 'config' / 'models'
DT = 0.002
N = 3000


def _readings(seed=5, n=N, faults=True):
    """Return the bus's body accelerations and travels of a car on a C road, faults injected."""
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0,
                               duration_s=n * DT + 0.2, dt=DT, rng=seed)
    car = FullCar(PASSENGER_CAR, [load_plant('kwok-current', str(MODELS / f'{c}.json'))
                                  for c in ('fl', 'fr', 'rl', 'rr')], road)
    rng = np.random.default_rng(seed)
    s = car.state
    acc, trv, t = np.empty((n, 4)), np.empty((n, 4)), np.empty(n)
    for k in range(n):
        acc[k] = np.round((s.body_a + rng.normal(scale=0.039, size=4)) / 0.01) * 0.01
        trv[k] = np.round((s.travel + rng.normal(scale=3.5e-5, size=4)) / 1e-4) * 1e-4
        t[k] = s.t
        s = car.step(DT, (0.3, 0.5, 0.7, 0.9))
    if not faults:
        return t, acc, trv
    trv[500:520, 1] = trv[500, 1] + 0.005      # travel_fr frozen 5 mm off the car
    trv[700, 0] = np.nan                        # one lost travel_fl reading (no fault)
    acc[800:803, 2] = acc[800, 2]               # accel_rl repeats three times (no fault)
    acc[1000:1030, 1] = np.nan                  # accel_fr drops out for 60 ms
    acc[1400:1410, 3] = 1e3                     # accel_rr at the end of its range
    trv[1800:2050, 2] = trv[1800, 2]            # travel_rl stuck for 0.5 s
    acc[2400:2440, 0] = acc[2400, 0]            # accel_fl stuck for 80 ms
    return t, acc, trv


def _pair(**kw):
    """Return the shipped vehicle filter and one with every cycle on the general path."""
    settings = EstimatorSettings(cycle_s=DT, **kw)
    shipped, general = VehicleEstimatorCore(PASSENGER_CAR, settings), \
        VehicleEstimatorCore(PASSENGER_CAR, settings)
    general.filter._fast = None
    return shipped, general


def _run_both(shipped, general, t, acc, trv, check=lambda k, a, b: None):
    """
    Run both filters on the same stream, asserting they agree on every cycle.

    Returns, per cycle, 1 when the shipped one ran it compiled. ``check(k, a, b)``: more
    assertions on cycle ``k``'s two estimates.
    """
    compiled = []
    for k in range(len(t)):
        before = shipped.filter.n_compiled
        a = shipped.step(k + 1, t[k], acc[k], trv[k])
        b = general.step(k + 1, t[k], acc[k], trv[k])
        compiled.append(shipped.filter.n_compiled - before)
        np.testing.assert_allclose(shipped.filter.x, general.filter.x, rtol=1e-9, atol=1e-12)
        assert (a.valid, a.reason, a.faults) == (b.valid, b.reason, b.faults), k
        assert shipped.filter.steady == general.filter.steady, k
        check(k, a, b)
    assert shipped.status() == general.status()
    assert general.filter.n_compiled == 0
    return np.array(compiled)


def test_compiled_steady_step_agrees_with_the_general_path():
    t, acc, trv = _readings()
    shipped, general = _pair(accel_bias_std=0.0)   # steady from the start
    compiled_by_cycle = _run_both(shipped, general, t, acc, trv)
    assert general.filter.n_compiled == 0
    # the faults were seen (each named and counted), and were not run compiled ...
    faults = shipped.status()['sensor_fault_entries']
    assert set(faults) == {'stuck_travel_fr', 'dropout_accel_fr', 'range_accel_rr',
                           'stuck_travel_rl', 'stuck_accel_fl'}
    for lo, hi in ((501, 520), (700, 701), (1000, 1030), (1400, 1410), (1924, 2050),
                   (2400, 2440)):
        assert not compiled_by_cycle[lo:hi].any(), (lo, hi)
    # ... while most clean cycles were, the harmless repeats among them, and again after
    # each fault once the filter was back on its steady gain
    assert compiled_by_cycle.sum() > N // 3
    assert compiled_by_cycle[800:803].all()
    # (a run of repeats counted compiled until it is long enough to be stuck: the general
    # path found it out on the same cycle, 0.25 s in)
    assert compiled_by_cycle[1801:1924].all()
    for lo, hi in ((100, 500), (900, 1000), (1300, 1400), (1700, 1800)):
        assert compiled_by_cycle[lo:hi].all(), (lo, hi)


def test_the_start_runs_compiled_on_the_gain_schedule_as_the_general_path_runs_it():
    # the default start: wide accelerometer-bias variances, about 12 s to the steady gain
    shipped, general = _pair()
    schedule = shipped.filter.schedule
    steady_at = schedule.steady_after
    assert steady_at is not None and steady_at % 100 == 0 and steady_at == schedule.n_steps
    n = steady_at + 200
    t, acc, trv = _readings(seed=7, n=n, faults=False)

    def check(k, a, b):
        np.testing.assert_allclose(shipped.filter.std(), general.filter.std(), rtol=1e-9)
        assert a.travel_std_m == pytest.approx(b.travel_std_m, rel=1e-9)
        assert shipped.filter.steady == (k + 1 >= steady_at), k
        if k in (1, 99, 100, 2345):          # the covariance, read while on the schedule
            np.testing.assert_allclose(shipped.filter.P, general.filter.P, rtol=1e-12,
                                       atol=1e-300)
    compiled = _run_both(shipped, general, t, acc, trv, check)
    # every cycle but the first (it starts the filter) ran compiled: the schedule's, then
    # the steady gain's
    assert compiled[1:].all() and not compiled[0]


def test_a_fault_on_the_schedule_leaves_it_with_the_general_paths_covariance():
    shipped, general = _pair()
    n = 1500
    t, acc, trv = _readings(seed=8, n=n, faults=False)
    trv[650, 2] = np.nan                  # one lost reading 1.3 s in: off the schedule
    acc[900:930, 1] = np.nan              # a dropout later, on the general path

    def check(k, a, b):
        if k == 650:                      # the covariance the general step took up
            np.testing.assert_allclose(shipped.filter.P, general.filter.P, rtol=1e-12,
                                       atol=1e-300)
    compiled = _run_both(shipped, general, t, acc, trv, check)
    assert compiled[1:650].all() and not compiled[650:].any()


def test_a_state_gone_non_finite_on_the_schedule_restarts_the_filter_off_it():
    """A diverged filter restarts its covariance while its step count goes on: off the schedule."""
    shipped, general = _pair()
    n = 700
    t, acc, trv = _readings(seed=9, n=n, faults=False)
    compiled = []
    for k in range(n):
        if k == 300:                      # the state corrupted on both (no reading does this)
            shipped.filter.x[0] = general.filter.x[0] = np.nan
        before = shipped.filter.n_compiled
        a = shipped.step(k + 1, t[k], acc[k], trv[k])
        b = general.step(k + 1, t[k], acc[k], trv[k])
        compiled.append(shipped.filter.n_compiled - before)
        assert (a.valid, a.reason) == (b.valid, b.reason), k
        np.testing.assert_allclose(shipped.filter.x, general.filter.x, rtol=1e-9, atol=1e-12)
        if k == 300:
            assert a.reason == 'diverged' and not a.valid
            np.testing.assert_array_equal(shipped.filter.P, general.filter.P)
    compiled = np.array(compiled)
    # compiled on the schedule up to the corruption, never after: the recursion restarted
    assert compiled[1:300].all() and not compiled[300:].any()
    assert shipped.filter.n_invalid == general.filter.n_invalid
    assert shipped.filter.n_invalid.get('diverged') == 1
    np.testing.assert_allclose(shipped.filter.P, general.filter.P, rtol=1e-9, atol=1e-300)
