"""
Tests of docs/extending.md: its python blocks run as written, and what they build is right.

The blocks of each ``##`` section are taken from the markdown and run in order in one
namespace; the law the first section adds to the registry is removed again afterwards.
"""
import pathlib
import re

import numpy as np
import pytest

from mr_damper_common.contract import CornerState
from quarter_car_sim.plant.quarter_car import LinearDamperPlant
from quarter_car_sim.simulate.quarter_car import simulate
from semi_active_control.car.quarter_car import QuarterCarParams
from semi_active_control.laws import law_names, LawOptions, LAWS, make_controller
from semi_active_control.runtime.controller_core import make_node_law

DOC = pathlib.Path(__file__).resolve().parents[1] / 'docs' / 'extending.md'


def _blocks(section):
    """Return the ```python blocks of the ``## section`` of docs/extending.md, in order."""
    text = DOC.read_text()
    parts = re.split(r'^## ', text, flags=re.M)
    body = [p for p in parts if p.startswith(section + '\n')]
    assert len(body) == 1, f'no single section {section!r} in {DOC}'
    blocks = re.findall(r'^```python\n(.*?)^```$', body[0], flags=re.M | re.S)
    assert blocks, f'no python block under {section!r}'
    return blocks


def _text_blocks(section):
    """Return the ```text blocks of a section (the lines the doc tells to add)."""
    text = DOC.read_text().split('\n## ' + section + '\n', 1)[1].split('\n## ', 1)[0]
    return re.findall(r'^```text\n(.*?)^```$', text, flags=re.M | re.S)


def _run(section):
    ns = {'__name__': 'docs_extending'}
    for block in _blocks(section):
        exec(compile(block, f'{DOC.name}: {section}', 'exec'), ns)
    return ns


@pytest.fixture(scope='module')
def law_doc():
    """Run the law section; restore the registry afterwards (the doc adds an entry)."""
    saved = dict(LAWS)
    try:
        yield _run('Add a control law')
    finally:
        LAWS.clear()
        LAWS.update(saved)


def _state(v_s, v_u):
    return CornerState(0.0, 0.0, v_s, 0.0, 0.0, v_u, 0.0, 0.0, 0.0, v_s - v_u, 3500.0, 0.0, 0.0)


@pytest.mark.slow
def test_law_is_registered_built_and_its_values_are_the_on_off_groundhook(law_doc):
    cls = law_doc['GroundhookOnOff']
    assert 'groundhook-onoff' in law_names() and 'groundhook-onoff' in law_names(damper_only=True)
    assert isinstance(make_controller('groundhook-onoff'), cls)
    node_law = make_node_law('groundhook-onoff', QuarterCarParams(), 1000.0, {})
    assert isinstance(node_law, cls) and node_law.kind == 'semi-active'
    law = cls(4000.0, 300.0)
    # v_u v_rel < 0 (wheel moving down, suspension extending): c_on
    assert law.demand(_state(0.1, -0.2)) == pytest.approx(-4000.0 * 0.3)
    # v_u v_rel > 0: c_off
    assert law.demand(_state(0.5, 0.2)) == pytest.approx(-300.0 * 0.3)
    with pytest.raises(ValueError):
        cls(100.0, 200.0)


def test_law_registry_line_of_the_doc_builds_the_law(law_doc):
    # the line the doc tells to add to LAWS in registry.py is the entry the example registers
    line = next(b for b in _text_blocks('Add a control law') if 'Law(' in b)
    entry = eval('{' + line + '}', dict(law_doc))
    assert list(entry) == ['groundhook-onoff']
    law = entry['groundhook-onoff']
    assert (law.car, law.kind) == (LAWS['groundhook-onoff'].car, LAWS['groundhook-onoff'].kind)
    assert isinstance(law.make(LawOptions()), law_doc['GroundhookOnOff'])


def test_law_runs_on_the_quarter_car_against_passive(law_doc):
    results = law_doc['results']
    assert list(results) == ['passive@0.0A', 'passive@2.0A', 'groundhook', 'groundhook-onoff']
    r = results['groundhook-onoff']
    m = {name: res.metrics() for name, res in results.items()}
    for name in results:
        assert np.isfinite(m[name]['rms_body_accel_wk']) and m[name]['rms_body_accel_wk'] > 0
    # the law's demands are dissipative and its commands within the coil's range
    assert np.all(r.demand * r.v_rel <= 0.0)
    assert np.all((r.current_cmd >= 0.0) & (r.current_cmd <= 2.0))
    assert 0.0 < m['groundhook-onoff']['mean_current_a'] < 2.0
    # the damper it drives lies between its softest and its hardest setting
    f = m['groundhook-onoff']['rms_damper_force']
    assert m['passive@0.0A']['rms_damper_force'] < f < m['passive@2.0A']['rms_damper_force']
    # a road-holding law: less dynamic tyre load than the softest setting
    assert m['groundhook-onoff']['rms_tyre_load_ratio'] < m['passive@0.0A']['rms_tyre_load_ratio']


def test_law_at_zero_gain_is_the_softest_passive_setting(law_doc):
    # a law that always asks zero force gets the inverse's lowest current, passive at 0 A, but
    # for the few low-velocity samples where the identified model's 0 A force has the wrong
    # sign (there zero force is within reach and the inverse lifts the current)
    ns = law_doc
    zero = simulate(ns['params'], ns['road'], ns['GroundhookOnOff'](0.0, 0.0), ns['plant'],
                    damper_params=ns['identified'])
    soft = ns['results']['passive@0.0A']
    assert np.all(zero.demand == 0.0)
    assert np.mean(zero.current_cmd > 0.0) < 0.05
    assert zero.metrics()['rms_body_accel_wk'] == pytest.approx(
        soft.metrics()['rms_body_accel_wk'], rel=0.01)


@pytest.fixture(scope='module')
def damper_doc():
    """Run the damper section (it registers nothing)."""
    return _run('Add a damper model')


def test_damper_example_force_has_the_bingham_truths(damper_doc):
    ns = damper_doc
    plant_cls, drive, v = ns['BinghamCurrentPlant'], ns['drive'], ns['v']
    f = ns['f_bingham']
    # the force follows the velocity's sign (dissipative), as the Kwok plant's does on average
    moving = np.abs(v) > 1e-6
    assert np.all(np.sign(f[moving]) == np.sign(v[moving]))
    dx = np.diff(ns['x'])
    assert np.sum(f[1:] * dx) > 0.0 and np.sum(ns['f_kwok'][1:] * dx) > 0.0
    # held 1 A, no lag: |F| = f_y0 + f_y1 + c0 |v| from the first step on (sample 0 is before
    # any step: the coil is still at 0 A)
    p = plant_cls(f_y0=80.0, f_y1=300.0, c0=900.0, coil_tau_s=0.0)
    f1 = drive(p, 1.0)
    assert abs(f1[0]) == pytest.approx(80.0 + 900.0 * abs(v[0]), rel=1e-12)
    np.testing.assert_allclose(np.abs(f1[1:][moving[1:]]),
                               380.0 + 900.0 * np.abs(v[1:][moving[1:]]), rtol=1e-12)
    # zero yield force: a linear damper c0 v, exactly
    f0 = drive(plant_cls(f_y0=0.0, f_y1=0.0, c0=1234.0), 2.0)
    np.testing.assert_array_equal(f0, drive(LinearDamperPlant(1234.0), 2.0))
    # the coil lag: after 5 time constants at 2 A the yield force is within 1 % of f_y(2 A)
    q = plant_cls(f_y0=0.0, f_y1=500.0, c0=0.0)
    q.reset()
    q.step(0.0, 0.0, 0.1, 2.0)
    for _ in range(int(round(5 * q.coil_tau_s / 1e-3)) + 1):
        force = q.step(1e-3, 0.0, 0.1, 2.0)
    assert 0.99 * 1000.0 < force <= 1000.0
    with pytest.raises(ValueError):
        plant_cls(c0=-1.0)


def test_damper_make_plant_branch_of_the_doc_builds_the_plant(damper_doc):
    # the return line the doc tells to add to make_plant builds the plant, defaults or given
    block = next(b for b in _text_blocks('Add a damper model')
                 if 'return BinghamCurrentPlant(' in b)
    expr = block.split('return ', 1)[1].strip()
    ns = dict(damper_doc)
    plant = eval(expr, {**ns, 'params': None, 'options': {}})
    assert isinstance(plant, ns['BinghamCurrentPlant'])
    assert plant.params == {'f_y0': 50.0, 'f_y1': 250.0, 'c0': 800.0}
    plant = eval(expr, {**ns, 'params': {'c0': 1200.0}, 'options': {'slew_a_per_s': 400.0}})
    assert plant.params['c0'] == 1200.0 and plant.slew_a_per_s == 400.0


def test_damper_example_in_the_quarter_car(damper_doc):
    ns = damper_doc
    m = ns['on_bingham'].metrics()
    assert np.isfinite(m['rms_body_accel_wk']) and m['rms_body_accel_wk'] > 0.0
    # with no yield force the car on the new plant is the car on a linear damper, sample for
    # sample
    params, road = QuarterCarParams(), ns['road']
    a = simulate(params, road, make_controller('passive@1A'),
                 ns['BinghamCurrentPlant'](f_y0=0.0, f_y1=0.0, c0=1500.0))
    b = simulate(params, road, make_controller('passive@1A'), LinearDamperPlant(1500.0))
    np.testing.assert_array_equal(a.a_s, b.a_s)
    np.testing.assert_array_equal(a.tyre_force, b.tyre_force)
