"""``bench/bench_diagnostics_status.py`` on a few statuses: the three ways write one status."""
import json

from script_helpers import load_script


def test_the_three_ways_write_the_same_vehicle_status(tmp_path, capsys):
    bench = load_script('bench/bench_diagnostics_status.py')
    out = tmp_path / 'status.json'
    assert bench.main(['--cycles', '200', '--repeats', '5', '--json', str(out)]) == 0
    fig = json.loads(out.read_text())
    # the vehicle computer's status: the bridge's four corners, the filter, the controller
    assert fig['key_values'] > 200 and fig['repeats'] == 5
    assert set(fig['ways']) == {'status dict', *bench.WAYS}
    assert all(0 < w['p50_ms'] <= w['p99_ms'] for w in fig['ways'].values())
    text = capsys.readouterr().out
    assert '"json, new" / "direct, reused" p50' in text


def test_json_text_is_the_json_of_a_value():
    bench = load_script('bench/bench_diagnostics_status.py')
    assert bench.json_text(True) == 'true' and bench.json_text(None) == 'null'
    assert bench.json_text(float('inf')) == 'inf' and bench.json_text([1.0, float('nan')]) == \
        '[1.0, null]'
