"""
Lint as a test (ament_pep257 convention): pydocstyle over packages, tests, benches and launchers.

ament_pep257's default ignore list, so D213 applies (a multi-line docstring's summary starts on
the line after the opening quotes), and its file selection: every ``*.py`` file, test modules
included (pydocstyle alone would skip ``test_*.py``), outside directories starting with ``.``
or ``_``.
"""
import subprocess
import sys

import pytest

from conftest import REPO

AMENT_PEP257_IGNORE = 'D100,D101,D102,D103,D104,D105,D106,D107,D203,D212,D404'


@pytest.mark.slow
def test_pep257_clean():
    proc = subprocess.run(
        [sys.executable, '-m', 'pydocstyle', f'--ignore={AMENT_PEP257_IGNORE}',
         r'--match=.*\.py', r'--match-dir=[^\._].*',
         'src', 'tests', 'bench', 'launch_scripts'],
        cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f'pydocstyle found problems:\n{proc.stdout}{proc.stderr}'
