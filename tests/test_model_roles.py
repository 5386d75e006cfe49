"""
Inside ``mr_damper_model`` imports point one way: models <- io <- identification <- live <- tools.

A module of a role (the sub-package it sits in) may import only from its own role or from the
roles to its left (issue 33): the force laws know nothing of files, the readers nothing of
fitting, the fitting nothing of the live identifier, and nothing below the entry points (the
identifier node, the command-line tools) imports them; ``nodes`` and ``tools`` are two entry
roles and import neither the other. Every import counts: module level and inside functions,
absolute and relative (``ast``).
"""
import ast

import pytest

from conftest import REPO

PACKAGE = 'mr_damper_model'
#: rank of each role: a module may import roles of its own rank or lower, and its own role
RANKS = {'models': 0, 'io': 1, 'identification': 2, 'live': 3, 'nodes': 4, 'tools': 4}
SOURCE = REPO / 'src' / PACKAGE / PACKAGE


def module_name(path, root):
    """Return the dotted name of a source file under ``root`` (the package's parent folder)."""
    parts = list(path.relative_to(root).with_suffix('').parts)
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def imported_names(tree, module, is_package):
    """Yield ``(line, dotted name)`` of every import in ``tree`` (relative ones resolved)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split('.')
                base = base[:len(base) - node.level + (1 if is_package else 0)]
                target = '.'.join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            for alias in node.names:        # `from pkg import io`: the role is the name
                yield node.lineno, f'{target}.{alias.name}'


def role_of(name, package=PACKAGE):
    """Return the role (first sub-package) of a dotted name inside ``package``, else None."""
    parts = name.split('.')
    return parts[1] if parts[0] == package and len(parts) > 1 else None


def violations(source=SOURCE, package=PACKAGE, ranks=RANKS):
    """Return ``['file:line role -> role (name)']`` of every import against the order."""
    found = []
    for path in sorted(source.rglob('*.py')):
        module = module_name(path, source.parent)
        own = role_of(module, package)
        if own not in ranks:
            continue
        tree = ast.parse(path.read_text(), filename=str(path))
        for line, name in imported_names(tree, module, path.name == '__init__.py'):
            other = role_of(name, package)
            if other is None or other == own:
                continue
            if other not in ranks or ranks[other] >= ranks[own]:
                found.append(f'{path.relative_to(source)}:{line} {own} -> {other} ({name})')
    return found


def test_every_module_has_a_role():
    roots = {p.relative_to(SOURCE).parts[0] for p in SOURCE.rglob('*.py')}
    assert roots - {'__init__.py'} == set(RANKS)


def test_roles_import_only_to_their_left():
    found = violations()
    assert not found, 'imports against models <- io <- identification <- live <- nodes/tools:\n' \
        + '\n'.join(found)


@pytest.mark.parametrize('code, bad', [
    ('from demo.tools.cli import read_record\n', True),              # models -> tools
    ('def f():\n    from demo.io import params_file\n', True),       # inside a function
    ('from ..live import running_median\n', True),                   # relative
    ('from demo import identification\n', True),                     # the role as a name
    ('import demo.nodes.node\n', True),
    ('from demo.models.base import get_model\nfrom . import base\n', False),
])
def test_the_check_sees_an_import_against_the_order(tmp_path, code, bad):
    pkg = tmp_path / 'demo'
    for role in ('models', 'io', 'identification', 'live', 'nodes', 'tools'):
        (pkg / role).mkdir(parents=True)
        (pkg / role / '__init__.py').write_text('')
    (pkg / '__init__.py').write_text('')
    (pkg / 'models' / 'plant.py').write_text(code)
    (pkg / 'tools' / 'cli.py').write_text('from demo.models import plant\nfrom ..io import x\n')
    found = violations(pkg, 'demo')
    assert bool(found) == bad, found
    assert all(f.startswith('models') for f in found)     # downward imports pass
