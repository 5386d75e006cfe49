"""Full-car Kalman estimator (3 body accelerometers + 4 position sensors): truths it must meet."""
import json

import numpy as np
import pytest

from semi_active_control.estimation import full_car as fe
from quarter_car_sim.plant.full_car import FullCar
from semi_active_control.car.full_car import PASSENGER_CAR
from quarter_car_sim.plant.two_track_road import make_two_track_road, TwoTrackRoad
from quarter_car_sim.simulate.full_car import true_vector
from quarter_car_sim.plant.sensors import FullCarSensors
from semi_active_control.estimation.sensor_specs import G0, ideal_spec

DT = 1e-3
C_PASSIVE = 1500.0


def _run(design, sensors, n, *, x0=None, P0=None, q0=None, flat=False, seed=1, force=None,
         delay_steps=0):
    if flat:
        t = np.arange(n + 100) * DT
        z = np.zeros_like(t)
        road = TwoTrackRoad(t, z, z, z, z, delay_s=0.1, name='flat')
    else:
        road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0,
                                   duration_s=n * DT + 0.1, dt=DT, rng=seed)
    car = FullCar(PASSENGER_CAR, None, road)
    s = car.state if q0 is None else car.set_state(q0)
    est = fe.FullCarEstimator(design, delay_steps=delay_steps)
    est.reset(x0, P0)
    err, true = [], []
    for _ in range(n):
        # the force the accelerometers see now (held over the last step) is the known input
        f = -C_PASSIVE * s.v_rel if force is None else force
        x = est.step(s.t, sensors.step(s.t, s), s.damper_force)
        err.append(x[:15] - true_vector(s))
        true.append(true_vector(s))
        s = car.step_force(DT, f)
    return est, np.array(err), np.array(true)


@pytest.fixture(scope='module')
def design():
    return fe.design_full_car_estimator(PASSENGER_CAR, DT)


@pytest.mark.slow
def test_noise_free_converges_from_wrong_initial_state():
    acc, pos = ideal_spec(offset=G0), ideal_spec()
    d = fe.design_full_car_estimator(PASSENGER_CAR, DT, accel=acc, travel=pos)
    sens = FullCarSensors(DT, accel=acc, travel=pos)
    # free vibration on a flat road (linear car: no wheel lifts), filter started at rest
    q0 = np.array([0.02, 0.01, -0.01, 0.0, 0.0, 0.0, 0.0])
    x0 = np.zeros(fe.N_E)
    x0[8:11] = [0.3, -0.2, 0.2]                     # wrong body rates too
    # a constant force (held the same in every convention) and free vibration
    # the start is known to be far off: a wide initial covariance
    est, err, _ = _run(d, sens, 3000, x0=x0, P0=np.eye(fe.N_E) * 0.1, q0=q0, flat=True,
                       force=np.array([300.0, -200.0, 100.0, 0.0]))
    e0 = np.abs(err[0]).max()
    assert e0 > 0.1
    # the error decays: travels exact at once, then everything below 1 % of the start
    assert np.abs(err[1:, 0:4]).max() < 1e-6
    assert np.abs(err[1000:]).max(axis=0).max() < 0.05 * e0
    assert np.abs(err[-1]).max() < 0.002 * e0
    assert np.abs(err[-1, 4:8]).max() < 1e-5


@pytest.mark.slow
def test_noisy_sensors_error_far_below_state_rms(design):
    est, err, true = _run(design, FullCarSensors(DT, seed=2), 2000)
    e, tr = err[300:], true[300:]
    for group in ('travel', 'body_rates', 'wheel_v'):
        sl = fe.STATE_GROUPS[group]
        ratio = np.sqrt((e[:, sl] ** 2).mean(0)) / np.sqrt((tr[:, sl] ** 2).mean(0))
        assert np.all(ratio < 0.2), (group, ratio)
    assert est.valid


@pytest.mark.slow
def test_one_step_delay_takes_the_sensor_latency(design):
    """Default sensors deliver 1 ms (one period) late: ``delay_steps=1`` removes that lag."""
    rms = {}
    for k in (0, 1):
        _, err, true = _run(design, FullCarSensors(DT, seed=2), 3000, delay_steps=k)
        rms[k] = np.sqrt(np.mean(err[1000:, 0:4] ** 2)) / np.sqrt(np.mean(true[1000:, 0:4] ** 2))
    assert rms[1] < 0.5 * rms[0], rms
    with pytest.raises(ValueError):
        fe.FullCarEstimator(design, delay_steps=2)


def test_three_accelerometers_fix_rigid_body_accelerations():
    p = PASSENGER_CAR
    rng = np.random.default_rng(3)
    acc_b = rng.normal(size=3)
    rows = [0, 1, 2]                                 # fl, fr, rl
    x, y = p.x, p.y
    # analytic: a_i = zdd - x_i thetadd + y_i phidd in the car's geometry matrix convention
    a = p.geometry[rows] @ acc_b
    got = fe.body_accelerations(p, a)
    np.testing.assert_allclose(got, acc_b, rtol=1e-12, atol=1e-12)
    # and the fourth corner follows from the rigid body
    assert abs(p.geometry[3] @ got - p.geometry[3] @ acc_b) < 1e-12
    assert len(x) == 4 and len(y) == 4


def test_dropout_is_detected_and_counted(design):
    sens = FullCarSensors(DT, seed=3, dropout=('accel_fr', 0.3, 0.1))
    est, _, _ = _run(design, sens, 600)
    n = est.n_invalid.get('dropout_accel_fr', 0)
    # no reading for > dropout_s (0.02 s) of the 0.1 s window: about 80 steps invalid
    assert 70 <= n <= 90
    assert est.valid
    assert sens.status()['accel_fr']['lost'] >= 100


def test_cli_sensing_vehicle_json(capsys):
    from quarter_car_sim.tools.full_car_sim import main
    assert main(['--compare', '--laws', 'modal-skyhook', '--duration', '0.5', '--sensing',
                 'vehicle', '--json']) == 0
    out = json.loads(capsys.readouterr().out)
    assert out['sensing'] == 'vehicle'
    m = out['laws']['modal-skyhook']
    est = m['estimation']
    assert set(est['rms_error']) == set(fe.STATE_GROUPS)
    assert est['steps'] == 501
    assert m['a_v'] > 0


# --- the vehicle computer's use: four accelerometers, faulty sensors left out (degrade) ------

DT2 = 2e-3
ALL4 = ('fl', 'fr', 'rl', 'rr')
STUCK = {'accel': 0.05, 'travel': 0.25}


def _specs_500hz():
    from semi_active_control.estimation.sensor_specs import accelerometer_spec, ride_height_spec
    return (accelerometer_spec(rate_hz=500.0, latency_s=0.0),
            ride_height_spec(rate_hz=500.0, latency_s=0.0))


@pytest.fixture(scope='module')
def design4():
    acc, pos = _specs_500hz()
    return fe.design_full_car_estimator(PASSENGER_CAR, DT2, accel_corners=ALL4, accel=acc,
                                        travel=pos)


def _run_degrade(design, faults, n, *, seed=4):
    """Run the filter with ``degrade`` on a road; return the estimator, errors, truths, valid."""
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0,
                               duration_s=n * DT2 + 0.1, dt=DT2, rng=seed)
    car = FullCar(PASSENGER_CAR, None, road)
    acc, pos = _specs_500hz()
    sens = FullCarSensors(DT2, seed=seed, accel=acc, travel=pos, accel_corners=ALL4,
                          faults=faults)
    est = fe.FullCarEstimator(design, degrade=True, stuck_s=STUCK, repeat_gate=5.0,
                              steady_tol=1e-3)
    s = car.state
    err, true, valid = [], [], []
    for _ in range(n):
        f = -C_PASSIVE * s.v_rel
        x = est.step(s.t, sens.step(s.t, s), s.damper_force)
        err.append(x[:15] - true_vector(s))
        true.append(true_vector(s))
        valid.append(est.valid)
        s = car.step_force(DT2, f)
    return est, np.array(err), np.array(true), np.array(valid)


def test_four_accelerometers_any_three_fix_the_rigid_body(design4):
    # the rigid body's heave, pitch and roll accelerations from any three of the four points
    p = PASSENGER_CAR
    acc_b = np.random.default_rng(5).normal(size=3)
    a = p.geometry @ acc_b
    for left_out in range(4):
        rows = [k for k in range(4) if k != left_out]
        got = np.linalg.solve(p.geometry[rows], a[rows])
        np.testing.assert_allclose(got, acc_b, rtol=1e-12, atol=1e-12)
    assert design4.sensors == ('accel_fl', 'accel_fr', 'accel_rl', 'accel_rr', 'travel_fl',
                               'travel_fr', 'travel_rl', 'travel_rr')
    # every set of three accelerometers and three position sensors observes the car; two
    # accelerometers are not enough for the rule, nor is a set without position sensors
    every = set(design4.sensors)
    for a_out in [None] + [f'accel_{c}' for c in ALL4]:
        for t_out in [None] + [f'travel_{c}' for c in ALL4]:
            assert fe.observes_the_car(design4, every - {a_out, t_out})
    assert not fe.observes_the_car(design4, [s for s in every if s.startswith('accel')])
    with pytest.raises(ValueError, match='not\n? ?on one line|three points'):
        fe.design_full_car_estimator(PASSENGER_CAR, DT2, accel_corners=('fl', 'fr'))


@pytest.mark.slow
def test_one_accelerometer_and_one_position_sensor_out_the_estimate_goes_on(design4):
    # a frozen accelerometer disagrees with the converged filter at once (the repeat gate);
    # a position sensor drops out: both named and left out, the estimate stays valid
    from semi_active_control.estimation.sensor_specs import Fault
    faults = [('accel_fr', Fault('stuck', 0.5, 1.5)),
              ('travel_rl', Fault('dropout', 0.8, 2.0))]
    est, err, true, valid = _run_degrade(design4, faults, 1500)
    assert est.fault_entries.get('stuck_accel_fr') == 1
    assert est.fault_entries.get('dropout_travel_rl') == 1
    assert 490 <= est.fault_steps['stuck_accel_fr'] <= 500         # 1 s at 2 ms
    assert 580 <= est.fault_steps['dropout_travel_rl'] <= 592      # 1.2 s - dropout_s
    assert valid[5:].all(), est.n_invalid
    # and the estimate stays usable while both are out: errors well below the states' RMS
    w = slice(int(0.85 / DT2), int(1.5 / DT2))
    for group in ('travel', 'body_rates', 'wheel_v'):
        sl = fe.STATE_GROUPS[group]
        ratio = (np.sqrt((err[w, sl] ** 2).mean(0))
                 / np.sqrt((true[w, sl] ** 2).mean(0)))
        assert np.all(ratio < 0.35), (group, ratio)
    assert est.faults == []                    # both back by the end


def test_two_accelerometers_out_too_few_sensors_then_back(design4):
    from semi_active_control.estimation.sensor_specs import Fault
    faults = [('accel_fl', Fault('dropout', 0.4, 0.8)), ('accel_rr', Fault('dropout', 0.4, 0.8))]
    est, _, _, valid = _run_degrade(design4, faults, 600)
    n_bad = est.n_invalid.get('too_few_sensors', 0)
    assert 170 <= n_bad <= 200                 # 0.4 s - dropout_s, at 2 ms
    assert valid[-1] and not valid[int(0.6 / DT2)]
    assert est.fault_entries == {'dropout_accel_fl': 1, 'dropout_accel_rr': 1}


def test_out_of_range_readings_are_not_used(design4):
    est = fe.FullCarEstimator(design4, gravity=0.0, degrade=True,
                              ranges={'accel': (-20.48, 20.47), 'travel': (-0.2048, 0.2047)})
    y = np.zeros(8)
    for k in range(20):
        y[5] = 0.2047 if k >= 10 else 0.0       # travel_fr at the end of the frame's range
        est.step(k * DT2, y, np.zeros(4))
    assert est.faults == ['range_travel_fr'] and est.valid
    assert est.fault_steps['range_travel_fr'] == 10
    assert abs(est.x[1]) < 1e-3                # the saturated reading was not taken
