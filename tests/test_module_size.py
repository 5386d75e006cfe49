"""
Every source module stays under about 600 lines, or its docstring says why it is longer.

The project's size rule (issue 33): a module longer than :data:`LIMIT_LINES` lines carries the
reason in its module docstring, in a sentence that names "600 lines".
"""
import ast

from conftest import REPO

LIMIT_LINES = 600


def oversized_without_reason(paths):
    """Return ``(path, lines)`` of the modules over the limit whose docstring gives no reason."""
    out = []
    for path in paths:
        text = path.read_text()
        lines = text.count('\n')
        if lines <= LIMIT_LINES:
            continue
        doc = ast.get_docstring(ast.parse(text)) or ''
        if '600 lines' not in ' '.join(doc.split()):
            out.append((str(path.relative_to(REPO) if path.is_relative_to(REPO) else path),
                        lines))
    return out


def _source_modules():
    for path in sorted((REPO / 'src').rglob('*.py')):
        if not {'build', 'install', '.venv', '__pycache__'} & set(path.parts):
            yield path


def test_every_source_module_is_short_or_says_why():
    modules = list(_source_modules())
    assert len(modules) > 100
    assert oversized_without_reason(modules) == []


def test_the_check_flags_a_long_module_without_a_reason(tmp_path):
    body = 'x = 1\n' * (LIMIT_LINES + 1)
    silent = tmp_path / 'silent.py'
    silent.write_text('"""A long module."""\n' + body)
    explained = tmp_path / 'explained.py'
    explained.write_text('"""\nA long module.\n\nOver the project\'s ~600\nlines: one '
                         'derivation.\n"""\n' + body)
    short = tmp_path / 'short.py'
    short.write_text('"""A short module."""\n' + 'x = 1\n' * 10)
    assert oversized_without_reason([silent, explained, short]) == [(str(silent),
                                                                     LIMIT_LINES + 2)]
