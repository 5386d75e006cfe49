"""Tests of quarter_car_sim.plant.road: ISO 8608 PSD level, deterministic profiles, CSV input."""
import numpy as np
import pytest
from scipy import signal

from quarter_car_sim.plant import road as rd


@pytest.mark.parametrize('road_class', ['A', 'C', 'E'])
def test_iso8608_psd_level_matches_class(road_class):
    # 4 km of road; Welch over distance; band-averaged PSD within 20 % of Gd(n) at 5 frequencies
    speed, dt = 20.0, 2e-3
    r = rd.iso8608(road_class, speed, 200.0, dt, rng=3)
    dx = speed * dt
    f, p = signal.welch(r.z, fs=1.0 / dx, nperseg=2 ** 14)
    for n in (0.05, 0.1, 0.3, 1.0, 2.0):
        m = (f > n / 1.15) & (f < n * 1.15)
        ratio = np.mean(p[m] * (f[m] / n) ** 2) / rd.iso8608_psd(n, road_class)
        assert 0.8 < ratio < 1.2, (n, ratio)


def test_iso8608_class_steps_are_factor_four_and_c_value():
    assert rd.ISO8608_GD_N0['C'] == pytest.approx(256e-6)
    assert rd.ISO8608_GD_N0['H'] == pytest.approx(262144e-6)
    r_a = rd.iso8608('A', 20.0, 20.0, rng=1)
    r_b = rd.iso8608('B', 20.0, 20.0, rng=1)
    # same phases: amplitude scales with sqrt(4) = 2
    np.testing.assert_allclose(r_b.z, 2.0 * r_a.z, rtol=1e-12, atol=1e-15)


def test_iso8608_seed_repeatable_and_zdot_consistent():
    a = rd.iso8608('C', 15.0, 10.0, rng=7)
    b = rd.iso8608('C', 15.0, 10.0, rng=7)
    c = rd.iso8608('C', 15.0, 10.0, rng=8)
    np.testing.assert_array_equal(a.z, b.z)
    assert not np.allclose(a.z, c.z)
    num = np.gradient(a.z, a.dt)
    assert np.sqrt(np.mean((num - a.zdot) ** 2)) < 0.02 * np.std(a.zdot)


@pytest.mark.parametrize('bad', ['Z', '', 'CC'])
def test_iso8608_unknown_class(bad):
    with pytest.raises(rd.RoadError, match='road class'):
        rd.iso8608(bad, 20.0, 1.0)


@pytest.mark.parametrize('speed', [-1.0, 0.0, float('nan')])
def test_bad_speed(speed):
    with pytest.raises(rd.RoadError, match='speed'):
        rd.iso8608('C', speed, 1.0)


def test_bump_sine_step_shapes():
    b = rd.bump(height=0.05, length=1.0, speed_m_s=10.0, duration_s=1.0, start_s=0.2)
    assert b.z.max() == pytest.approx(0.05, rel=1e-3)
    assert b.t[np.argmax(b.z)] == pytest.approx(0.25, abs=1e-3)
    assert b.z[b.t < 0.2].max() == 0.0 and b.z[b.t > 0.31].max() == 0.0
    s = rd.sine(amplitude=0.01, frequency_hz=2.0, duration_s=2.0)
    assert np.sqrt(np.mean(s.z ** 2)) == pytest.approx(0.01 / np.sqrt(2), rel=1e-3)
    st = rd.step(height=0.02, duration_s=1.0, start_s=0.5)
    assert st.z[st.t < 0.5].max() == 0.0 and st.z[st.t >= 0.5].min() == 0.02


def test_csv_time_and_distance(tmp_path):
    p = tmp_path / 'r.csv'
    p.write_text('t,height\n0,0\n1,0.01\n2,0\n')
    r = rd.from_csv(p, dt=0.01)
    assert r.duration == pytest.approx(2.0)
    assert r.height(0.5) == pytest.approx(0.005)
    q = tmp_path / 'd.csv'
    q.write_text('distance,z\n0,0\n10,0.02\n')
    r2 = rd.from_csv(q, speed_m_s=5.0, dt=0.01)
    assert r2.duration == pytest.approx(2.0)
    assert r2.z[-1] == pytest.approx(0.02)
    assert r2.zdot[50] == pytest.approx(0.01, rel=1e-6)


@pytest.mark.parametrize('text, match', [
    ('a,b\n0,0\n1,1\n', 'header'),
    ('t,height\n0,0\n', 'at least 2'),
    ('t,height\n0,0\n1,nan\n', 'NaN'),
    ('t,height\n0,0\n0,1\n', 'increasing'),
    ('t,height\n0,x\n1,1\n', 'non-numeric'),
    ('distance,height\n0,0\n1,1\n', 'speed'),
])
def test_csv_errors_name_the_file(tmp_path, text, match):
    p = tmp_path / 'bad.csv'
    p.write_text(text)
    with pytest.raises(rd.RoadError, match=match) as info:
        rd.from_csv(p)
    assert 'bad.csv' in str(info.value)


def test_csv_missing_file(tmp_path):
    with pytest.raises(rd.RoadError, match='not found'):
        rd.from_csv(tmp_path / 'nope.csv')


def test_make_road_specs(tmp_path):
    assert rd.make_road('iso8608-B', duration_s=2.0, rng=1).name.startswith('iso8608-B')
    assert rd.make_road('bump', duration_s=2.0).z.max() > 0
    with pytest.raises(rd.RoadError, match='unknown road'):
        rd.make_road('gravel')
    with pytest.raises(rd.RoadError, match='speed'):
        rd.make_road('iso8608-C', speed_m_s=-5.0)


def test_make_road_node_options(tmp_path):
    # a bare 'iso8608' takes `road_class`; 'file' needs `file`; `repeat` makes it periodic
    a = rd.make_road('iso8608', road_class='D', duration_s=2.0, rng=3)
    b = rd.make_road('iso8608-D', duration_s=2.0, rng=3)
    np.testing.assert_array_equal(a.z, b.z)
    assert a.name == b.name and not a.periodic
    assert rd.make_road('iso8608', road_class='D', duration_s=2.0, rng=3, repeat=True).periodic
    with pytest.raises(rd.RoadError, match='road_file'):
        rd.make_road('file')
    path = tmp_path / 'road.csv'
    path.write_text('t,z\n0.0,0.0\n0.5,0.01\n1.0,0.0\n')
    c = rd.make_road('file', file=str(path), duration_s=1.0)
    np.testing.assert_array_equal(c.z, rd.make_road(str(path), duration_s=1.0).z)
