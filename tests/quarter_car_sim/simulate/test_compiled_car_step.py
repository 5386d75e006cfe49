"""The car's step with the compiled Spencer damper equals the interpreted one (the reference)."""
import dataclasses

import numpy as np

from mr_damper_model.models import presets
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.plant.quarter_car import QuarterCar
from quarter_car_sim.plant.road import make_road
from quarter_car_sim.simulate import live_loop
from semi_active_control.car.quarter_car import QuarterCarParams
from semi_active_control.laws import Skyhook
from semi_active_control.supervision.failsafe import ModelSupervisor


def _run(compiled, steps=1500):
    """Run the suite's car (skyhook, supervised inverse, Spencer truth) on ISO C."""
    params = QuarterCarParams()
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=4, duration_s=2.0)
    car = QuarterCar(params, make_plant('spencer', compiled=compiled), road, t0=-0.2)
    sup = ModelSupervisor(timeout_s=1.0, safe_current_a=0.5)
    loop = live_loop.ClosedLoop(car, Skyhook(3000.0), sup, 1e-3,
                                metrics=live_loop.make_running_metrics(params, 1e-3))
    model, truth = presets.thesis_kwok_current()
    msg = dict(truth, i_ref_a=model.options['i_ref_a'], current_min_a=0.0, current_max_a=2.0,
               valid=1.0)
    rows, currents = [], []
    for k in range(steps):
        if k == 300:
            sup.offer(msg, 1e-3 * k)            # fail-safe first, then the inverse in use
        rows.append(dataclasses.astuple(loop.step(1e-3 * k)))
        currents.append(loop.i_cmd)
    return np.array(rows), np.array(currents), live_loop.metrics_dict(loop.metrics)


def test_the_car_with_the_compiled_damper_step_is_the_reference_car_step_for_step():
    states, currents, metrics = _run(compiled=True)
    ref_states, ref_currents, ref_metrics = _run(compiled=False)
    # the loop ran both modes, the damper moved and the commands varied (not a trivial run)
    assert currents[0] == 0.5 and np.ptp(currents[400:]) > 1.0
    assert np.ptp(states[:, -2]) > 200.0                         # damper force [N]
    np.testing.assert_array_equal(states, ref_states)
    np.testing.assert_array_equal(currents, ref_currents)
    assert metrics == ref_metrics
