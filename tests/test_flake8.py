"""
Lint as a test (ament_flake8 convention): flake8 over packages, tests, benches and launchers.

Line length 99 as in ament's configuration; pyflakes errors (unused imports, undefined names)
and pycodestyle errors fail the suite.
"""
import subprocess
import sys

import pytest

from conftest import REPO


@pytest.mark.slow
def test_flake8_clean():
    proc = subprocess.run(
        [sys.executable, '-m', 'flake8', '--max-line-length', '99', '--exclude', '__pycache__',
         'src', 'tests', 'bench', 'launch_scripts'],
        cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f'flake8 found problems:\n{proc.stdout}{proc.stderr}'
