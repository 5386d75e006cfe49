"""Node health: levels, combination of findings, flat key-values and back (no ROS)."""
import math

import numpy as np
import pytest

from mr_damper_common import health as h


def test_worst_keeps_the_highest_level_and_joins_its_messages():
    assert h.worst([]).level == h.OK and h.worst([]).message == 'ok'
    out = h.worst([(h.WARN, 'outliers rejected'), (h.OK, 'fine'), (h.ERROR, 'fit process dead'),
                   (h.ERROR, 'no samples')], {'n': 1})
    assert out.level == h.ERROR
    assert out.message == 'fit process dead; no samples'
    assert out.values == {'n': 1}
    assert h.worst([(h.WARN, 'a'), (h.WARN, 'b')]).message == 'a; b'


def test_health_refuses_unknown_level():
    with pytest.raises(ValueError, match='level'):
        h.Health(7, 'x')


@pytest.mark.parametrize('value, text', [
    (3, '3'), (np.int64(3), '3'), (1.5, '1.5'), (np.float64(0.25), '0.25'), (True, 'true'),
    (np.bool_(False), 'false'), (None, 'null'), ('stale', 'stale'), (math.nan, 'nan'),
    (math.inf, 'inf'), (-math.inf, '-inf'), ([0.0, 2.0], '[0.0, 2.0]'),
    ([1.0, math.nan], '[1.0, null]'), ((np.int64(1), 2), '[1, 2]'),
])
def test_value_text(value, text):
    assert h.value_text(value) == text


def test_flatten_unflatten_round_trip():
    values = {'b': {'y': 2, 'x': {'deep': 'text'}}, 'a': 1.25, 'c': [1, 2], 'd': False}
    pairs = h.flatten(values)
    assert [k for k, _ in pairs] == ['a', 'b.x.deep', 'b.y', 'c', 'd']
    assert h.unflatten(pairs) == values


def test_flatten_refuses_dotted_keys_and_unflatten_a_value_with_children():
    with pytest.raises(ValueError, match='dot'):
        h.flatten({'a.b': 1})
    with pytest.raises(ValueError, match='nests'):
        h.unflatten([('a', '1'), ('a.b', '2')])


def test_text_that_is_not_json_stays_text():
    assert h.text_value('no_parameters_yet') == 'no_parameters_yet'
    assert h.text_value('12') == 12


def test_value_text_writes_arrays_and_nested_non_finite_values_as_json():
    import json
    import numpy as np
    from mr_damper_common.health import value_text
    assert json.loads(value_text(np.array([1.0, np.nan]))) == [1.0, None]
    assert json.loads(value_text([[1.0, float('nan')], [np.float64(2.0)]])) == [[1.0, None],
                                                                                [2.0]]
    assert value_text(np.float64('inf')) == 'inf' and value_text(np.int64(3)) == '3'


def test_value_text_of_plain_values_is_their_json():
    """The plain types' direct path writes what JSON writes, also at the float edges."""
    import enum
    import json
    rng = np.random.default_rng(3)
    floats = [0.0, -0.0, 1e-300, 5e-324, 1.7976931348623157e308, 0.1, 1 / 3, 1e16, 123456789.0]
    floats += list(rng.standard_normal(200) * 10.0 ** rng.integers(-20, 20, 200))
    ints = [0, -1, 2 ** 63, -(2 ** 70)] + [int(i) for i in rng.integers(-10 ** 12, 10 ** 12, 100)]

    class Mode(enum.IntEnum):
        SAFE = 2
    for value in floats + ints + [True, False, None, Mode.SAFE]:
        assert h.value_text(value) == json.dumps(value), value
        assert h.text_value(h.value_text(value)) == value


def test_flatten_orders_keys_by_their_text():
    assert [k for k, _ in h.flatten({10: 'a', 2: 'b', 'x': 1})] == ['10', '2', 'x']
    assert [k for k, _ in h.flatten({'b': 1, 'B': 2, 'a': {'z': 0}})] == ['B', 'a.z', 'b']
