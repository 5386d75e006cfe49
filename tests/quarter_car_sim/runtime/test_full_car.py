"""The live full-car runtime: one corner without a model stays safe while the others control."""
import math

import numpy as np
import pytest

from mr_damper_common.contract import IdentifiedSet
from mr_damper_model.identification import presets
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.plant.two_track_road import make_two_track_road
from semi_active_control.car.full_car import PASSENGER_CAR
from quarter_car_sim.metrics.full_car import iso2631_seat
from quarter_car_sim.runtime.full_car import FullCarRuntime

KW = presets.thesis_kwok_current()[1]
IDENTIFIED = IdentifiedSet(KW, current_min_a=0.0, current_max_a=2.0, valid=True)
SAFE_A = 0.7


def _runtime(**kw):
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0, duration_s=2.0,
                               rng=3)
    opts = dict(dt=1e-3, timeout_s=1e9, safe_current_a=SAFE_A, settle_s=0.1)
    opts.update(kw)
    return FullCarRuntime(PASSENGER_CAR, road, [make_plant('kwok-current') for _ in range(4)],
                          'modal-skyhook', **opts)


def test_corner_without_parameters_stays_safe_while_the_others_control():
    rt = _runtime()
    for corner in ('fl', 'fr', 'rl'):                      # rr gets no model
        assert rt.offer_parameters(corner, IDENTIFIED, 0.0).accepted
    n = 600
    rr_currents, others = [], []
    for k in range(n):
        _, currents, _ = rt.step(t_clock=k * rt.dt)
        rr_currents.append(currents[3])
        others.append(currents[:3])
    assert rt.steps == n
    assert rt.normal_steps == [n, n, n, 0]
    assert rt.modes == ['normal', 'normal', 'normal', 'failsafe']
    assert all(i == SAFE_A for i in rr_currents)
    # the controlled corners use their inverse: their currents move over the coil range
    others = np.asarray(others)
    assert np.all((others >= 0.0) & (others <= 2.0))
    assert np.ptp(others, axis=0).min() > 0.1
    st = rt.status()
    assert st['corners_normal'] == 3
    assert [st['corners'][c]['params_accepted'] for c in ('fl', 'fr', 'rl', 'rr')] == [1, 1, 1, 0]
    assert st['corners']['rr']['mode'] == 'failsafe'
    assert math.isnan(st['corners']['rr']['first_normal_t_sim'])
    assert st['corners']['fl']['first_normal_t_sim'] == pytest.approx(-0.1)


def test_body_log_covers_the_recorded_time_only_and_gives_iso_figures():
    rt = _runtime(log_max_s=0.3)
    for k in range(600):                                    # 0.1 s settling + 0.5 s
        rt.step(t_clock=k * rt.dt)
    t, acc = rt.body_log()
    assert len(t) == 301 and acc.shape == (301, 3)          # capped at log_max_s
    assert t[0] == pytest.approx(0.0, abs=1e-9) and np.all(np.diff(t) > 0)
    m = rt.body_metrics()
    assert m['a_v'] >= m['a_wz'] > 0
    assert m['duration_s'] == pytest.approx(0.301, abs=1e-6)   # 301 steps of 1 ms


def test_body_metrics_called_as_the_run_goes_equal_the_figures_of_the_whole_log():
    rt = _runtime()
    seen = []
    for k in range(1500):                                   # 0.1 s settling + 1.4 s
        rt.step(t_clock=k * rt.dt)
        if k in (150, 151, 700, 1200):                      # a status now and then
            seen.append(rt.body_metrics())
    t, acc = rt.body_log()
    whole = iso2631_seat(t, acc[:, 0], acc[:, 1], acc[:, 2])
    last = rt.body_metrics()
    for key, value in whole.items():
        assert last[key] == pytest.approx(value, rel=1e-9), key
    assert last['duration_s'] == pytest.approx(len(t) * rt.dt)
    # each earlier call had the figures of the log up to then
    assert [m['duration_s'] for m in seen] == pytest.approx([0.051, 0.052, 0.601, 1.101])
    assert seen[2]['a_v'] == pytest.approx(iso2631_seat(t[:601], *acc[:601].T)['a_v'],
                                           rel=1e-9)


def test_corner_state_is_the_quarter_car_view_of_the_corner():
    rt = _runtime()
    rt.step(0.0)
    s = rt.state
    for i in range(4):
        c = s.corner(i)
        assert c.z_s - c.z_u == pytest.approx(c.travel)
        assert c.v_s - c.v_u == pytest.approx(c.v_rel)
        assert c.tyre_force == s.tyre_force[i] and c.z_r == s.z_r[i]


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match='dt'):
        _runtime(dt=0.0)
    with pytest.raises(ValueError, match='log_max_s'):
        _runtime(log_max_s=-1.0)
