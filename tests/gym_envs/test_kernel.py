"""
The compiled car step (mr_damper_gym.kernel) against the simulator's own plain-Python step.

The kernel mirrors, for arrays of cars, QuarterCar / FullCar with their damper plants, the road
sampling, the ISO 2631-1 filters of the metrics and the sensors' error model; these tests drive
both with the same roads, currents and random numbers and compare sample by sample.
"""
import math

import numpy as np
import pytest

from mr_damper_gym.batch import CarBatch
from mr_damper_gym.core import EnvCore
from mr_damper_gym import roads as R
from mr_damper_model.models.plant import make_plant
from mr_damper_model.models.presets import spencer_thesis_like
from mr_damper_model.models.spencer import (heun_substeps, heun_substeps_lanes, z_roots,
                                            z_step_rooted)
from semi_active_control.laws import Passive
from quarter_car_sim.plant.quarter_car import QuarterCar
from quarter_car_sim.plant.full_car import FullCar
from quarter_car_sim.simulate.full_car import simulate_full_car
from quarter_car_sim.plant.sensors import Sensor
from semi_active_control.estimation.sensor_specs import accelerometer_spec, ride_height_spec
from quarter_car_sim.simulate.quarter_car import simulate


def _core(car, plant, **kw):
    return EnvCore(car, plant=plant, episode_end='none', observation='state', **kw)


def _road(core, seed, duration_s=0.6):
    spec = R.road_spec(core.defaults, {'road_seed': seed, 'duration_s': duration_s,
                                       'road_class': 'D', 'events': [{'kind': 'bump',
                                                                      'at_s': 0.2}]}, None)
    return R.build_road(core.car, core.params, spec, core.dt)


def _kernel_run(core, road, currents):
    """Step one car through ``currents`` (n, nc); return the true-state rows after each."""
    b = CarBatch(core.model, 1)
    core._load(b, 0, road, float(currents[0][0]), None)
    rows = [b.obs[0, :core.model.n_state_obs].copy()]
    for c in currents:
        b.step(np.asarray(c, dtype=float)[None, :])
        rows.append(b.obs[0, :core.model.n_state_obs].copy())
    return np.array(rows), b


def _currents(n, nc, seed):
    rng = np.random.default_rng(seed)
    return np.repeat(rng.uniform(0.0, 2.0, (n // 20 + 1, nc)), 20, axis=0)[:n]


@pytest.mark.parametrize('plant', ['kwok-current', 'spencer'])
def test_quarter_car_step_is_the_simulators(plant):
    core = _core('quarter', plant)
    road = _road(core, 4)
    n = 600
    cur = _currents(n, 1, 1)
    rows, _ = _kernel_run(core, road, cur)
    t0 = -core.settle_steps * core.dt
    car = QuarterCar(core.params, make_plant(plant), road, t0=t0)
    for _ in range(core.settle_steps):
        car.step(core.dt, cur[0, 0])
    ref = [car.state]
    for c in cur:
        ref.append(car.step(core.dt, c[0]))
    travel = np.array([s.travel for s in ref])
    force = np.array([s.damper_force for s in ref])
    a_s = np.array([s.a_s for s in ref])
    tyre = np.array([s.z_u - s.z_r for s in ref])
    # same operations in the same order: equal to the last bit, but for the body
    # acceleration, formed in another order (round-off), and the Spencer plant's force: the
    # kernel's plant takes its own tanh (``spencer.tanh_lanes``, within a few ulp of the C
    # library's), so its force is the simulator's to round-off (1.2e-16 of the peak when
    # written; held to 1e-12), and the travel over this run still to the bit
    assert np.array_equal(rows[:, 0], travel)
    if plant == 'spencer':
        np.testing.assert_allclose(rows[:, 6], force, rtol=1e-12,
                                   atol=1e-12 * np.max(np.abs(force)))
    else:
        assert np.array_equal(rows[:, 6], force)
    np.testing.assert_allclose(rows[:, 1], tyre, rtol=0, atol=1e-15)
    np.testing.assert_allclose(rows[:, 4], a_s, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(rows[:, 7], [s.coil_current for s in ref])
    assert np.ptp(force) > 100.0        # the currents and the bump did move the damper


def test_full_car_step_is_the_simulators():
    core = _core('full', 'spencer')
    road = _road(core, 7)
    n = 500
    cur = _currents(n, 4, 2)
    rows, _ = _kernel_run(core, road, cur)
    car = FullCar(core.params, [make_plant('spencer') for _ in range(4)], road,
                  t0=-core.settle_steps * core.dt)
    for _ in range(core.settle_steps):
        car.step(core.dt, np.full(4, cur[0, 0]))      # the env settles at one current
    ref = [car.state]
    for c in cur:
        ref.append(car.step(core.dt, c))
    # the 14 x 31 products are summed in another order than numpy's: round-off only
    for j, field in ((0, 'travel'), (2, 'v_rel'), (6, 'damper_force'), (7, 'coil_current')):
        truth = np.array([getattr(s, field) for s in ref])
        scale = np.max(np.abs(truth))
        np.testing.assert_allclose(rows[:, 4 * j:4 * j + 4], truth, rtol=0, atol=1e-9 * scale)
    acc = np.array([s.acc[:3] for s in ref])
    np.testing.assert_allclose(rows[:, 42:45], acc, rtol=0, atol=1e-9 * np.max(np.abs(acc)))
    assert np.min([s.tyre_force.min() for s in ref]) < 0.5 * core.params.static_tyre_loads.min()


def test_spencer_lanes_are_heun_substeps_to_round_off():
    """
    The kernel's four plants side by side (``heun_substeps_lanes``) are each one's step.

    Not bit for bit: the lanes take their own tanh (``tanh_lanes``, within a few ulp of the C
    library's, which ``heun_substeps`` with ``z_step_rooted`` calls); over 40 draws of ten
    sub-steps the states differ by at most 3.4e-16 relative (z: of its saturation value
    ``zs``); held to 1e-12.
    """
    rng = np.random.default_rng(8)
    p0 = np.array(list(spencer_thesis_like().values()), dtype=float)
    worst = 0.0
    for _ in range(40):
        P = np.tile(p0, (4, 1))
        # beta == gamma (the linear branch), beta > gamma (tanh), beta < gamma (tan), beta 0
        P[:, 9:11] = [[3.63e6, 3.63e6], [2e6, 5e6], [4e6, 1e6], [2e6, 0.0]]
        P[:, 12] = rng.uniform(50.0, 300.0, 4)
        zc = np.array([z_roots(P[q, 11], P[q, 10], P[q, 9]) for q in range(4)])
        h = np.full(4, 1e-4)
        decay = np.exp(-P[:, 12] * h)
        y, u, xs = rng.normal(0.0, 0.01, 4), rng.uniform(0.0, 2.0, 4), rng.normal(0.0, 0.02, 4)
        z = rng.uniform(-1.0, 1.0, 4) * zc[:, 2]
        vs, dx, dv = rng.normal(0.0, 0.3, 4), rng.normal(0.0, 3e-5, 4), rng.normal(0.0, 3e-3, 4)
        i_drv = rng.uniform(0.0, 2.0, 4)
        want = np.array([heun_substeps(z_step_rooted, tuple(zc[q]), tuple(P[q]), y[q], z[q],
                                       u[q], xs[q], vs[q], dx[q], dv[q], i_drv[q], h[q],
                                       decay[q], 10)
                         for q in range(4)])
        got = [a.copy() for a in (y, z, u, xs, vs)]
        heun_substeps_lanes(z_step_rooted, zc, P, h, decay, 10, *got, dx, dv, i_drv,
                            np.empty((4, 8)))
        got = np.array(got[:3]).T
        scale = np.abs(want)
        scale[:, 1] = np.maximum(scale[:, 1], zc[:, 2])
        worst = max(worst, np.max(np.abs(got - want) / scale))
        assert np.all(np.abs(got - want) <= 1e-12 * scale)
    assert worst > 0.0      # the own tanh is in use (3.4e-16 when written)


@pytest.mark.slow
@pytest.mark.parametrize('car', ['quarter', 'full'])
def test_running_iso_figures_are_the_offline_metrics(car):
    """The kernel's ISO filters and sums give the offline tools' metrics of the same run."""
    core = _core(car, 'spencer')
    road = _road(core, 3, duration_s=1.0)
    fig = core.passive_figures(road, 0.8)
    plants = [make_plant('spencer') for _ in range(core.model.nc)]
    if car == 'quarter':
        m = simulate(core.params, road, Passive(0.8), plants[0]).metrics()
        keys = ('rms_body_accel_wk', 'rms_tyre_load_ratio', 'rms_suspension_travel',
                'rms_body_accel')
        assert fig['n_samples'] == m['n_samples']
    else:
        m = simulate_full_car(core.params, road, 'passive@0.8A', plants,
                              core.damper_params).metrics(core.params)
        keys = ('a_wz', 'a_w_pitch', 'a_w_roll', 'a_v', 'vdv_total', 'crest_max',
                'max_rms_tyre_load_ratio')
    for key in keys:
        assert fig[key] == pytest.approx(m[key], rel=1e-9), key


@pytest.mark.parametrize('kind, spec', [
    ('accel', accelerometer_spec(dropout_prob=0.05)),
    ('travel', ride_height_spec(dropout_prob=0.05, dropout_mode='hold', bias=1e-3,
                                bias_rw=1e-4)),
    ('accel', accelerometer_spec(latency_s=0.0, bias_drift=0.01, dropout_prob=0.02))],
    ids=['accelerometer', 'position_hold', 'no_latency_drift'])
def test_sensor_model_is_the_simulators(kind, spec):
    """Readings equal ``quarter_car_sim.plant.sensors.Sensor.sample`` fed the same draws."""
    from mr_damper_gym.batch import DRAW_BLOCK
    dt = 1e-3
    core = _core('quarter', 'kwok-current', settle_s=0.0,
                 sensors=[('s', kind, 0, spec)])
    road = _road(core, 2)
    b = CarBatch(core.model, 1)
    core._load(b, 0, road, 0.0, np.random.default_rng(11))
    n = 600
    col = 4 if kind == 'accel' else 0              # body acceleration or travel of the state
    slot = core.model.n_state_obs
    truth, got = [], []
    cur = _currents(n, 1, 3)
    for c in cur:
        b.step(c[None, :])
        truth.append(b.obs[0, col])
        got.append(b.obs[0, slot] if b.obs[0, slot + 1] else math.nan)
    # the same numbers: the turn-on bias, then the first block (random walk, noise, loss)
    g = np.random.default_rng(11)
    bias = spec.bias + (g.normal(0.0, spec.bias_std) if spec.bias_std else 0.0)
    normal = g.standard_normal((DRAW_BLOCK, 1, 2))[:, 0].T
    loss = g.random((DRAW_BLOCK, 1))[:, 0]
    sensor = Sensor(spec.replace(bias=bias, bias_std=0.0))
    normals, uniforms = [], []
    for j in range(n):
        if j > 0 and spec.bias_rw:
            normals.append(normal[0, j])
        normals.append(normal[1, j])
        uniforms.append(loss[j])
    sensor._normal, sensor._uniform = normals[::-1], uniforms[::-1]
    sampled = [sensor.sample((j + 1) * dt, x) for j, x in enumerate(truth)]
    lat = int(round(spec.latency_s / dt))
    want = np.array([math.nan] * lat + sampled[:n - lat])
    got = np.array(got)
    lost = np.isnan(want)
    assert lost.sum() >= 5 or spec.dropout_mode == 'hold'
    np.testing.assert_array_equal(np.isnan(got), lost)
    np.testing.assert_allclose(got[~lost], want[~lost], rtol=0, atol=1e-12)
    assert sensor.n_dropped >= 5
