"""``bench/bench_vehicle_startup.py`` without a suite run: its reading of summaries, its table."""
import pytest

from script_helpers import load_script


def _bench():
    return load_script('bench/bench_vehicle_startup.py')


def summary_run(exit_code=0, ups=1, first_up_s=4.0, failed=0, deaths=0, restarts=0,
                cycles=2000, timeouts=0):
    """Build a ``_run`` result with the summary keys the bench reads (None: the key is absent)."""
    chain = None if ups is None else {'transitions': 2, 'failed': failed, 'deaths': deaths,
                                      'ups': ups, 'first_up_s': first_up_s}
    return {'exit': exit_code,
            'summary': {'restarts': [{'node': 'x'}] * restarts,
                        'vehicle': {'chain': chain, 'control_cycles': cycles,
                                    'driver_command_timeouts': timeouts}}}


def test_a_start_up_is_up_when_the_chain_came_up_and_absent_figures_count_as_none():
    bench = _bench()
    one = bench.startup(summary_run(ups=2, first_up_s=3.5, deaths=1, restarts=1))
    assert one == {'exit': 0, 'up': True, 'first_up_s': 3.5, 'ups': 2, 'failed': 0,
                   'deaths': 1, 'restarts': 1, 'cycles': 2000, 'driver_timeouts': 0}
    never = bench.startup(summary_run(exit_code=1, ups=0, first_up_s=None, failed=7, cycles=0))
    assert not never['up'] and never['first_up_s'] is None and never['failed'] == 7
    empty = bench.startup({'exit': -9, 'summary': {}})      # no summary written at all
    assert not empty['up'] and empty['cycles'] == 0 and empty['restarts'] == 0


def test_a_layout_s_figures_count_start_ups_and_take_the_median_of_those_up():
    bench = _bench()
    runs = [bench.startup(summary_run(first_up_s=t)) for t in (4.0, 6.0, 5.0)]
    runs.append(bench.startup(summary_run(ups=0, first_up_s=None, failed=3)))
    runs.append(bench.startup(summary_run(first_up_s=9.0, cycles=0, exit_code=1)))
    f = bench.layout_figures(runs)
    assert (f['runs'], f['exit_0'], f['up'], f['commanded']) == (5, 4, 4, 3)
    assert f['first_up_p50_s'] == 5.5 and f['first_up_max_s'] == 9.0
    assert (f['ups'], f['failed']) == (4, 3)
    assert bench.layout_figures([runs[3]])['first_up_p50_s'] is None


def test_the_table_puts_the_layouts_side_by_side(capsys):
    bench = _bench()
    figures = {'loop': bench.layout_figures([bench.startup(summary_run(first_up_s=4.25))]),
               'nodes': bench.layout_figures([bench.startup(summary_run(ups=0,
                                                                        first_up_s=None))])}
    bench.report(figures)
    lines = capsys.readouterr().out.splitlines()
    assert lines[:2] == ['| start-ups | `loop` | `nodes` |', '|---|---|---|']
    assert '| chain up (every node active) | 1 of 1 | 0 of 1 |' in lines
    assert '| manager start -> chain up, p50 / max | 4.25 s / 4.25 s | - / - |' in lines


def test_layouts_alternate_and_every_run_gets_the_sets(monkeypatch, tmp_path, capsys):
    bench = _bench()
    calls = []

    def fake_run(name, args, out, duration):
        calls.append((name, args, duration))
        return summary_run(first_up_s=float(len(calls)))
    monkeypatch.setattr(bench, '_run', fake_run)
    out = tmp_path / 'figures.json'
    assert bench.main(['--runs', '2', '--duration', '7', '--set', 'x.y=1',
                       '--json', str(out)]) == 0
    assert [c[0] for c in calls] == ['loop_1', 'nodes_1', 'loop_2', 'nodes_2']
    assert all(c[1][-2:] == ['--set', 'x.y=1'] and c[2] == 7.0 for c in calls)
    assert [c[1][c[1].index('--vehicle-layout') + 1] for c in calls] == \
        ['loop', 'nodes', 'loop', 'nodes']
    assert '| chain up (every node active) | 2 of 2 | 2 of 2 |' in capsys.readouterr().out
    assert out.is_file()


@pytest.mark.parametrize('argv', [['--layouts', 'loop,bus'], ['--layouts', ''],
                                  ['--runs', '0'], ['--duration', '0']])
def test_bad_options_are_refused(argv):
    with pytest.raises(SystemExit):
        _bench().parse_args(argv)
