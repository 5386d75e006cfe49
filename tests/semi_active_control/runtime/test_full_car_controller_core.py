"""The full car's external controller core: four corner states in, four supervised currents."""
import math

import numpy as np
import pytest

from full_car_cases import corners_of
from mr_damper_common.contract import CornerState, IdentifiedSet
from mr_damper_model.identification import presets
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.runtime.full_car import FullCarRuntime
from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.runtime.full_car_controller_core import (body_coordinates,
                                                                  full_car_state_of_corners,
                                                                  FullCarControllerCore)

KW = presets.thesis_kwok_current()[1]
IDENTIFIED = IdentifiedSet(KW, current_min_a=0.0, current_max_a=2.0, valid=True)
SAFE_A = 0.7
T = PASSENGER_CAR.geometry


def test_body_coordinates_of_a_rigid_body_are_exact_and_survive_one_missing_corner():
    x = np.array([0.012, -0.03, 0.02])
    points = T @ x
    np.testing.assert_allclose(body_coordinates(T, points), x, rtol=0, atol=1e-15)
    for i in range(4):
        p = points.copy()
        p[i] = math.nan
        np.testing.assert_allclose(body_coordinates(T, p), x, rtol=0, atol=1e-15)
    p = points.copy()
    p[:2] = math.nan
    assert np.all(np.isnan(body_coordinates(T, p)))


def test_assembled_state_gives_the_car_body_rates():
    rt = FullCarRuntime(PASSENGER_CAR, make_two_track_road(
        'iso8608-C', PASSENGER_CAR, speed_m_s=20.0, duration_s=1.0, rng=2),
        [make_plant('kwok-current') for _ in range(4)], 'passive@0.5A', settle_s=0.0)
    for k in range(300):
        _, _, new = rt.step(k * 1e-3)
    s = full_car_state_of_corners(PASSENGER_CAR, corners_of(new))
    np.testing.assert_allclose(s.v[:3], new.v[:3], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(s.q, new.q, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(s.v_rel, new.v_rel, rtol=0, atol=0)


@pytest.mark.parametrize('law', ['modal-skyhook', 'per-corner-skyhook'])
@pytest.mark.slow
def test_same_currents_as_the_built_in_controller_and_rr_safe_without_a_model(law):
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0, duration_s=2.0,
                               rng=3)
    rt = FullCarRuntime(PASSENGER_CAR, road, [make_plant('kwok-current') for _ in range(4)],
                        law, dt=1e-3, timeout_s=1e9, safe_current_a=SAFE_A, settle_s=0.1)
    core = FullCarControllerCore(PASSENGER_CAR, law, dt=1e-3, timeout_s=1e9,
                                 safe_current_a=SAFE_A)
    for corner in ('fl', 'fr', 'rl'):                      # rr gets no model
        assert rt.offer_parameters(corner, IDENTIFIED, 0.0).accepted
        assert core.offer_parameters(corner, IDENTIFIED, 0.0).accepted
    n = 500
    got, want = [], []
    for k in range(n):
        state, currents, _ = rt.step(k * 1e-3)
        answers = [core.offer_state(i, c, k * 1e-3) for i, c in enumerate(corners_of(state))]
        assert answers[:3] == [None, None, None]           # the fourth completes the set
        got.append(answers[3])
        want.append(currents)
    got, want = np.asarray(got), np.asarray(want)
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-4)     # inverse tolerance 1e-4 A
    assert np.all(got[:, 3] == SAFE_A)
    assert np.ptp(got[:, :3], axis=0).min() > 0.1          # the law, not the safe current
    st = core.status(t_clock=n * 1e-3)
    assert st['sets'] == n and st['dropped'] == {'replaced': 0, 'incomplete': 0}
    assert [st['corners'][c]['normal_commands'] for c in ('fl', 'fr', 'rl', 'rr')] == [
        n, n, n, 0]
    assert st['corners_normal'] == 3 and st['corners']['rr']['mode'] == 'failsafe'
    assert [st['corners'][c]['states'] for c in ('fl', 'fr', 'rl', 'rr')] == [n] * 4


def test_incomplete_and_replaced_states_are_counted_and_never_answered_twice():
    core = FullCarControllerCore(PASSENGER_CAR, 'modal-skyhook', safe_current_a=SAFE_A)

    def cs(t):
        return CornerState(t, z_s=0.0, v_s=0.0, a_s=0.0, z_u=0.0, v_u=0.0, travel=0.0, v_rel=0.0,
                           z_r=0.0)

    assert core.offer_state('fl', cs(1.0), 1.0) is None
    assert core.offer_state('fl', cs(1.001), 1.0) is None      # replaces fl's first
    for c in ('fr', 'rl'):
        assert core.offer_state(c, cs(1.0), 1.0) is None
    # four fresh states, stamps differ: the older three are dropped, fl waits for the others
    assert core.offer_state('rr', cs(1.0), 1.0) is None
    assert core.dropped == {'replaced': 1, 'incomplete': 3}
    for c in ('fr', 'rl'):
        assert core.offer_state(c, cs(1.001), 1.0) is None
    currents = core.offer_state('rr', cs(1.001), 1.0)
    assert currents == [SAFE_A] * 4                           # no models: all safe
    assert core.sets == 1 and core.states == [2, 2, 2, 2]
    assert core.offer_state('rr', cs(1.001), 1.0) is None      # a set is answered once


def test_bad_settings_are_refused_with_their_name():
    with pytest.raises(ValueError, match='dt'):
        FullCarControllerCore(PASSENGER_CAR, 'modal-skyhook', dt=0.0)
