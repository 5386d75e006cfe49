"""
Tests of the compiled kernels' disk cache (mr_damper_model.models.compiled).

Each case runs a fresh interpreter that evaluates both stateful models and prints
``compiled.cache_status()``: numba's own counters of signatures loaded from the cache (hits) and
compiled in the process (misses). No timing is asserted.
"""
import json
import os
from pathlib import Path
import subprocess
import sys

import pytest

_RUN = """
import json, sys
import numpy as np
{patch}
from mr_damper_model.models import compiled
from mr_damper_model.models.bouc_wen import BoucWen
from mr_damper_model.models.presets import spencer_thesis_like
from mr_damper_model.models.spencer import Spencer
t = np.arange(200) / 1000.0
x = 0.01 * np.sin(2 * np.pi * 3 * t)
v = 0.01 * 2 * np.pi * 3 * np.cos(2 * np.pi * 3 * t)
bw = BoucWen()
f_bw = bw.force([600.0, 100.0, 300.0, 5.0, 300.0, 150.0, 150.0, 1.5], x, v, t=t)
sp = Spencer()
f_sp = sp.force(sp.from_dict(spencer_thesis_like()), x, v, np.full(t.size, 1.0), t)
print(json.dumps({{'status': compiled.cache_status(),
                  'f': [float(f_bw[-1]), float(f_sp[-1])]}}))
"""

_READ_ONLY_TREE = """
from numba.core import caching
def _read_only(self):
    raise PermissionError('read-only package folder (simulated)')
caching.InTreeCacheLocator.ensure_cache_path = _read_only
"""

_NO_CACHE_FOLDER = """
from numba.core import caching
def _unwritable(self):
    raise PermissionError('no writable folder (simulated)')
caching._CacheLocator.ensure_cache_path = _unwritable
"""

KERNELS = ('mr_damper_model.models.bouc_wen._z_loop', 'mr_damper_model.models.spencer._force_loop')


def _run(patch='', **env):
    code = _RUN.format(patch=patch)
    full_env = dict(os.environ, **env)
    full_env.pop('NUMBA_CACHE_DIR', None)
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=600, env=full_env)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_second_process_loads_the_cache_beside_the_source():
    _run()                       # compiles, or loads what an earlier run stored
    second = _run()
    for name in KERNELS:
        st = second['status'][name]
        assert st['cached'] and st['error'] == ''
        assert st['cache_misses'] == 0 and st['cache_hits'] == 1
        module = name.split('.')[2]
        cache = Path(st['cache_path'])
        # in-tree cache of the (editable) package: the module's own __pycache__
        assert cache.parent.name == 'models'
        assert list(cache.glob(f'{module}.*.nbi')) and list(cache.glob(f'{module}.*.nbc'))


@pytest.mark.slow
@pytest.mark.parametrize('patch', [_READ_ONLY_TREE, _NO_CACHE_FOLDER],
                         ids=['user_cache_fallback', 'no_cache_at_all'])
def test_read_only_package_folder_degrades_gracefully(patch, tmp_path):
    reference = _run()['f']
    first = _run(patch, XDG_CACHE_HOME=str(tmp_path))
    assert first['f'] == reference          # same machine code, same numbers
    for name in KERNELS:
        st = first['status'][name]
        if patch is _READ_ONLY_TREE:
            # numba falls back to the user-wide cache folder
            assert st['cached'] and Path(st['cache_path']).is_relative_to(tmp_path)
            assert st['cache_misses'] == 1
        else:
            assert not st['cached'] and st['cache_path'] is None
            assert 'no locator' in st['error']
    if patch is _READ_ONLY_TREE:
        assert list(tmp_path.rglob('*.nbi'))
        again = _run(patch, XDG_CACHE_HOME=str(tmp_path))
        assert all(again['status'][n]['cache_hits'] == 1 for n in KERNELS)
    else:
        assert not list(tmp_path.rglob('*.nbi'))


def test_a_kernel_with_helpers_of_another_module_recompiles_when_they_change(
        tmp_path, monkeypatch):
    # numba's cache watches the kernel's own file only: the helper's source keys the name
    (tmp_path / 'gym_helper_mod.py').write_text('def twice(x):\n    return 2.0 * x\n')
    (tmp_path / 'gym_kernel_mod.py').write_text(
        'from gym_helper_mod import twice\n\n\ndef loop(a):\n    return twice(a) + 1.0\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    import gym_helper_mod
    import gym_kernel_mod
    from mr_damper_model.models import compiled
    first = compiled._build(gym_kernel_mod.loop, (gym_helper_mod.twice,), False)
    assert first(3.0) == 7.0
    name = first.py_func.__qualname__
    assert name.startswith('loop_src') and len(name) == len('loop_src') + 12
    (tmp_path / 'gym_helper_mod.py').write_text('def twice(x):\n    return x + x\n')
    again = compiled._build(gym_kernel_mod.loop, (gym_helper_mod.twice,), False)
    assert again.py_func.__qualname__ != name
    assert again(3.0) == 7.0
