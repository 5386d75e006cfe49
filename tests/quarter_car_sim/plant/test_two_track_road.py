"""Two-track roads: rear delay, isotropic coherence, ISO level, events."""
import numpy as np
import pytest
from scipy import signal

from quarter_car_sim.plant import road as qroad
from quarter_car_sim.plant.two_track_road import (event_road, iso8608_two_tracks,
                                                  make_two_track_road)
from semi_active_control.car.full_car import PASSENGER_CAR
from quarter_car_sim.plant.two_track_road import isotropic_coherence
from quarter_car_sim.plant.road import RoadError


def test_rear_wheels_see_the_front_track_delayed_by_wheelbase_over_speed():
    road = iso8608_two_tracks('C', 20.0, 4.0, wheelbase_m=2.348, track_m=1.242, rng=3)
    assert road.delay_s == 2.348 / 20.0
    for t in np.linspace(road.delay_s, 3.9, 57):
        now, now_d = road.at(t)
        then, then_d = road.at(t - road.delay_s)
        np.testing.assert_allclose(now[2:], then[:2], rtol=0, atol=1e-12)
        np.testing.assert_allclose(now_d[2:], then_d[:2], rtol=0, atol=1e-9)
    # sampled: the rear series is the front series shifted by the delay in whole samples
    dt = 1e-3
    t = np.arange(0, 4.0, dt)
    z = road.corner_series(t)
    lag = int(round(road.delay_s / dt))
    xc = signal.correlate(z[:, 2], z[:, 0], mode='full')
    assert np.argmax(xc) - (t.size - 1) == lag


def test_left_track_is_the_quarter_car_iso_road():
    road = iso8608_two_tracks('B', 15.0, 3.0, wheelbase_m=2.5, track_m=1.5, rng=7)
    ref = qroad.iso8608('B', 15.0, 3.0 + 2.5 / 15.0, 1e-3, np.random.default_rng(7))
    np.testing.assert_array_equal(road.z_left, ref.z)


def test_coherence_estimate_matches_isotropic_model():
    track, dx = 1.5, 0.05
    speed = 20.0
    road = iso8608_two_tracks('C', speed, 150.0, wheelbase_m=2.5, track_m=track,
                              dt=dx / speed, rng=11)
    n, coh = signal.coherence(road.z_left, road.z_right, fs=1.0 / dx, nperseg=1024)
    band = (n >= 0.05) & (n <= 1.5)
    model = isotropic_coherence(n[band], track) ** 2
    err = coh[band] - model
    assert np.mean(np.abs(err)) < 0.04
    assert np.max(np.abs(err)) < 0.2
    # the model itself: long waves coherent, short waves not
    assert model[0] > 0.6 and model[-1] < 0.01
    # both tracks carry the class's PSD level
    for z in (road.z_left, road.z_right):
        f, p = signal.welch(z, fs=1.0 / dx, nperseg=4096)
        m = (f > 0.05) & (f < 2.0)
        ratio = np.mean(p[m] * (f[m] / 0.1) ** 2) / qroad.ISO8608_GD_N0['C']
        assert ratio == pytest.approx(1.0, rel=0.2)


def test_identical_and_independent_options():
    kw = dict(wheelbase_m=2.5, track_m=1.5, rng=2)
    same = iso8608_two_tracks('C', 20.0, 2.0, coherence='identical', **kw)
    np.testing.assert_allclose(same.z_right, same.z_left, atol=1e-15)
    ind = iso8608_two_tracks('C', 20.0, 60.0, coherence='independent', **kw)
    assert abs(np.corrcoef(ind.z_left, ind.z_right)[0, 1]) < 0.2
    with pytest.raises(RoadError, match='coherence'):
        iso8608_two_tracks('C', 20.0, 1.0, coherence='bogus', **kw)


def test_events_single_side_and_delay():
    pot = event_road('pothole', 10.0, 2.0, wheelbase_m=2.5)
    assert np.min(pot.z_left) == pytest.approx(-0.05, abs=1e-4)
    assert np.all(pot.z_right == 0.0)
    front = [pot.at(t)[0][0] for t in np.arange(0, 2.0, 1e-3)]
    rear = [pot.at(t)[0][2] for t in np.arange(0, 2.0, 1e-3)]
    # the front wheel meets the hole at start_s, the rear wheel one wheelbase later
    assert np.argmin(front) * 1e-3 == pytest.approx(0.5 + 0.3 / 10.0, abs=2e-3)
    assert np.argmin(rear) * 1e-3 == pytest.approx(0.5 + 0.3 / 10.0 + 0.25, abs=2e-3)
    both = event_road('bump', 10.0, 2.0, wheelbase_m=2.5)
    np.testing.assert_array_equal(both.z_left, both.z_right)
    one = event_road('single-bump', 10.0, 2.0, wheelbase_m=2.5, side='right')
    assert np.all(one.z_left == 0.0) and np.max(one.z_right) == pytest.approx(0.05, abs=1e-4)


def test_make_two_track_road_specs_and_errors():
    r = make_two_track_road('iso8608-D', PASSENGER_CAR, speed_m_s=20.0, duration_s=2.0, rng=1)
    assert r.duration == pytest.approx(2.0, abs=2e-3)
    assert r.delay_s == pytest.approx(PASSENGER_CAR.wheelbase / 20.0)
    with pytest.raises(RoadError, match='unknown road'):
        make_two_track_road('gravel', PASSENGER_CAR)
    with pytest.raises(RoadError, match='ISO 8608'):
        make_two_track_road('iso8608-Z', PASSENGER_CAR)
    with pytest.raises(RoadError, match='track_m'):
        iso8608_two_tracks('C', 20.0, 1.0, wheelbase_m=2.5, track_m=0.0)
