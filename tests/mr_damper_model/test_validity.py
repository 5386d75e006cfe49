"""The one rule for a parameter set's values, shared by the identifier and the car's supervisor."""
import math

import pytest

from mr_damper_model.models.presets import thesis_kwok_current
from mr_damper_model.live import LiveConfig
from mr_damper_model.models.validity import (BOUND_TOL, check_model_parameters,
                                             check_parameter_values, PINNED_FRACTION)
from semi_active_control.supervision.failsafe import kwok_current_bounds, ModelSupervisor

NAMES = ('c', 'k', 'beta', 'f0')
LO, HI = (0.0, -1e4, 0.1, -500.0), (1e5, 1e4, 1000.0, 500.0)


@pytest.mark.parametrize('values, reason, names', [
    ((10.0, 0.0, 5.0, 0.0), '', ()),
    ((0.0, 0.0, 5.0, 0.0), '', ()),                          # a zero bound is physical
    ((math.nan, 0.0, 5.0, 0.0), 'non_finite', ('c',)),
    ((-1.0, 0.0, 5.0, 0.0), 'out_of_bounds', ('c',)),
    ((10.0, 0.0, 5.0, 500.0), 'pinned_at_bound', ('f0',)),
    ((10.0, 0.0, 999.5, -499.6), 'pinned_at_bound', ('beta', 'f0')),
])
def test_reasons_and_names(values, reason, names):
    check = check_parameter_values(NAMES, values, LO, HI)
    assert (check.reason, check.names) == (reason, names)
    assert bool(check) == (reason == '')


def test_bound_tolerance_is_a_fraction_of_the_span():
    span = HI[0] - LO[0]
    just_out = (HI[0] + 0.5 * BOUND_TOL * span, 0.0, 5.0, 0.0)
    far_out = (HI[0] + 2 * BOUND_TOL * span, 0.0, 5.0, 0.0)
    assert check_parameter_values(NAMES, just_out, LO, HI, pinned_fraction=None).reason == ''
    assert check_parameter_values(NAMES, far_out, LO, HI).reason == 'out_of_bounds'


def test_exempt_parameters_leave_the_pinned_check_only():
    values = (10.0, 0.0, 1000.0, 0.0)
    assert check_parameter_values(NAMES, values, LO, HI).reason == 'pinned_at_bound'
    assert check_parameter_values(NAMES, values, LO, HI, exempt=('beta',)).reason == ''


def _car_verdict(params):
    sup = ModelSupervisor(timeout_s=10.0, safe_current_a=0.5)
    msg = dict(params, i_ref_a=2.0, current_min_a=0.0, current_max_a=2.0, valid=1.0)
    return sup.check(msg)


@pytest.mark.parametrize('name, where', [('f0', 'hi'), ('beta0', 'lo'), ('c1', 'hi'),
                                         ('beta1', 'lo')])
@pytest.mark.parametrize('offset', [-2.0, -0.5, 0.5, 2.0])
def test_identifier_and_car_agree_at_every_edge(name, where, offset):
    # a set moved to (and around) a bound of one parameter: both sides reach the same verdict
    _, truth = thesis_kwok_current()
    bounds = kwok_current_bounds()
    lo, hi = bounds[name]
    edge = hi if where == 'hi' else lo
    step = (hi - lo) * (PINNED_FRACTION if abs(offset) < 1 else BOUND_TOL)
    params = dict(truth, **{name: edge + offset * step})
    ident = check_model_parameters('kwok-current', params, i_ref_a=2.0)
    car = _car_verdict(params)
    assert ident.reason == (car.reason if not car.accepted else ''), (ident, car)


def test_both_sides_default_to_the_same_pinned_fraction():
    assert LiveConfig().pinned_fraction == PINNED_FRACTION
    assert ModelSupervisor(timeout_s=1.0, safe_current_a=0.5).pinned_fraction == PINNED_FRACTION
