"""Tests of semi_active_control.laws.preview: the LQ preview design and the quarter-car law."""
import numpy as np
import pytest
from scipy.linalg import expm

from mr_damper_model.identification import presets
from mr_damper_model.models.plant import KwokCurrentPlant
from semi_active_control.laws.optimal import ClippedOptimalWk, wk_lqr_design
from semi_active_control.laws.preview import (ClippedOptimalWkPreview, lq_preview,
                                              quarter_car_lq_preview, quarter_car_road_input)
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.preview_sensor import (FedController, IDEAL_LOOK_AHEAD, LookAheadSpec,
                                                  PreviewFeed)
from quarter_car_sim.plant.road import iso8608
from semi_active_control.estimation.road_preview import RoadPreview
from quarter_car_sim.simulate.quarter_car import make_inverse, simulate

PARAMS = QuarterCarParams()


def _sqrt_psd(m):
    """Return L with L'L = m for a symmetric positive semi-definite m."""
    lam, vec = np.linalg.eigh(0.5 * (m + m.T))
    return (vec * np.sqrt(np.clip(lam, 0.0, None))).T


def _brute_force_first_move(A, B, Q, R, N, G, P, x0, heights, h, dtf):
    """
    First move of the finite-horizon QP with the road known, solved as one least squares.

    The car is discretised exactly at ``dtf`` (force held, road velocity constant over each
    ``h`` between the previewed heights), the cost summed by the rectangle rule over the
    horizon ``(len(heights) - 1) h`` plus the terminal cost ``x'Px`` (after the horizon the
    road is held: the infinite-horizon LQR's cost-to-go). Every force of every fine step is a
    decision variable.
    """
    n, m = B.shape
    k = int(round(h / dtf))
    steps = k * (len(heights) - 1)
    big = np.zeros((n + m + 1, n + m + 1))
    big[:n, :n], big[:n, n:n + m], big[:n, n + m] = A, B, G[:, 0]
    e = expm(big * dtf)
    ad, bd, gd = e[:n, :n], e[:n, n:n + m], e[:n, n + m]
    zdot = np.repeat(np.diff(heights) / h, k)
    x_u = np.zeros((n, m * steps))                  # state's dependence on the forces
    x_f = np.asarray(x0, dtype=float).copy()        # and on x0 and the road
    lw = _sqrt_psd(np.block([[Q, N], [N.T, R]])) * np.sqrt(dtf)
    rows, rhs = [], []
    for i in range(steps):
        u = np.zeros((m, m * steps))
        u[:, m * i:m * (i + 1)] = np.eye(m)
        rows.append(lw @ np.vstack([x_u, u]))
        rhs.append(lw @ np.concatenate([x_f, np.zeros(m)]))
        x_u = ad @ x_u
        x_u[:, m * i:m * (i + 1)] += bd
        x_f = ad @ x_f + gd * zdot[i]
    lp = _sqrt_psd(P)
    rows.append(lp @ x_u)
    rhs.append(lp @ x_f)
    u = np.linalg.lstsq(np.vstack(rows), -np.concatenate(rhs), rcond=None)[0]
    return u[:m]


def test_lq_preview_gain_equals_the_brute_force_finite_horizon_qp():
    # the closed form (Riccati solution, FIR over the horizon) against the QP over every force
    # of a finely discretised car with the road known: the QP converges to the continuous
    # optimum at first order in its step, so two steps extrapolate (Richardson) onto it
    design = wk_lqr_design(PARAMS)
    h, horizon = 1e-3, 0.03
    pv = quarter_car_lq_preview(design, PARAMS, horizon, h)
    assert pv.taps.shape == (31, 1, 1)
    np.testing.assert_allclose(pv.gain.ravel(), design.gain, rtol=1e-9)
    rng = np.random.default_rng(3)
    n = design.A.shape[0]
    heights = np.cumsum(rng.normal(0.0, 1e-3, 31))
    x0 = np.zeros(n)
    x0[:4] = rng.normal(0.0, [5e-3, 0.05, 1e-3, 0.1])          # travel, v_s, tyre def., v_u
    closed = -pv.gain @ x0 + pv.feedforward(heights[:, None])
    args = (design.A, design.B, design.Q, design.R, design.N,
            quarter_car_road_input(PARAMS, n), pv.P, x0, heights, h)
    coarse = _brute_force_first_move(*args, h / 2)
    fine = _brute_force_first_move(*args, h / 4)
    ff = pv.feedforward(heights[:, None])
    assert abs(ff[0]) > 0.2 * abs(closed[0])                    # the road part is not small
    assert abs(fine[0] - closed[0]) < 0.6 * abs(coarse[0] - closed[0])     # converges ...
    assert 2.0 * fine[0] - coarse[0] == pytest.approx(closed[0], rel=1e-4)  # ... onto it


def test_lq_preview_without_a_horizon_has_no_taps_and_the_lqr_gain():
    design = wk_lqr_design(PARAMS)
    pv = quarter_car_lq_preview(design, PARAMS, 0.0)
    assert pv.taps.shape == (1, 1, 1) and not pv.taps.any()
    np.testing.assert_allclose(pv.gain.ravel(), design.gain, rtol=1e-9)


def test_taps_see_height_differences_only():
    # the road enters the quarter car through its velocity: an offset of the whole previewed
    # road gives no feedforward (the taps sum to zero)
    pv = quarter_car_lq_preview(wk_lqr_design(PARAMS), PARAMS, 0.2)
    assert abs(pv.taps.sum()) < 1e-9 * np.abs(pv.taps).sum()
    z = np.linspace(0.0, 0.01, pv.taps.shape[0])[:, None]
    assert pv.feedforward(z + 0.05) == pytest.approx(pv.feedforward(z), abs=1e-9)


@pytest.mark.parametrize('kw, msg', [(dict(horizon_s=-1.0, step_s=1e-3), 'horizon_s'),
                                     (dict(horizon_s=0.1, step_s=0.0), 'step_s')])
def test_lq_preview_refuses_bad_options(kw, msg):
    d = wk_lqr_design(PARAMS)
    with pytest.raises(ValueError, match=msg):
        lq_preview(d.A, d.B, d.Q, d.R, d.N, quarter_car_road_input(PARAMS, d.A.shape[0]), **kw)


@pytest.fixture(scope='module')
def kwok():
    _, truth = presets.thesis_kwok_current()
    return truth, KwokCurrentPlant(truth, coil_tau_s=0.0), make_inverse(truth)


def _preview_law(design, inverse, road, horizon, spec=IDEAL_LOOK_AHEAD, name='pv'):
    base = ClippedOptimalWk(design, inverse.body_force_range)
    rp = RoadPreview(1, [(0, 0.0)])
    law = ClippedOptimalWkPreview(base, quarter_car_lq_preview(design, PARAMS, horizon), rp,
                                  name=name)
    return FedController(law, PreviewFeed(rp, road, spec))


def test_zero_length_preview_is_todays_law(kwok):
    _, plant, inverse = kwok
    road = iso8608('C', 20.0, 1.0, 1e-3, rng=5)
    design = wk_lqr_design(PARAMS)
    today = simulate(PARAMS, road, ClippedOptimalWk(design, inverse.body_force_range), plant,
                     inverse=inverse)
    law = _preview_law(design, inverse, road, 0.0)
    res = simulate(PARAMS, road, law, plant, inverse=inverse)
    np.testing.assert_array_equal(res.current_cmd, today.current_cmd)
    np.testing.assert_array_equal(res.demand, today.demand)


@pytest.mark.slow
def test_preview_lowers_wk_on_the_car_and_feeds_forward(kwok):
    # the ideal look-ahead law against today's law on the same road, damper model = plant
    _, plant, inverse = kwok
    road = iso8608('C', 20.0, 4.0, 1e-3, rng=6)
    design = wk_lqr_design(PARAMS)
    today = simulate(PARAMS, road, ClippedOptimalWk(design, inverse.body_force_range), plant,
                     inverse=inverse).metrics()
    law = _preview_law(design, inverse, road, 0.2)
    m = simulate(PARAMS, road, law, plant, inverse=inverse).metrics()
    assert m['rms_body_accel_wk'] < 0.98 * today['rms_body_accel_wk']
    st = law.law.stats.as_dict()
    # before the first frame reaches the wheel (0.5 m ahead at 20 m/s: 25 steps) it falls back
    assert st['dropouts'] == 1 and 20 <= st['fallback_steps'] <= 30
    assert st['previewed_steps'] == st['steps'] - st['fallback_steps']


@pytest.mark.slow
def test_a_preview_dropout_falls_back_to_todays_law_and_is_counted(kwok):
    # the sensor is blind 1.0-2.52 s: the law previews on the map it has until the wheel
    # passes the last frame's far end (15 m = 0.75 s later), then it is today's law until
    # a new frame covers the road under the wheel again (0.5 m after the frame's position)
    _, plant, inverse = kwok
    road = iso8608('C', 20.0, 3.0, 1e-3, rng=7)
    design = wk_lqr_design(PARAMS)
    spec = LookAheadSpec(outages=((1.0, 2.52),))
    law = _preview_law(design, inverse, road, 0.2, spec=spec)
    base = ClippedOptimalWk(design, inverse.body_force_range)
    seen = []

    class Spy:
        kind, name, state_fields = 'semi-active', 'spy', ('z_u', 'z_r')

        def reset(self):
            law.reset()
            base.reset()

        def demand(self, state):
            f = law.demand(state)
            seen.append((state.t, law.law.last_feedforward, f,
                         base.demand(state), law.law.stats.fallback_steps))
            return f

    simulate(PARAMS, road, Spy(), plant, inverse=inverse, settle_s=0.0)
    t, ff, f, f_base, fallbacks = (np.array(c) for c in zip(*seen))
    falling = np.diff(np.concatenate([[0], fallbacks])) > 0
    st = law.law.stats.as_dict()
    assert st['dropouts'] == 2                                 # the start and the outage
    frames = np.arange(0.0, 3.0, 1.0 / 18.0)
    last_before = frames[frames < 1.0][-1]
    first_after = frames[frames >= 2.52][0]
    out = falling & (t > 1.0)
    assert t[out][0] == pytest.approx(last_before + 15.0 / 20.0, abs=2.5e-3)
    assert t[out][-1] == pytest.approx(first_after + 0.5 / 20.0, abs=2.5e-3)
    assert np.all(ff[falling] == 0.0)
    np.testing.assert_allclose(f[falling], f_base[falling], atol=1e-9)   # today's law
    assert np.any(ff[~falling] != 0.0)
    counts = law.status()
    blind = int(np.sum((frames >= 1.0) & (frames < 2.52)))
    assert counts['road_preview']['frame_invalid'] == counts['sensor_frames']['outage'] == blind
