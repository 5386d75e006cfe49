"""``bench/bench_estimator_start.py`` on a few cycles: both filters from the same start agree."""
import json

from script_helpers import load_script


def test_the_schedule_and_the_general_step_give_one_estimate(tmp_path, capsys):
    bench = load_script('bench/bench_estimator_start.py')
    out = tmp_path / 'start.json'
    assert bench.main(['--cycles', '300', '--json', str(out)]) == 0
    fig = json.loads(out.read_text())
    assert fig['cycles'] == 300 and fig['steady_after'] == fig['schedule_steps'] > 300
    ways = fig['ways']
    # the schedule ran every cycle but the first compiled; the general step none
    assert ways['schedule']['compiled_cycles'] == 299
    assert ways['general']['compiled_cycles'] == 0
    assert all(0 < w['p50_us'] <= w['p99_us'] for w in ways.values())
    # the same recursion: round-off apart
    diff = fig['max_relative_difference']
    assert diff['state'] < 1e-6 and diff['std'] < 1e-9, diff
    assert 'general / schedule p50' in capsys.readouterr().out
