"""
The node parameter tables in docs/nodes.md match the parameters the nodes declare.

Each node module declares its parameters once, in ``PARAMETERS`` (a tuple of
``mr_damper_common.node_utils.Param``). docs/nodes.md holds, after the line
``<!-- parameters: <module> -->``, the table this file prints for that module. Print a table
to paste with::

    .venv/bin/python -P tests/test_docs_parameters.py mr_damper_model.nodes.identifier_node
"""
import importlib
import math
from pathlib import Path
import re
import sys

import pytest

DOCS = Path(__file__).resolve().parents[1] / 'docs' / 'nodes.md'
NODE_MODULES = (
    'mr_damper_rig.rig_node',
    'mr_damper_model.nodes.identifier_node',
    'quarter_car_sim.nodes.quarter_car_node',
    'semi_active_control.nodes.semi_active_controller_node',
    'mr_damper_can.can_bridge_node',
    'mr_damper_can.can_driver_sim_node',
    'semi_active_control.nodes.state_estimator_node',
    'quarter_car_sim.nodes.full_car_node',
    'mr_damper_can.vehicle_bridge_node',
    'mr_damper_can.vehicle_computer_node',
    'semi_active_control.nodes.vehicle_estimator_node',
    'semi_active_control.nodes.vehicle_controller_node',
    'semi_active_control.nodes.lifecycle_manager_node',
)
HEADER = ('| parameter | default | range | while running | meaning |', '|---|---|---|---|---|')


def _number(value):
    if isinstance(value, float) and math.isinf(value):
        return 'inf' if value > 0 else '-inf'
    return f'{value:g}'


def format_default(value):
    """Write a default as the docs show it (YAML-like: true, 'text', [1.0, 2.0], 0.5)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(format_default(v) for v in value) + ']'
    return repr(value)


def format_range(spec):
    """Write a range as ``low .. high`` (``-inf``/``inf`` for an open side; ``-`` for none)."""
    if spec.low is None and spec.high is None:
        return '-'
    low = -math.inf if spec.low is None else spec.low
    high = math.inf if spec.high is None else spec.high
    return f'{_number(low)} .. {_number(high)}'


def table_rows(specs):
    """Return the table lines (header included) of ``specs``."""
    rows = list(HEADER)
    for spec in specs:
        rows.append(f'| `{spec.name}` | `{format_default(spec.default)}` | {format_range(spec)} '
                    f'| {"yes" if spec.dynamic else "no"} | {spec.description} |')
    return rows


def docs_table(module, text=None):
    """Return the table lines under the marker of ``module`` in docs/nodes.md (None if absent)."""
    text = DOCS.read_text() if text is None else text
    lines = text.splitlines()
    marker = f'<!-- parameters: {module} -->'
    try:
        start = lines.index(marker) + 1
    except ValueError:
        return None
    rows = []
    for line in lines[start:]:
        if not line.startswith('|'):
            break
        rows.append(line.rstrip())
    return rows


@pytest.mark.parametrize('module', NODE_MODULES)
def test_docs_table_matches_declared_parameters(module):
    specs = importlib.import_module(module).PARAMETERS
    names = [s.name for s in specs]
    assert len(names) == len(set(names)), f'{module}: a parameter is declared twice'
    for spec in specs:
        assert spec.description.strip(), f'{module}.{spec.name}: no description'
        assert '|' not in spec.description, f'{module}.{spec.name}: "|" breaks the table'
    rows = docs_table(module)
    assert rows is not None, f'docs/nodes.md has no "<!-- parameters: {module} -->" table'
    expected = table_rows(specs)
    documented = {re.match(r'\| `([^`]+)`', r).group(1) for r in rows[2:]}
    assert documented == set(names), (
        f'{module}: in docs only {sorted(documented - set(names))}, '
        f'declared only {sorted(set(names) - documented)}')
    assert rows == expected, '\n'.join(
        f'docs: {a}\ncode: {b}' for a, b in zip(rows, expected) if a != b)


def test_table_format_of_a_known_spec():
    from mr_damper_common.node_utils import Param
    rows = table_rows([Param('gain', 2.0, 'Gain [N s/m]', 0.0, None, dynamic=True),
                       Param('mode', 'sim', 'Source'), Param('on', False, 'Switch')])
    assert rows[2:] == ['| `gain` | `2.0` | 0 .. inf | yes | Gain [N s/m] |',
                        "| `mode` | `'sim'` | - | no | Source |",
                        '| `on` | `false` | - | no | Switch |']
    text = 'x\n<!-- parameters: m -->\n' + '\n'.join(rows) + '\n\nafter'
    assert docs_table('m', text) == rows and docs_table('other', text) is None


if __name__ == '__main__':
    for name in sys.argv[1:] or NODE_MODULES:
        print(f'<!-- parameters: {name} -->')
        print('\n'.join(table_rows(importlib.import_module(name).PARAMETERS)))
        print()
