"""Tests of quarter_car_sim.road_preview and quarter_car_sim.preview_sensor."""
import math

import numpy as np
import pytest

from quarter_car_sim.preview_sensor import (LookAheadSensor, LookAheadSpec, SpeedSignal,
                                            TrackTimeline)
from quarter_car_sim.road import RoadProfile
from quarter_car_sim.road_preview import FrontRoadEstimate, PreviewFrame, RoadPreview


def _ramp_road(speed=20.0, duration=4.0, dt=1e-3):
    """Return a road whose height is its distance x 1 % (a height tells where it was read)."""
    t = np.arange(0.0, duration + dt / 2, dt)
    return RoadProfile(t, 0.01 * speed * t, np.full(t.size, 0.01 * speed), speed_m_s=speed)


def test_odometer_integrates_the_speed_signal_and_refuses_bad_samples():
    rp = RoadPreview(1, [(0, 0.0)])
    for k in range(11):
        assert rp.offer_speed(0.1 * k, 10.0 + k)
    assert rp.position == pytest.approx(sum(0.05 * (20.0 + 2 * k + 1) for k in range(10)))
    assert rp.position_at(0.05) == pytest.approx(0.5 * 0.1 * (10.0 + 11.0) / 2)
    assert rp.position_at(5.0) is None                        # future
    assert not rp.offer_speed(0.5, 10.0)                      # back in time
    assert not rp.offer_speed(2.0, math.nan)
    assert not rp.offer_speed(2.0, -1.0)
    assert rp.status()['speed_rejected'] == 3


def test_a_frame_goes_where_the_axle_was_at_its_stamp_and_is_held_beyond():
    rp = RoadPreview(1, [(0, 0.0)], spacing_m=0.01)
    for k in range(101):
        rp.offer_speed(0.001 * k, 10.0)                       # 1 m in 0.1 s
    d = np.linspace(0.5, 2.0, 16)
    assert rp.offer_frame(PreviewFrame(0.05, d, (0.1 * (0.5 + d))[None, :]))   # at 0.5 m
    # the heights are 0.1 x position: the window reads them at the wheel's position ahead
    z = rp.window([0.0, 0.05, 0.1, 0.2])
    np.testing.assert_allclose(z[:3, 0], 0.1 * np.array([1.0, 1.5, 2.0]), atol=1e-12)
    assert z[3, 0] == pytest.approx(0.25, abs=1.1e-3)          # beyond 2.5 m: held (last cell)
    # a frame that does not reach under the wheel leaves it without a window
    rp2 = RoadPreview(1, [(0, 0.0)])
    rp2.offer_speed(0.0, 10.0)
    rp2.offer_frame(PreviewFrame(0.0, d, np.zeros((1, d.size))))
    assert rp2.window([0.0, 0.1]) is None


def test_bad_frames_are_refused_and_counted():
    rp = RoadPreview(2, [(0, 0.0), (1, 0.0)], history_s=0.5)
    d = np.linspace(0.5, 15.0, 10)
    good = np.zeros((2, 10))
    assert not rp.offer_frame(PreviewFrame(0.0, d, good))      # no speed yet
    for k in range(2001):
        rp.offer_speed(0.001 * k, 20.0)
    assert not rp.offer_frame(PreviewFrame(2.5, d, good))      # stamp in the future
    assert not rp.offer_frame(PreviewFrame(1.0, d, good))      # older than the history
    assert not rp.offer_frame(PreviewFrame(1.9, d[::-1], good))
    assert not rp.offer_frame(PreviewFrame(1.9, d, good[:1]))  # one track of two
    assert not rp.offer_frame(PreviewFrame(1.9, d, good, valid=False))
    part = good.copy()
    part[1, 3] = math.nan
    assert rp.offer_frame(PreviewFrame(1.9, d, part))          # a lost point is skipped
    st = rp.status()
    assert st == {'frames': 7, 'frame_no_speed': 1, 'frame_future': 1, 'frame_too_old': 1,
                  'frame_bad_shape': 2, 'frame_invalid': 1, 'points_not_finite': 1,
                  'frames_taken': 1}


def test_front_road_estimate_is_the_road_under_the_wheel():
    # wheel on a sine road with a tyre deflection of its own: z_r = int(v_u) - d
    t = np.arange(0.0, 1.0, 1e-3)
    zr = 0.01 * np.sin(2 * np.pi * 3 * t)
    d = 0.002 * np.cos(2 * np.pi * 7 * t)
    zu = zr + d
    vu = np.gradient(zu, t, edge_order=2)
    est = FrontRoadEstimate(1, leak_s=np.inf)
    out = np.array([est.update(tk, [v], [dk])[0] for tk, v, dk in zip(t, vu, d)])
    np.testing.assert_allclose(out - out[0], zr - zr[0], atol=2e-5)
    assert est.update(1.1, [math.nan], [0.0]) is None and est.rejected == 1


def test_sensor_delivers_each_frame_its_latency_late_at_its_rate():
    road = _ramp_road()
    sensor = LookAheadSensor(LookAheadSpec(latency_s=0.02, rate_hz=10.0), road)
    got = []
    for k in range(1001):
        t = 0.001 * k
        got += [(t, f) for f in sensor.frames_until(t)]
    assert len(got) == 10                                      # 0.0 .. 0.9 s, the last late
    for t, f in got:
        assert t == pytest.approx(f.stamp + 0.02, abs=1e-9)
        # the ramp: height = 1 % of the distance driven; the points are ahead of the axle
        np.testing.assert_allclose(f.heights_m[0], 0.01 * (20.0 * f.stamp + f.distance_m),
                                   atol=1e-9)
    assert f.distance_m[0] == 0.5 and f.distance_m[-1] == pytest.approx(15.0)


def test_sensor_noise_bias_pitch_and_dropouts():
    road = _ramp_road(duration=20.0)
    spec = LookAheadSpec(height_noise_m=0.003, height_bias_m=0.01, dropout_prob=0.25,
                         pitch_error_gain=1.0, camera_height_m=1.25, rate_hz=20.0)
    sensor = LookAheadSensor(spec, road, rng=3)
    sensor.reset(t0=0.0)                                       # the first frame at 0
    frames = sensor.frames_until(10.0, pitch=0.0)
    assert sensor.counts['measured'] == 201
    assert len(frames) + sensor.counts['lost'] == 201
    assert 0.18 < sensor.counts['lost'] / 201 < 0.32
    err = np.concatenate([f.heights_m[0] - 0.01 * (20.0 * f.stamp + f.distance_m)
                          for f in frames])
    assert np.mean(err) == pytest.approx(0.01, abs=2e-4)
    assert np.std(err) == pytest.approx(0.003, rel=0.05)
    # a pitch e puts the point at distance D at D + D^2 e / h, read D e too high
    flat = LookAheadSensor(LookAheadSpec(pitch_error_gain=0.5, camera_height_m=1.25), road)
    f = flat.frames_until(10.0, pitch=2e-3)[0]                 # the first frame at 10 s
    e = 0.5 * 2e-3
    d = f.distance_m
    np.testing.assert_allclose(f.heights_m[0],
                               0.01 * (20.0 * f.stamp + d + d ** 2 * e / 1.25) + d * e,
                               atol=1e-12)


def test_an_outage_gives_invalid_frames():
    sensor = LookAheadSensor(LookAheadSpec(outages=((0.2, 0.4),), rate_hz=10.0), _ramp_road())
    sensor.reset(t0=0.0)
    frames = sensor.frames_until(1.0)
    assert [f.valid for f in frames] == [True, True, False, False, True, True, True, True,
                                         True, True, True]
    assert sensor.counts['outage'] == 2


@pytest.mark.parametrize('kw', [dict(range_m=(5.0, 1.0)), dict(rate_hz=0.0),
                                dict(latency_s=-0.1), dict(dropout_prob=1.5),
                                dict(height_bias_m=math.nan)])
def test_bad_sensor_settings_are_refused(kw):
    with pytest.raises(ValueError):
        LookAheadSpec(**kw)


def test_speed_signal_and_timeline():
    assert SpeedSignal(0.02).read(20.0) == pytest.approx(20.4)
    with pytest.raises(ValueError, match='scale_error'):
        SpeedSignal(-1.0)
    with pytest.raises(ValueError, match='speed'):
        TrackTimeline([0.0, 1.0], [0.0, 0.0], math.nan)


def test_the_map_averages_the_noise_of_the_frames_that_saw_a_point():
    # 3 mm noise per frame; a point 2-5 m ahead has been seen by about 10 frames at 18 Hz;
    # a running mean weighting the newest 1/4 keeps about sqrt(0.25 / 1.75) = 0.38 of the
    # noise the newest frame alone has (the same frames into both maps)
    road = _ramp_road(duration=6.0)
    sensor = LookAheadSensor(LookAheadSpec(height_noise_m=0.003), road, rng=2)
    sensor.reset(t0=0.0)
    maps = {f: RoadPreview(1, [(0, 0.0)], fuse=f) for f in (1, 4)}
    err = {f: [] for f in maps}
    s = np.linspace(0.1, 0.25, 100)
    for k in range(5001):
        t = 1e-3 * k
        frames = sensor.frames_until(t)
        for f, rp in maps.items():
            rp.offer_speed(t, 20.0)
            for fr in frames:
                rp.offer_frame(fr)
            if k > 1000 and k % 50 == 0:
                err[f].append(rp.window(s)[:, 0] - 0.01 * (rp.position + 20.0 * s))
    std = {f: np.std(np.concatenate(e)) for f, e in err.items()}
    assert 0.8 < std[1] / 0.003 < 1.05          # interpolation between points averages a bit
    assert 0.25 < std[4] / std[1] < 0.5
