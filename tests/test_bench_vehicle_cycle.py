"""``bench/bench_vehicle_cycle.py`` on a few cycles: every cycle of every way counted per stage."""
import json

from script_helpers import load_script


def test_each_way_counts_every_cycle_in_every_stage(tmp_path, capsys):
    bench = load_script('bench/bench_vehicle_cycle.py')
    out = tmp_path / 'cycle.json'
    assert bench.main(['--cycles', '40', '--warmup', '60', '--json', str(out)]) == 0
    fig = json.loads(out.read_text())
    assert list(fig['ways']) == ['back-to-back', 'spin', 'sleep']
    for way, stages in fig['ways'].items():
        # every cycle estimated, answered by the law and its frame encoded, none skipped
        assert {s: h['n'] for s, h in stages.items()} == \
            {'estimate': 40, 'control': 40, 'send': 40}, way
        assert all(0 < h['p50_s'] <= h['max_s'] for h in stages.values()), way
    printed = capsys.readouterr().out
    assert 'p50 / back-to-back' in printed and 'sleep' in printed


def test_the_cycles_are_the_cars_bus_sensors():
    import numpy as np
    bench = load_script('bench/bench_vehicle_cycle.py')
    acc, travel = bench.sensor_cycles(500)
    assert acc.shape == travel.shape == (500, 4)
    assert np.all(np.isfinite(acc)) and np.all(np.isfinite(travel))
    # gravity removed (a mean far from 9.81 m/s^2), travels of a car on a rough road
    assert np.all(np.abs(acc.mean(0)) < 2.0) and np.all(travel.std(0) > 1e-4)
