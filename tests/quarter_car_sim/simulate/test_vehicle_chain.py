"""The vehicle chain offline: the vehicle computer's cores on a simulated car, and lock-step."""
import numpy as np
import pytest

from conftest import REPO
from mr_damper_model.io.params_file import load_plant
from quarter_car_sim.metrics.full_car import body_a_v
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.simulate.full_car import simulate_full_car
from quarter_car_sim.simulate.vehicle_chain import simulate_vehicle_chain
from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.estimation.vehicle_estimator import (EstimatorSettings,
                                                              VehicleEstimatorCore)

MODELS = REPO / 'src' / 'semi_active_control' / 'config' / 'models'
FILES = [str(MODELS / f'{c}.json') for c in ('fl', 'fr', 'rl', 'rr')]
DT = 1e-3
DURATION = 4.0


@pytest.fixture(scope='module')
def road():
    return make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0,
                               duration_s=DURATION + 1.0, dt=DT, rng=3)


def plants():
    return [load_plant('kwok-current', f) for f in FILES]


def a_v(res):
    return body_a_v(res.t, res.acc)


def chain(road, law='modal-skyhook', **kw):
    return simulate_vehicle_chain(PASSENGER_CAR, road, law, plants(), FILES, dt=DT,
                                  duration_s=DURATION, **kw)


def test_true_states_answered_every_step_are_lock_step(road):
    # the chain's controller core on the true state, each car step, at once: the offline
    # full car's loop (another controller object, the same law, inverses and models)
    res = chain(road, sensing='true', cycle_steps=1, delay_steps=0)
    ref = simulate_full_car(PASSENGER_CAR, road, 'modal-skyhook', plants(), FILES, dt=DT,
                            duration_s=DURATION)
    np.testing.assert_allclose(res.current_cmd, ref.current_cmd, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.acc, ref.acc, rtol=0, atol=1e-9)
    assert res.status['refused_models'] == {} and res.normal.all()


def test_the_command_reaches_the_drivers_delay_steps_after_its_cycle(road):
    # cycles every 2 car steps (t = -0.5 s + 2 k ms): the drivers' currents change only on the
    # cycles' steps when answered at once, only on the steps after them with one step's delay
    for delay, parity in ((0, 0), (1, 1)):
        res = chain(road, sensing='true', cycle_steps=2, delay_steps=delay)
        change = np.flatnonzero(np.any(np.diff(res.current_cmd, axis=0) != 0, axis=1)) + 1
        assert len(change) > 100 and np.all(change % 2 == parity), delay
    # a passive law at the safe current is blind to cycle, delay and sensing (an invalid
    # estimate gets that current too): the same ride to the bit
    runs = [chain(road, law='passive@0.5A', sensing=s, cycle_steps=c, delay_steps=d)
            for s, c, d in (('true', 1, 0), ('true', 2, 1), ('estimate', 2, 2))]
    for r in runs[1:]:
        np.testing.assert_array_equal(r.acc, runs[0].acc)
        np.testing.assert_array_equal(r.current_cmd, runs[0].current_cmd)


def test_the_estimate_drives_the_law_near_lock_step_and_every_cycle_counts(road):
    est = VehicleEstimatorCore(PASSENGER_CAR, EstimatorSettings(cycle_s=2 * DT))
    res = chain(road, sensing='estimate', estimator=est)
    lock = chain(road, sensing='true', cycle_steps=1, delay_steps=0)
    st = res.status['estimator']
    assert st['invalid_steps'] == 0 and st['steps'] == res.status['cycles']
    assert st['cycles']['lost'] == 0 and st['sensor_fault_entries'] == {}
    assert res.status['cycles'] == (500 + len(res.t) + 1) // 2      # one every 2 car steps
    ratio = a_v(res) / a_v(lock)
    passive = a_v(chain(road, law='passive@0.5A', sensing='true', cycle_steps=1,
                        delay_steps=0))
    assert 1.0 <= ratio < 1.1, ratio                   # the law's gain over passive mostly kept
    assert a_v(res) < 0.8 * passive
    with pytest.raises(ValueError, match='cycle'):
        chain(road, estimator=est, cycle_steps=1)
    with pytest.raises(ValueError, match='sensing'):
        chain(road, sensing='ideal')
