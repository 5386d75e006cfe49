"""Sensor error models: statistical truths, quantisation, latency, dropouts, faults."""
import math

import numpy as np
import pytest

from quarter_car_sim.plant.sensors import sample_series, Sensor, SensorSampler
from semi_active_control.estimation.sensor_specs import (accelerometer_spec, default_specs, Fault,
                                                         G0, ride_height_spec, SensorError,
                                                         SensorSpec)


def test_noise_std_is_density_times_sqrt_bandwidth():
    spec = SensorSpec(noise_density=2e-3, rate_hz=1000.0)
    n = 20000
    y = sample_series(spec, np.arange(n) * 1e-3, np.zeros(n), rng=3)
    expect = 2e-3 * math.sqrt(500.0)
    # sample std of n Gaussian draws: relative standard error 1 / sqrt(2 n) = 0.5 %
    assert abs(np.std(y) / expect - 1.0) < 5 * (1.0 / math.sqrt(2 * n))
    assert abs(np.mean(y)) < 5 * expect / math.sqrt(n)
    spec2 = spec.replace(bandwidth_hz=100.0)
    assert spec2.noise_std == pytest.approx(2e-3 * 10.0)


def test_white_noise_spectrum_is_flat_at_the_density():
    from scipy.signal import welch
    spec = SensorSpec(noise_density=1e-3, rate_hz=1000.0)
    y = sample_series(spec, np.arange(2 ** 16) * 1e-3, np.zeros(2 ** 16), rng=5)
    f, pxx = welch(y, fs=1000.0, nperseg=1024)
    # one-sided PSD of white noise of variance s^2 sampled at fs: 2 s^2 / fs = density^2
    assert np.median(pxx[5:-5]) == pytest.approx(1e-6, rel=0.1)


def test_quantisation_step_and_error_bound():
    q = 0.01
    spec = SensorSpec(noise_density=0.0, quantum=q)
    x = np.linspace(-0.2, 0.2, 1001)
    y = sample_series(spec, np.arange(x.size) * 1e-3, x)
    assert np.allclose(y / q, np.round(y / q), atol=1e-9)
    assert np.max(np.abs(y - x)) <= q / 2 + 1e-12
    assert set(np.round(np.diff(np.unique(y)) / q).astype(int)) == {1}
    assert spec.variance == pytest.approx(q * q / 12.0)


def test_scale_offset_bias_and_drift():
    spec = SensorSpec(noise_density=0.0, scale_error=0.02, offset=G0, bias=0.1,
                      bias_drift=0.5)
    s = Sensor(spec)
    assert s.sample(0.0, 1.0) == pytest.approx(1.02 * (1.0 + G0) + 0.1)
    assert s.sample(2.0, 0.0) == pytest.approx(1.02 * G0 + 0.1 + 1.0)


def test_bias_random_walk_variance_grows_with_time():
    spec = SensorSpec(noise_density=0.0, bias_rw=0.01)
    ends = []
    for seed in range(400):
        s = Sensor(spec, rng=seed)
        for t in np.arange(0.0, 1.0001, 0.01):
            s.sample(t, 0.0)
        ends.append(s.bias_now)
    # variance of a random walk after 1 s: bias_rw^2 * 1 s; 400 draws: +-15 % (2 sigma)
    assert np.var(ends) == pytest.approx(1e-4, rel=0.2)


def test_turn_on_bias_is_seeded():
    spec = accelerometer_spec(dropout_prob=0.0)
    a = sample_series(spec, np.arange(50) * 1e-3, np.zeros(50), rng=7)
    b = sample_series(spec, np.arange(50) * 1e-3, np.zeros(50), rng=7)
    c = sample_series(spec, np.arange(50) * 1e-3, np.zeros(50), rng=8)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_latency_shifts_by_whole_samples():
    dt = 1e-3
    spec = SensorSpec(noise_density=0.0, latency_s=3e-3)
    sp = SensorSampler(spec, dt)
    x = np.arange(20, dtype=float)
    out = [sp.step(k * dt, xi) for k, xi in enumerate(x)]
    assert out[:3] == [None, None, None]
    assert out[3:] == list(x[:-3])


def test_slower_sensor_delivers_every_nth_step():
    spec = SensorSpec(noise_density=0.0, rate_hz=250.0)
    sp = SensorSampler(spec, 1e-3)
    out = [sp.step(k * 1e-3, float(k)) for k in range(12)]
    assert out == [0.0, None, None, None, 4.0, None, None, None, 8.0, None, None, None]
    with pytest.raises(SensorError, match='above the control rate'):
        SensorSampler(SensorSpec(noise_density=0.0, rate_hz=2000.0), 1e-3)


@pytest.mark.parametrize('mode', ['nan', 'hold'])
def test_random_dropouts_nan_or_hold(mode):
    spec = SensorSpec(noise_density=0.0, dropout_prob=0.1, dropout_mode=mode)
    s = Sensor(spec, rng=11)
    x = np.arange(5000, dtype=float)
    y = np.array([s.sample(k * 1e-3, xi) for k, xi in enumerate(x)])
    lost = np.isnan(y) if mode == 'nan' else np.r_[False, y[1:] == y[:-1]]
    assert s.n_dropped == int(lost.sum())
    # binomial(5000, 0.1): mean 500, sd 21
    assert 400 < s.n_dropped < 600
    if mode == 'hold':
        assert not np.any(np.isnan(y[1:]))


def test_injected_faults():
    faults = (Fault('stuck', 0.010, 0.020), Fault('dropout', 0.030, 0.035),
              Fault('bias_step', 0.040, value=2.0))
    spec = SensorSpec(noise_density=0.0, faults=faults)
    s = Sensor(spec)
    t = np.arange(50) * 1e-3
    y = np.array([s.sample(ti, float(k)) for k, ti in enumerate(t)])
    assert np.all(y[10:20] == 9.0)                     # frozen at the last value before
    assert y[20] == 20.0
    assert np.all(np.isnan(y[30:35])) and y[35] == 35.0
    assert np.array_equal(y[40:], np.arange(40, 50) + 2.0)
    with pytest.raises(SensorError, match='kind'):
        Fault('melted', 0.0)


def test_defaults_cite_their_datasheet_figures():
    acc = accelerometer_spec()
    assert acc.noise_density == pytest.approx(250e-6 * 9.80665)      # ADXL313 z axis
    assert acc.quantum == pytest.approx(9.80665 / 1024)               # 1024 LSB/g
    rh = ride_height_spec()
    assert rh.quantum == pytest.approx(0.2 / 4096)                    # 12 bit over 0.2 m
    assert set(default_specs()) == {'body_accel', 'travel'}
    assert set(default_specs(wheel_accel=True)) == {'body_accel', 'travel', 'wheel_accel'}


@pytest.mark.parametrize('bad, match', [
    (dict(noise_density=-1.0), 'noise_density'), (dict(rate_hz=0.0), 'rate_hz'),
    (dict(dropout_prob=1.0), 'dropout_prob'), (dict(dropout_mode='x'), 'dropout_mode'),
    (dict(quantum=math.nan), 'quantum'), (dict(scale_error=-1.0), 'scale_error')])
def test_bad_settings_name_the_setting(bad, match):
    with pytest.raises(SensorError, match=match):
        SensorSpec(**{'noise_density': 1e-3, **bad})


def test_vehicle_sensors_of_the_car_with_an_injected_dropout():
    """VehicleSensors: default sensors, seeded, the dropout window NaN and counted."""
    from types import SimpleNamespace

    from quarter_car_sim.plant.sensors import VehicleSensors
    from semi_active_control.estimation.sensor_specs import SensorError
    dt = 1e-3

    def run(seed):
        vs = VehicleSensors(dt, seed, dropout=(0.2, 0.1))
        out = []
        for k in range(500):
            t = k * dt
            out.append(vs.step(t, SimpleNamespace(a_s=0.0, a_u=0.0, travel=0.01)))
        return vs, out
    vs, out = run(3)
    assert set(vs.samplers) == {'body_accel', 'travel'}
    # 1 ms latency: the sample taken at t is delivered at t + dt (none at the first step)
    assert out[0] == {} and set(out[1]) == {'body_accel', 'travel'}
    acc = np.array([r['body_accel'] for r in out[1:]])
    t_sample = np.arange(499) * dt
    inside = (t_sample >= 0.2 - 1e-9) & (t_sample < 0.3 - 1e-9)
    assert np.all(np.isnan(acc[inside]))
    assert np.count_nonzero(np.isnan(acc[~inside])) <= 2       # random loss 1e-4 per sample
    assert abs(np.nanmean(acc[~inside]) - G0) < 0.5            # specific force: +g at rest
    travel = np.array([r['travel'] for r in out[1:]])
    assert np.all(np.isfinite(travel)) and np.all(np.abs(travel - 0.01) < 1e-3)
    st = vs.status()
    # every lost sample counted (the last one, still in the latency queue, may be lost too)
    n_nan = np.count_nonzero(np.isnan(acc))
    assert st['sensors']['body_accel']['lost'] in (n_nan, n_nan + 1)
    assert st['sensors']['body_accel']['samples'] == 500
    assert st['dropout_window_s'] == [0.2, 0.1] and st['dropout_sensors'] == ['body_accel']
    # seeded: the same readings again; another seed, others
    _, again = run(3)
    _, other = run(4)
    assert again[250:260] == out[250:260] and other[10] != out[10]
    assert VehicleSensors(dt, dropout=(1.0, 0.0)).status()['dropout_window_s'] == []
    with pytest.raises(SensorError, match='dropout_sensors'):
        VehicleSensors(dt, dropout=(1.0, 1.0), dropout_sensors=('wheel_accel',))


def test_bus_sensor_cluster_reads_all_eight_sensors_once_a_cycle():
    """The chassis bus's cluster: 4 accelerometers + 4 ride heights, every cycle, no delay."""
    from types import SimpleNamespace

    from quarter_car_sim.plant.sensors import bus_sensor_cluster
    dt, cycle = 1e-3, 2e-3
    cl = bus_sensor_cluster(dt, cycle, seed=5)
    travel = np.array([0.01, -0.02, 0.03, 0.0])
    state = SimpleNamespace(body_a=np.zeros(4), travel=travel)
    out = [cl.step(k * dt, state) for k in range(200)]
    names = {f'{s}_{c}' for s in ('accel', 'travel') for c in ('fl', 'fr', 'rl', 'rr')}
    # a reading of every sensor on the cycle's steps (no latency), none between them
    assert all(set(r) == names for r in out[0::2]) and all(r == {} for r in out[1::2])
    st = cl.status()
    assert {s: st[s]['samples'] for s in names} == dict.fromkeys(names, 100)
    assert all(st[s]['lost'] == 0 for s in names)
    # the parts' error models: +g at rest within the turn-on bias, travel within its accuracy
    acc = np.array([[r[f'accel_{c}'] for c in ('fl', 'fr', 'rl', 'rr')] for r in out[0::2]])
    assert np.all(np.abs(acc.mean(0) - G0) < 5 * accelerometer_spec().bias_std + 0.05)
    tr = np.array([[r[f'travel_{c}'] for c in ('fl', 'fr', 'rl', 'rr')] for r in out[0::2]])
    assert np.all(np.abs(tr - travel) < 2e-3)
    # seeded
    again = bus_sensor_cluster(dt, cycle, seed=5)
    assert [again.step(k * dt, state) for k in range(10)] == out[:10]
