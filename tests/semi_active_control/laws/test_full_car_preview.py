"""Tests of semi_active_control.laws.full_car_preview: the full car's LQ preview, road sources."""
import json

import numpy as np
import pytest
from scipy.linalg import expm

from mr_damper_model.identification import presets
from mr_damper_model.models.plant import KwokCurrentPlant
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.simulate.full_car import simulate_full_car
from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.laws.full_car_lqr import relative_model
from semi_active_control.laws.full_car_lqr_wk import (FullCarClippedOptimalWk,
                                                      full_car_lqr_wk_design)
from semi_active_control.laws.full_car_preview import (FedFullCarLaw, full_car_lq_preview,
                                                       FullCarPreviewLaw,
                                                       make_full_car_preview_law,
                                                       make_road_preview)
from quarter_car_sim.plant.preview_sensor import IDEAL_LOOK_AHEAD, PreviewFeed, SpeedSignal
from semi_active_control.estimation.road_preview import FrontRoadEstimate

P = PASSENGER_CAR


@pytest.fixture(scope='module')
def design():
    return full_car_lqr_wk_design(P)


def _full_model(design):
    """Return the unreduced car (15 states, the road warp kept) with the 20 filter states."""
    A, B, Cy, Dy, n = relative_model(P)
    aw, bw, cw, dw = design.filter
    ca = design.model['Ca']
    da = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]) @ Dy   # seat at the CG
    nw = aw.shape[0]
    af = np.zeros((15 + nw, 15 + nw))
    af[:15, :15], af[15:, :15], af[15:, 15:] = A, bw @ ca, aw
    bf = np.vstack([B, bw @ da])
    e = np.zeros((15 + nw, 4))
    e[4:8] = -np.eye(4)
    e[11:15] = np.diag(P.c_t / P.m_u)
    cz = np.zeros((18, 15 + nw))
    cz[0:3, :15], cz[0:3, 15:] = dw @ ca, cw
    cz[3:6, :15] = Cy
    cz[6:14, :8] = np.eye(8)
    dz = np.vstack([dw @ da, Dy, np.zeros((8, 4)), np.eye(4)])
    return af, bf, e, cz, dz, n


def _dp_first_move(design, x0, zdot, dtf, tail_s):
    """
    Return the first move of the finite-horizon QP with the road known.

    Exact discretisation at ``dtf``, rectangle-rule cost, road velocities ``zdot`` (steps, 4)
    then held still for ``tail_s``; solved by dynamic programming on the unreduced car: the
    warp is a state here.
    """
    af, bf, e, cz, dz, _ = _full_model(design)
    nx, m = bf.shape
    big = np.zeros((nx + m + 4, nx + m + 4))
    big[:nx, :nx], big[:nx, nx:nx + m], big[:nx, nx + m:] = af, bf, e
    ex = expm(big * dtf)
    ad, bd, gd = ex[:nx, :nx], ex[:nx, nx:nx + m], ex[:nx, nx + m:]
    w = design.model['W']
    mxx, mxu, muu = cz.T @ w @ cz * dtf, cz.T @ w @ dz * dtf, dz.T @ w @ dz * dtf
    steps = zdot.shape[0] + int(round(tail_s / dtf))
    s_mat, s_vec = np.zeros((nx, nx)), np.zeros(nx)
    for k in range(steps - 1, -1, -1):
        g = gd @ zdot[k] if k < zdot.shape[0] else np.zeros(nx)
        sb = s_mat @ bd
        quu = muu + bd.T @ sb
        qux = mxu.T + sb.T @ ad
        qu = bd.T @ (s_mat @ g + s_vec)
        qx = ad.T @ (s_mat @ g + s_vec)
        kk = np.linalg.solve(quu, np.column_stack([qux, qu]))
        s_mat = mxx + ad.T @ s_mat @ ad - qux.T @ kk[:, :nx]
        s_mat = 0.5 * (s_mat + s_mat.T)
        s_vec = qx - qux.T @ kk[:, nx]
    return -(kk[:, :nx] @ x0 + kk[:, nx])


@pytest.mark.slow
def test_full_car_preview_equals_the_brute_force_qp_with_the_warp_as_a_state(design):
    # the closed form works on the warp-free subspace with the road warp as a known input;
    # the brute force keeps the warp as a state of the whole car: both must give the first move
    h, horizon = 1e-3, 0.04
    pv = full_car_lq_preview(design, P, horizon, h)
    rng = np.random.default_rng(5)
    heights = np.cumsum(rng.normal(0.0, 1e-3, (41, 4)), axis=0)     # four different wheels
    _, _, _, _, _, n = _full_model(design)
    V = design.model['V']
    u_n = np.concatenate([n, n, np.zeros(7)]) / np.sqrt(2.0)
    ff = pv.feedforward(heights)
    xw = rng.normal(0.0, 1.0, 34)                   # reduced car state and filter states,
    xw *= np.linalg.norm(ff) / np.linalg.norm(pv.gain @ xw)      # feedback as large as ff
    x = V @ xw[:14] + u_n * (-(n @ heights[0]) / np.sqrt(2.0))        # the road's warp now
    closed = -pv.gain @ xw + ff
    x0 = np.concatenate([x, xw[14:]])
    moves = []
    for dtf in (h / 2, h / 4):
        zdot = np.repeat(np.diff(heights, axis=0) / h, int(round(h / dtf)), axis=0)
        moves.append(_dp_first_move(design, x0, zdot, dtf, 3.0))
    coarse, fine = moves
    assert np.linalg.norm(fine - closed) < 0.6 * np.linalg.norm(coarse - closed)
    assert np.linalg.norm(2.0 * fine - coarse - closed) < 4e-3 * np.linalg.norm(closed)


def test_common_and_track_offsets_of_the_road_give_no_feedforward(design):
    # only height differences and the road warp act: a common offset and one per track
    # (left wheels together, right wheels together) are no input
    pv = full_car_lq_preview(design, P, 0.2)
    rng = np.random.default_rng(2)
    z = rng.normal(0.0, 1e-3, (pv.taps.shape[0], 4))
    off = np.array([0.02, -0.01, 0.02, -0.01])
    np.testing.assert_allclose(pv.feedforward(z + off), pv.feedforward(z), atol=1e-9)
    warp = np.array([1.0, -1.0, -1.0, 1.0]) * 1e-3
    assert np.abs(pv.feedforward(z + warp) - pv.feedforward(z)).max() > 1.0   # the warp acts


@pytest.fixture(scope='module')
def kwok():
    _, truth = presets.thesis_kwok_current()
    return truth, [KwokCurrentPlant(truth, coil_tau_s=0.0) for _ in range(4)]


@pytest.mark.slow
def test_zero_length_preview_is_todays_full_car_law(kwok):
    truth, plants = kwok
    road = make_two_track_road('iso8608-C', P, speed_m_s=20.0, duration_s=0.5, rng=3)
    today = simulate_full_car(P, road, FullCarClippedOptimalWk.from_car(P), plants, [truth] * 4)
    for source in ('wheelbase', 'look-ahead'):
        law = make_full_car_preview_law(P, source=source, horizon_s=0.0)
        fed = FedFullCarLaw(law, PreviewFeed(law.road, road,
                                             IDEAL_LOOK_AHEAD if source == 'look-ahead'
                                             else None))
        res = simulate_full_car(P, road, fed, plants, [truth] * 4)
        np.testing.assert_array_equal(res.current_cmd, today.current_cmd)


@pytest.mark.slow
@pytest.mark.parametrize('speed_error', [0.0, 0.02])
def test_the_front_road_delayed_by_the_wheelbase_is_the_rear_road(kwok, speed_error):
    # wheelbase preview on a straight two-track road: the road the law estimated under each
    # front wheel, placed by the odometer, is under the rear wheel one wheelbase later; with a
    # speed signal 2 % fast the odometer counts the wheelbase as 2 % shorter, so the map's
    # rear road is the road L e / (1 + e) (46 mm, 2.3 ms) ahead of the rear wheel
    truth, plants = kwok
    v, dt = 20.0, 1e-3
    road = make_two_track_road('iso8608-C', P, speed_m_s=v, duration_s=2.0, rng=4)
    law = make_full_car_preview_law(P, source='wheelbase', horizon_s=0.05)
    law.front = FrontRoadEstimate(2, leak_s=np.inf)
    fed = FedFullCarLaw(law, PreviewFeed(law.road, road, None, SpeedSignal(speed_error)))
    rows = []

    class Spy:
        name, corner_laws = 'spy', law.corner_laws

        def reset(self):
            fed.reset()

        def prepare(self, state):
            out = fed.prepare(state)
            z = law.road.window([0.0])
            if z is not None and state.t >= 0.0:
                rows.append(np.concatenate([[state.t], z[0], state.z_r]))
            return out

    simulate_full_car(P, road, Spy(), plants, [truth] * 4, settle_s=0.0)
    r = np.array(rows)
    t, est, true = r[:, 0], r[:, 1:5], r[:, 5:9]
    assert t[0] == pytest.approx(P.wheelbase / (v * (1 + speed_error)), abs=2e-3)
    err = est - true
    if speed_error == 0.0:
        # the rear wheels' road is the front wheels' (one offset per track: the estimate
        # starts on a road at 0) to a small fraction of the road's range
        for w in range(4):
            assert np.ptp(err[:, w]) < 0.005 * np.ptp(true[:, w])
        np.testing.assert_allclose(err[:, 2], err[:, 0].mean(), atol=0.005 * np.ptp(true))
        np.testing.assert_allclose(err[:, 3], err[:, 1].mean(), atol=0.005 * np.ptp(true))
    else:
        lag = P.wheelbase * speed_error / (1.0 + speed_error) / v       # 2.3 ms at 20 m/s
        for w in (2, 3):
            shifts = np.arange(0, 8)
            res = [np.ptp(est[8:-8, w] - np.interp(t[8:-8] + s * dt, t, true[:, w]))
                   for s in shifts]
            assert shifts[int(np.argmin(res))] == round(lag / dt)


@pytest.mark.slow
def test_preview_lowers_a_v_and_tyre_loads_on_the_car(kwok):
    truth, plants = kwok
    road = make_two_track_road('iso8608-C', P, speed_m_s=20.0, duration_s=2.0, rng=6)
    today = simulate_full_car(P, road, FullCarClippedOptimalWk.from_car(P), plants,
                              [truth] * 4).metrics(P)
    law = make_full_car_preview_law(P, source='look-ahead', horizon_s=0.3)
    fed = FedFullCarLaw(law, PreviewFeed(law.road, road, IDEAL_LOOK_AHEAD))
    m = simulate_full_car(P, road, fed, plants, [truth] * 4).metrics(P)
    assert m['a_v'] < 0.97 * today['a_v']
    assert m['max_rms_tyre_load_ratio'] < today['max_rms_tyre_load_ratio']
    st = fed.status()
    assert st['law']['previewed_steps'] > 0.9 * st['law']['steps']
    assert st['road_preview']['frames_taken'] == st['sensor_frames']['delivered']


def test_preview_law_refuses_bad_settings(design):
    base = FullCarClippedOptimalWk(design)
    pv = full_car_lq_preview(design, P, 0.1)
    with pytest.raises(ValueError, match='source'):
        FullCarPreviewLaw(base, pv, make_road_preview(P), source='radar')
    with pytest.raises(ValueError, match='feed'):
        law = FullCarPreviewLaw(base, pv, make_road_preview(P))
        FedFullCarLaw(law, PreviewFeed(make_road_preview(P), make_two_track_road(
            'iso8608-C', P, duration_s=0.2, rng=1)))


@pytest.mark.slow
def test_full_car_sim_prints_the_preview_rows_with_their_settings(capsys):
    from quarter_car_sim.tools.full_car_sim import main
    rows = 'preview-wheelbase,preview-look-ahead-ideal,preview-look-ahead'
    assert main(['--compare', '--laws', rows, '--duration', '0.3', '--json',
                 '--preview-latency', '0.03', '--speed-error', '0.01']) == 0
    out = json.loads(capsys.readouterr().out)
    assert list(out['laws']) == rows.split(',')
    wb, ideal, real = (out['laws'][n]['preview'] for n in rows.split(','))
    assert wb['source'] == 'wheelbase' and wb['sensor'] is None
    assert wb['speed_scale_error'] == 0.01 and ideal['speed_scale_error'] == 0.0
    assert ideal['sensor']['latency_s'] == 0.0 and real['sensor']['latency_s'] == 0.03
    assert real['sensor']['height_noise_m'] == 0.003 and real['horizon_s'] == 0.3
    for p in (wb, ideal, real):
        assert p['law']['steps'] == 801 and p['law']['previewed_steps'] > 0   # 0.5 s + 0.3 s
    assert main(['--compare', '--laws', 'preview-look-ahead', '--preview-range', '5']) == 2
    assert 'preview-range' in capsys.readouterr().err
