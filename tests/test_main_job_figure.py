"""
``launch_scripts/make_main_job_figure.py``: the README figure is the run's three plots joined.

Three PNGs of known sizes and colours are joined without a suite run (``--duration 0``); the
result is as tall as asked, each panel keeps its aspect ratio, and each colour sits
in its panel's column, left to right. A folder without the plots exits 2 and writes nothing.
"""
import numpy as np
import pytest

from script_helpers import load_script

pytestmark = pytest.mark.slow       # matplotlib's import: seconds on the 2 shared cores


def _script():
    return load_script('launch_scripts/make_main_job_figure.py')


def test_joins_the_three_plots_side_by_side(tmp_path):
    import matplotlib.image as mpimg
    script = _script()
    # (height, width) in pixels and a solid colour per panel
    panels = {'hysteresis.png': ((100, 200), (1.0, 0.0, 0.0)),
              'convergence.png': ((50, 50), (0.0, 1.0, 0.0)),
              'ride.png': ((200, 100), (0.0, 0.0, 1.0))}
    for name, ((h, w), rgb) in panels.items():
        mpimg.imsave(tmp_path / name, np.tile(np.array(rgb), (h, w, 1)))
    out = tmp_path / 'main_job.png'
    assert script.main(['--duration', '0', '--run', str(tmp_path), '--out', str(out),
                        '--height', '200']) == 0
    joined = mpimg.imread(out)[..., :3]
    # all scaled to 200 px: widths 400, 200 and 100 px
    assert joined.shape[0] == 200
    assert abs(joined.shape[1] - 700) <= 2
    middle = joined[100]
    for x, rgb in ((200, (1, 0, 0)), (500, (0, 1, 0)), (650, (0, 0, 1))):
        np.testing.assert_allclose(middle[x], rgb, atol=0.05)


def test_a_run_without_plots_exits_2(tmp_path):
    out = tmp_path / 'main_job.png'
    assert _script().main(['--duration', '0', '--run', str(tmp_path), '--out', str(out)]) == 2
    assert not out.exists()
