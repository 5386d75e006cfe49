"""
``bench/bench_vehicle.py`` without a suite run: its options, each run's suite arguments, the table.

The unpinned runs' ``--set`` go through the launcher's own parsing (``resolve_config``) and give
the empty CPU list, no pinning; the pinned runs keep the YAML's cores.
"""
import pytest

from mr_damper_bringup.config import node_params, resolve_config
from mr_damper_bringup.launcher import parse_args as suite_parse_args
from script_helpers import load_script


def _bench():
    return load_script('bench/bench_vehicle.py')


def test_options_default_to_pinned_and_collect_every_set():
    bench = _bench()
    args = bench.parse_args([])
    assert args.pinning == 'pinned' and args.set == []
    args = bench.parse_args(['--pinning', 'both', '--set', 'a.b=1', '--set', 'c.d=x'])
    assert args.pinning == 'both' and args.set == ['a.b=1', 'c.d=x']
    assert bench.pinnings('both') == ('pinned', 'unpinned')
    assert bench.pinnings('unpinned') == ('unpinned',)
    with pytest.raises(SystemExit):
        bench.parse_args(['--pinning', 'sometimes'])


def test_suite_arguments_put_the_bench_s_sets_after_the_pinning_s():
    bench = _bench()
    base = ['--config', 'vehicle']
    assert bench.suite_args(base, ['a.b=1'], 'pinned') == base + ['--set', 'a.b=1']
    assert bench.suite_args(base, ['a.b=1'], 'unpinned') == base + [
        '--set', "full_car_node.cpu_affinity=''", '--set', "vehicle_computer.cpu_affinity=''",
        '--set', 'a.b=1']
    assert bench.suite_args(base, ['a.b=1']) == base + ['--set', 'a.b=1']   # external run


@pytest.mark.parametrize('pinning, car, computer',
                         [('pinned', '0', '1'), ('unpinned', '', '')])
def test_the_launcher_reads_unpinned_as_empty_cpu_lists(tmp_path, pinning, car, computer):
    bench = _bench()
    argv = bench.suite_args(['--config', 'vehicle', '--out', str(tmp_path)], (), pinning)
    cfg = resolve_config(suite_parse_args(argv), tmp_path)
    assert node_params(cfg, 'full_car_node')['cpu_affinity'] == car
    assert node_params(cfg, 'vehicle_computer')['cpu_affinity'] == computer


def test_compare_prints_the_runs_side_by_side(capsys):
    bench = _bench()

    def run(answered, p99):
        return {'exit': 0, 'load_start': 1.0, 'load_end': 1.5,
                'summary': {'vehicle': {'answered_fraction': answered, 'frames_lost': {'total': 0},
                                        'sensor_to_command_s': {'p50': 0.001, 'p99': p99,
                                                                'max': 0.005}}},
                'cpu': {'full_car_node': {'cpu_mean_percent': 70.0}}}
    bench.compare({'pinned': run(0.951, 0.0026), 'unpinned': run(0.94, 0.003)})
    lines = capsys.readouterr().out.splitlines()
    assert lines[:2] == ['| figure | pinned | unpinned | goal |', '|---|---|---|---|']
    assert '| answered within the cycle | 95.1 % | 94 % | >= 99.9 % |' in lines
    assert ('| sensor frame -> command frame p50 / p99 / max | 1 / 2.6 / 5 ms | 1 / 3 / 5 ms '
            '| p99 <= 2 ms |') in lines
    assert '| frames lost on the bus | 0 | 0 | counted |' in lines
    assert '| CPU mean full_car_node, one core = 100 % | 70.0 % | 70.0 % |  |' in lines


def test_both_runs_each_layout_pinned_then_unpinned_and_every_run_gets_the_sets(monkeypatch):
    bench = _bench()
    calls = []

    def fake_run(name, args, out, duration):
        calls.append((name, args))
        return {'exit': 0, 'wall_s': 1.0, 'load_start': 0.0, 'load_end': 0.0, 'summary': {},
                'cpu': {}}
    monkeypatch.setattr(bench, '_run', fake_run)
    assert bench.main(['--pinning', 'both', '--set', 'x.y=1']) == 0
    assert [name for name, _ in calls] == ['vehicle_loop_pinned', 'vehicle_loop_unpinned',
                                           'vehicle_nodes_pinned', 'vehicle_nodes_unpinned',
                                           'external']
    assert all(args[-2:] == ['--set', 'x.y=1'] for _, args in calls)
    assert [sum(a.endswith("cpu_affinity=''") for a in args) for _, args in calls] == \
        [0, 2, 0, 2, 0]


def test_cyclictest_output_gives_each_cpus_late_wakeups():
    # two threads' histograms (latency [us], count per thread) and the summary lines
    text = '\n'.join([
        '# /dev/cpu_dma_latency set to 0us', '# Histogram',
        '000010 000900 000950', '000600 000050 000040', '001500 000030 000009',
        '002500 000020 000001', '# Total: 000001000 001000',
        '# Min Latencies: 00007 00010', '# Avg Latencies: 00031 00029',
        '# Max Latencies: 03373 02600', '# Histogram Overflows: 00002 00000',
        '# Histogram Overflow at cycle number:', '# Thread 0: 00123 00456', '# Thread 1:'])
    cpus = _bench().parse_cyclictest(text)['cpus']
    assert len(cpus) == 2
    a, b = cpus
    assert (a['min_us'], a['avg_us'], a['max_us'], a['overflows']) == (7, 31, 3373, 2)
    # overflows (beyond the histogram) are late beyond every threshold
    assert a['wakeups'] == 900 + 50 + 30 + 20 + 2
    assert a['late'] == {'500': 50 + 30 + 20 + 2, '1000': 30 + 20 + 2, '2000': 20 + 2}
    assert b['wakeups'] == 1000 and b['late'] == {'500': 50, '1000': 10, '2000': 1}
    # the most a loop could answer: the share of wake-ups not later than its slack
    bench = _bench()
    assert bench.answer_ceiling(b) == {'0': 1.0 - 1 / 1000, '1000': 1.0 - 10 / 1000}
    assert bench.answer_ceiling(a) == {'0': 1.0 - 22 / 1002, '1000': 1.0 - 52 / 1002}


def test_without_cyclictest_the_platform_is_not_measured(monkeypatch, capsys):
    import shutil
    bench = _bench()
    monkeypatch.setattr(shutil, 'which', lambda name: None)
    assert bench.platform_latency(1.0) is None
    bench.report_platform(None)
    assert 'rt-tests' in capsys.readouterr().out


def test_device_interrupts_are_read_per_cpu_from_proc_interrupts():
    text = '\n'.join([
        '           CPU0       CPU1       ',
        ' 36:          0     246296 PCI-MSIX-0000:00:02.0   1-edge      virtio1-req.0',
        ' 39:      22239          3 PCI-MSIX-0000:00:03.0   2-edge      virtio2-output.0',
        'LOC:    5638852    5532684   Local timer interrupts',
        'ERR:          0'])
    irq = _bench().device_interrupts(text)
    assert irq == {'PCI-MSIX-0000:00:02.0 1-edge virtio1-req.0': [0, 246296],
                   'PCI-MSIX-0000:00:03.0 2-edge virtio2-output.0': [22239, 3]}
    assert _bench().device_interrupts('') == {}


def test_a_vehicle_runs_report_has_the_loops_stages_or_none(capsys):
    bench = _bench()
    ex = {'estimate': {'n': 9, 'p50_s': 2e-4, 'p99_s': 4e-4, 'max_s': 5e-4},
          'control': {'n': 9, 'p50_s': 2.5e-4, 'p99_s': 3e-4, 'max_s': 5e-4},
          'send': {'n': 9, 'p50_s': 1.5e-4, 'p99_s': 2e-4, 'max_s': 5e-4}}
    deadline = {'entries': {'deadline_misses': 4, 'sensor_timeout': 1},
                'failsafe_s': {'deadline_misses': 0.1, 'sensor_timeout': 2.5}}
    run = {'exit': 0, 'wall_s': 1.0, 'load_start': 0.0, 'load_end': 0.0, 'cpu': {},
           'summary': {'vehicle': {'sensor_to_command_s': {'p50': 9e-4}, 'execution_s': ex,
                                   'reception_s': {'n': 9, 'p50_s': 2e-4, 'p99_s': 1.5e-3},
                                   'cycles_queued': 3, 'deadline': deadline,
                                   'reader_cpu_per_cycle_s': {'mean': 1.1e-3, 'p50': 1e-3,
                                                              'p99': 1.8e-3},
                                   'loop_misses': {'bunched': 1, 'queued': 2,
                                                   'reached_late': 4, 'slow': 0}}}}
    bench.report_vehicle(run)
    out = capsys.readouterr().out
    assert 'watchdog trips 4, 0.10 s on the safe current, 25 ms a trip' in out
    assert 'bus reader thread CPU per cycle mean / p50 / p99 1.1 / 1 / 1.8 ms (the mean 55 % ' \
        'of a core at 2 ms)' in out
    assert 'estimate 0.2 / 0.4 ms, control 0.25 / 0.3 ms, send 0.15 / 0.2 ms' in out
    assert 'add up to 0.6 ms of the response\'s p50 0.9 ms' in out
    assert 'reception (bus time to the loop\'s start) p50 / p99 0.2 / 1.5 ms; cycles queued ' \
        'behind the one before 3' in out
    assert 'after their deadline, by cause: bunched 1, queued 2, reached_late 4, slow 0 ' \
        '(of 7)' in out
    rows = {f: v for f, v, _ in bench._vehicle_figures(run)}
    assert rows['loop execution p50 / p99 [ms]: estimate, control, send'] == \
        '0.2 / 0.4, 0.25 / 0.3, 0.15 / 0.2'
    del run['summary']['vehicle']['execution_s']     # the nodes layout: no loop
    del run['summary']['vehicle']['reader_cpu_per_cycle_s']   # a summary before it
    deadline['entries']['deadline_misses'] = 0
    bench.report_vehicle(run)
    out = capsys.readouterr().out
    assert 'loop execution' not in out and 'reception' not in out
    assert 'CPU per cycle mean / p50 / p99 n/a / n/a / n/a (the mean n/a of a core' in out
    assert 'watchdog trips 0, 0.10 s on the safe current\n' in out
    assert 'n/a' in bench._vehicle_figures(run)[5][1]


def test_the_report_splits_the_cycles_by_the_hypervisors_steal(capsys):
    bench = _bench()
    bench.report_steal({'share': {0: 0.0123, 1: 0.004},
                        'split': {'quiet': {'intervals': 50, 'cycles': 25000, 'misses': 5,
                                            'on_time': 0.9998},
                                  'stolen': {'intervals': 6, 'cycles': 3000, 'misses': 90,
                                             'on_time': 0.97},
                                  'unsampled': 0}})
    text = capsys.readouterr().out
    assert 'cpu0 1.23 %, cpu1 0.40 %' in text
    assert 'without steal: 50, cycles 25000, misses 5, on time 99.98 %' in text
    assert 'with steal: 6, cycles 3000, misses 90, on time 97 %' in text
    bench.report_steal({'share': {0: 0.0}, 'error': 'FileNotFoundError: no mcap'})
    assert 'deadline counts not read: FileNotFoundError' in capsys.readouterr().out
    bench.report_steal(None)
    assert capsys.readouterr().out == ''
