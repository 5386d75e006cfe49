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


def test_noisy_sensors_error_far_below_state_rms(design):
    est, err, true = _run(design, FullCarSensors(DT, seed=2), 2000)
    e, tr = err[300:], true[300:]
    for group in ('travel', 'body_rates', 'wheel_v'):
        sl = fe.STATE_GROUPS[group]
        ratio = np.sqrt((e[:, sl] ** 2).mean(0)) / np.sqrt((tr[:, sl] ** 2).mean(0))
        assert np.all(ratio < 0.2), (group, ratio)
    assert est.valid


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
