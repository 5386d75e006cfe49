"""The law registry: one dict whose keys are the names, the factories and lists read off it."""
import pytest

from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.laws import (CONTROLLER_NAMES, DAMPER_LAW_NAMES, Law, law_names, LAWS,
                                      make_controller, make_full_car_law, Passive, Skyhook)


def test_the_names_are_the_keys_in_order():
    assert CONTROLLER_NAMES == ('passive@<I>A', 'skyhook', 'skyhook-onoff', 'groundhook',
                                'hybrid', 'add', 'sh-add', 'clipped-optimal',
                                'clipped-optimal-wk', 'skyhook-ideal', 'lqr-active')
    assert DAMPER_LAW_NAMES == CONTROLLER_NAMES[:-2]
    assert law_names('full') == ('modal-skyhook', 'full-car-clipped-optimal',
                                 'full-car-clipped-optimal-wk')
    assert set(LAWS) == ({'passive'} | set(CONTROLLER_NAMES[1:]) | set(law_names('full')))


@pytest.mark.parametrize('name', [n for n, law in LAWS.items() if law.car == 'quarter'])
def test_each_quarter_car_entry_makes_a_law_of_its_kind(name):
    law = make_controller(name)
    assert law.kind == LAWS[name].kind
    assert law.name == ('passive@0.0A' if name == 'passive' else name)


@pytest.mark.parametrize('name', [n for n, law in LAWS.items() if law.car == 'full'])
def test_each_full_car_entry_makes_a_law_with_four_corners(name):
    law = make_full_car_law(name, PASSENGER_CAR)
    assert law.name == name and len(law.corner_laws) == 4
    assert all(c.kind == LAWS[name].kind for c in law.corner_laws)


def test_a_law_added_to_the_dict_is_built_and_listed_by_both_factories():
    class Soft(Skyhook):
        pass

    LAWS['soft-skyhook'] = Law('quarter', 'semi-active',
                               lambda o: Soft(o.c_sky / 2, o.c_p))
    try:
        assert 'soft-skyhook' in law_names(damper_only=True)
        law = make_controller('soft-skyhook', c_sky=3000.0, damper_only=True)
        assert isinstance(law, Soft) and law.c_sky == 1500.0
        corners = make_full_car_law('per-corner-soft-skyhook', PASSENGER_CAR).corner_laws
        assert all(isinstance(c, Soft) for c in corners)
    finally:
        del LAWS['soft-skyhook']
    assert 'soft-skyhook' not in law_names()


def test_wrong_car_and_unknown_names_say_what_to_use():
    with pytest.raises(ValueError, match='full-car law'):
        make_controller('modal-skyhook')
    with pytest.raises(ValueError, match='per-corner-skyhook'):
        make_full_car_law('skyhook', PASSENGER_CAR)
    with pytest.raises(ValueError, match='unknown controller .*skyhook-onoff'):
        make_controller('magic')
    with pytest.raises(ValueError, match='active: it needs a force actuator'):
        make_controller('lqr-active', damper_only=True)
    with pytest.raises(ValueError, match='bad passive current'):
        make_controller('passive@halfA')
    law = make_full_car_law('passive@0.5A', PASSENGER_CAR)
    assert law.name == 'passive@0.5A' and all(isinstance(c, Passive) and c.current_a == 0.5
                                              for c in law.corner_laws)
