"""
Road preview on the nodes, without ROS: the car's look-ahead frames and the controller's input.

The frames go through the message conversion both ways (``RoadPreview``), as between
``full_car_node`` and ``vehicle_controller_node``; the car's state as the vehicle's
``FullCarState`` message carries it.
"""
import math

import numpy as np
import pytest

from mr_damper_common import messages
from mr_damper_common.contract import IdentifiedSet
from mr_damper_model.models import presets
from mr_damper_model.models.plant import KwokCurrentPlant
from semi_active_control.estimation.vehicle_estimator import VehicleEstimate
from quarter_car_sim.plant.preview_sensor import IDEAL_LOOK_AHEAD, LookAheadSpec, PreviewFeed
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.runtime.full_car import FullCarRuntime
from quarter_car_sim.runtime.look_ahead import simulated_look_ahead, SimulatedLookAhead
from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.estimation.preview_input import FUTURE_S, PreviewInput
from semi_active_control.laws.full_car_preview import FedFullCarLaw, make_full_car_preview_law
from semi_active_control.runtime.live_preview import LivePreview
from semi_active_control.runtime.vehicle_controller import full_car_state, VehicleControllerCore
from semi_active_control.supervision.corner_models import CornerModels

P = PASSENGER_CAR
KW = presets.thesis_kwok_current()[1]
IDENTIFIED = IdentifiedSet(KW, current_min_a=0.0, current_max_a=2.0, valid=True)
DT = 1e-3
SUPERVISION = dict(timeout_s=1e9, safe_current_a=0.5, i_min_a=0.0, i_max_a=2.0,
                   min_current_span_a=1.0)


def wire(seq, frame, speed):
    """Send a frame through the message and back (the topic between the two nodes)."""
    msg = messages.road_preview_msg(frame.stamp, frame.distance_m, frame.heights_m,
                                    sequence=seq, speed_m_s=speed, valid=frame.valid,
                                    reason='' if frame.valid else 'outage')
    return messages.road_preview_fields(msg)


def controller(law='preview-look-ahead', **preview):
    """Return a vehicle controller core at the test's period, active, each corner on a model."""
    live = LivePreview(P, law, dt=DT, **preview) if law == 'preview-look-ahead' else None
    core = VehicleControllerCore(P, law, CornerModels([''] * 4, **SUPERVISION), cycle_s=DT,
                                 deadline_s=1e9, preview=live)
    core.configure(0.0)
    core.activate(0.0)
    for i in range(4):
        assert core.offer_parameters(i, IDENTIFIED, 0.0).accepted
    return core


def over_the_wire(state, sequence):
    """Return the car's state as the controller reads it (the FullCarState message, back)."""
    f = messages.full_car_state_fields(messages.full_car_state_msg(
        VehicleEstimate.exact(state, sequence)))
    return full_car_state(P.geometry, f['t'], f['body'], f['body_rates'], f['body_acc'],
                          f['travel'], f['travel_velocity'], f['tyre_deflection'],
                          f['wheel_velocity'], f['damper_force'])


def drive(cores, road, sensor, duration_s, spy=None):
    """
    Drive the car on ``road``: the first core's currents act; every core sees the same states.

    Before each step the sensor's frames due go over the wire to every preview core.
    """
    plants = [KwokCurrentPlant(KW, coil_tau_s=0.0) for _ in range(4)]
    rt = FullCarRuntime(P, road, plants, 'passive@0.5A', dt=DT, settle_s=0.0)
    for k in range(int(round(duration_s / DT))):
        state = rt.state
        for seq, frame in sensor.frames(state.t, float(state.q[1])):
            fields = wire(seq, frame, sensor.speed_m_s)
            for core in cores:
                core.offer_preview(fields)
        wired = over_the_wire(state, k + 1)
        out = [core.command(wired, k + 1, True, '', k * DT).currents_a for core in cores]
        if spy is not None:
            spy(wired, out)
        rt.step(k * DT, out[0])
    return rt


@pytest.fixture(scope='module')
def road():
    return make_two_track_road('iso8608-C', P, speed_m_s=20.0, duration_s=1.5, rng=5)


@pytest.mark.slow
def test_live_preview_on_an_ideal_sensor_is_the_offline_preview_law(road):
    # the same law fed offline (PreviewFeed) and live (numbered frames over the message, the
    # speed signal held, frames handed to the map at their step) previews the same steps and
    # asks the same forces
    live = controller()
    offline = make_full_car_preview_law(P, source='look-ahead', dt=DT)
    fed = FedFullCarLaw(offline, PreviewFeed(offline.road, road, IDEAL_LOOK_AHEAD))
    sensor = SimulatedLookAhead(IDEAL_LOOK_AHEAD, road)
    diffs, scale = [], []

    def spy(state, _):
        fed.prepare(state)
        diffs.append(np.abs(np.subtract(live.preview.law.forces, offline.forces)).max())
        scale.append(np.abs(offline.feedforward).max())

    drive([live], road, sensor, 1.0, spy)
    st = live.status()['preview']
    assert st['law'] == offline.stats.as_dict()
    # all but the first 143 steps: the rear wheels' road (2.85 m behind the sensor's near end)
    assert st['law']['fallback_steps'] == math.ceil((P.wheelbase + 0.5) / 20.0 / DT)
    assert max(diffs) < 1e-6 * max(scale) and max(scale) > 50.0
    assert st['input']['messages']['lost'] == 0
    assert st['road_preview']['frames_taken'] == sensor.status()['delivered']


@pytest.mark.slow
def test_outage_falls_back_to_the_law_without_preview_counted_then_previews_again(road):
    # a realistic sensor blind from 0.3 to 0.6 s: after the preview timeout the law is
    # full-car-clipped-optimal-wk, current for current (each through its corner's inverse and
    # supervisor), each step counted; after the outage the preview comes back
    spec = LookAheadSpec(latency_s=0.02, height_noise_m=0.003, outages=((0.3, 0.6),))
    sensor = SimulatedLookAhead(spec, road, speed_error=0.02)
    live = controller(preview_timeout_s=0.1)
    plain = controller('full-car-clipped-optimal-wk')
    law = live.preview.law
    fallback, previewed = [], []

    def spy(state, currents):
        (fallback if not law.last_previewed else previewed).append(state.t)
        if not law.last_previewed:
            np.testing.assert_array_equal(currents[0], currents[1])
            assert law.forces == plain.controller.law.forces
            assert not law.feedforward.any()

    drive([live, plain], road, sensor, 1.5, spy)
    st = live.status()['preview']
    inp = st['input']
    assert inp['refused']['invalid'] == sensor.status()['outage'] > 0
    assert inp['fallback']['no_frame_yet'] > 0 and inp['fallback']['timeout'] > 0
    assert st['law']['fallback_steps'] == len(fallback)
    assert st['law']['previewed_steps'] == len(previewed)
    assert st['law']['dropouts'] == 2          # the start (no frame yet) and the outage
    # order: preview, fallback after the last frame before the outage plus the timeout, preview
    last_before = max(t for t in np.arange(0.0, 0.3, 1 / 18.0))
    out_fallback = [t for t in fallback if t > 0.25]   # not the start's (rear map empty)
    assert min(out_fallback) == pytest.approx(last_before + 0.1, abs=2 * DT + 0.02)
    assert st['first_previewed_t'] < 0.3 < st['last_fallback_t'] < st['last_previewed_t']
    assert st['last_fallback_t'] >= 0.6
    assert live.answered == plain.answered == 1500


def input_for_tests(**kwargs):
    law = make_full_car_preview_law(P, source='look-ahead', horizon_s=0.05)
    return law, PreviewInput(law.road, **kwargs)


def frame_fields(seq, stamp, *, valid=True, speed=20.0, heights=None):
    d = np.arange(0.5, 15.01, 0.5)
    h = np.zeros((2, d.size)) if heights is None else heights
    return {'sequence': seq, 'stamp': stamp, 'speed_m_s': speed, 'distance_m': d,
            'heights_m': h, 'valid': valid, 'reason': '' if valid else 'outage'}


def test_input_takes_frames_at_their_step_and_refuses_stale_repeated_future_invalid():
    _, inp = input_for_tests(timeout_s=0.2, max_age_s=0.05)
    assert not inp.before_step(0.0) and inp.fallback['no_frame_yet'] == 1
    assert inp.offer(frame_fields(1, 0.01))            # waits: the car is at 0.0
    assert inp.before_step(0.005) is False and inp.status()['pending'] == 1
    assert inp.before_step(0.01) and inp.last_frame_stamp == 0.01
    assert not inp.offer(frame_fields(1, 0.02))        # same number again
    assert inp.refused['sequence'] == 1
    assert inp.offer(frame_fields(3, 0.02))            # one lost on the way: counted
    assert inp.sequence.lost == 1
    inp.before_step(0.08)                              # 60 ms old at its step: stale
    assert inp.refused['stale'] == 1 and inp.last_frame_stamp == 0.01
    assert not inp.offer(frame_fields(4, 0.09, valid=False))
    assert inp.refused['invalid'] == 1
    assert inp.offer(frame_fields(5, 0.1 + 2 * FUTURE_S))
    inp.before_step(0.1)
    assert inp.refused['future'] == 1 and inp.status()['pending'] == 0
    assert inp.before_step(0.2) and not inp.before_step(0.2101)   # timeout 0.2 s after 0.01
    assert inp.fallback['timeout'] == 1
    inp.refuse('layout')
    assert inp.status()['refused']['layout'] == 1


def test_input_holds_the_speed_and_ignores_a_bad_one():
    law, inp = input_for_tests()
    inp.offer(frame_fields(1, 0.0, speed=20.0))
    assert law.road.speed == 20.0 and law.road.position == 0.0
    inp.offer(frame_fields(2, 0.05, speed=math.nan))
    assert inp.refused['speed'] == 1
    inp.before_step(0.1)
    assert law.road.position == pytest.approx(2.0)     # 0.1 s at the held 20 m/s


def test_input_keeps_at_most_max_pending_frames():
    _, inp = input_for_tests(max_pending=3)
    for k in range(5):
        inp.offer(frame_fields(k + 1, 0.5 + 0.01 * k))
    assert inp.refused['overflow'] == 2 and inp.status()['pending'] == 3


@pytest.mark.parametrize('kwargs', [dict(timeout_s=0.0), dict(max_age_s=math.nan),
                                    dict(max_pending=0)])
def test_input_refuses_bad_settings(kwargs):
    with pytest.raises(ValueError):
        input_for_tests(**kwargs)


def test_unknown_live_preview_law_is_an_error():
    with pytest.raises(ValueError, match='preview-look-ahead'):
        LivePreview(P, 'preview-mpc-look-ahead')


def test_a_preview_message_that_did_not_decode_is_counted_by_its_reason():
    core = controller()
    assert not core.offer_preview(messages.MessageError('layout', 'heights do not match'))
    assert core.status()['preview']['input']['refused']['layout'] == 1
    plain = controller('modal-skyhook')
    assert not plain.offer_preview(frame_fields(1, 0.0)) and 'preview' not in plain.status()


def test_sensor_numbers_its_frames_so_the_controller_counts_the_lost_ones(road):
    sensor = simulated_look_ahead({'preview_dropout_prob': 0.3, 'preview_seed': 7,
                                   'speed_error': 0.02}, road)
    _, inp = input_for_tests()
    seqs = []
    for k in range(1000):
        for seq, frame in sensor.frames(-0.01 + k * DT):
            seqs.append(seq)
            inp.offer(wire(seq, frame, sensor.speed_m_s))
    counts = sensor.status()
    assert counts['lost'] > 0 and counts['delivered'] == len(seqs)
    assert seqs[0] == 1 and np.all(np.diff(seqs) >= 1)
    assert inp.sequence.lost == sum(np.diff(seqs) - 1) == counts['lost'] - (
        counts['measured'] - seqs[-1])
    assert sensor.speed_m_s == pytest.approx(20.0 * 1.02)


def test_node_settings_build_the_sensor_model(road):
    s = simulated_look_ahead({'preview_near_m': 1.0, 'preview_far_m': 5.0,
                              'preview_rate_hz': 10.0, 'preview_outage_start_s': 0.2,
                              'preview_outage_s': 0.1}, road)
    assert s.sensor.spec.range_m == (1.0, 5.0) and np.allclose(s.sensor.spec.outages, [(0.2, 0.3)])
    assert s.sensor.distance[0] == 1.0 and s.sensor.distance[-1] == pytest.approx(5.0)
    with pytest.raises(ValueError, match='range_m'):
        simulated_look_ahead({'preview_near_m': 5.0, 'preview_far_m': 1.0}, road)
