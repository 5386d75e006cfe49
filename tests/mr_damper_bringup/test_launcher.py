"""Tests of mr_damper_bringup.launcher: the drain condition and the progress line (no graph)."""
import pytest

from mr_damper_bringup.launcher import (clear_run_outputs, identifier_drained, parse_args,
                                        progress_line, RUN_OUTPUTS, statuses_recorded)


def _monitor():
    """Return the launcher's real Monitor, fed decoded statuses with ``add(node, status)``."""
    from mr_damper_bringup.monitor_node import Monitor
    mon = Monitor()
    mon.add = lambda node, d: mon.store({node: d})
    return mon


def test_identifier_drained_waits_for_a_settled_recorder_count():
    mon = _monitor()
    assert identifier_drained(mon) == (False, (None, None))
    mon.add('identifier', {'samples_received': 900})
    mon.add('recorder', {'measurements': 900})
    assert identifier_drained(mon)[0] is False           # one recorder status: not settled
    mon.add('recorder', {'measurements': 1000})
    assert identifier_drained(mon) == (False, (900, 1000))
    mon.add('recorder', {'measurements': 1000})          # settled at 1000
    assert identifier_drained(mon)[0] is False           # identifier still behind
    mon.add('identifier', {'samples_received': 1000})
    assert identifier_drained(mon) == (True, (1000, 1000))


def test_after_a_restart_the_drain_waits_for_both_counts_to_settle():
    """A restarted identifier counts from 0: its count cannot reach the recorder's."""
    mon = _monitor()
    mon.add('identifier', {'samples_received': 300})
    mon.add('recorder', {'measurements': 1000})
    mon.add('recorder', {'measurements': 1000})
    assert identifier_drained(mon, exact=False)[0] is False      # one identifier status
    mon.add('identifier', {'samples_received': 400})
    assert identifier_drained(mon, exact=False)[0] is False      # still moving
    mon.add('identifier', {'samples_received': 400})
    assert identifier_drained(mon, exact=False) == (True, (400, 1000))
    assert identifier_drained(mon)[0] is False                  # the exact rule never would


def test_the_stop_waits_for_a_recorded_status_of_every_running_node_heard():
    """A late node the monitor heard but the recorder has not: not done until it has."""
    import types
    mon = _monitor()
    running = ['recorder', 'fl.quarter_car_node', 'fl.mr_damper_rig', 'fr.mr_damper_rig']

    def hear(*names):
        mon.on_status('diagnostics', types.SimpleNamespace(status=[
            types.SimpleNamespace(name=n, level=0, message='ok', values=[]) for n in names]))

    assert statuses_recorded(mon, running) == (True, ())          # nothing heard yet
    hear('fl/mr_damper_rig', 'fl/quarter_car_node')
    mon.add('recorder', {'statuses': {'fl/mr_damper_rig': 3}})
    assert statuses_recorded(mon, running) == (False, (('fl/mr_damper_rig', 3),))
    # a node no longer running is not waited for (a dead node's status may never be recorded)
    assert statuses_recorded(mon, ['fl.mr_damper_rig'])[0] is True
    mon.add('recorder', {'statuses': {'fl/mr_damper_rig': 4, 'fl/quarter_car_node': 1}})
    assert statuses_recorded(mon, running)[0] is True
    hear('fr/mr_damper_rig')                                       # fr's rig heard: wait again
    assert statuses_recorded(mon, running)[0] is False


def test_progress_line_from_the_statuses():
    mon = _monitor()
    assert 'no status yet' in progress_line(mon, 1.0)
    mon.add('recorder', {'measurements': 5000})
    mon.add('quarter_car', {'mode': 'failsafe', 'reason': 'stale', 't_sim': 4.0,
                            'failsafe_s': 1.5, 'current_a': 0.5})
    mon.parameters, mon.n_parameters, mon.n_valid = {'nrmse_percent': 1.25}, 3, 2
    mon.metrics = {'rms_body_accel_wk': 0.9}
    line = progress_line(mon, 10.0)
    assert 'recorded 5000 samples' in line and '3 updates (2 valid), nrmse 1.2 %' in line
    assert 'failsafe (stale)' in line and 'Wk 0.900' in line
    assert 'controller' not in line
    # an external controller: its mode (has it a model?) next to the car's (do commands come?)
    mon.add('controller', {'mode': 'failsafe', 'reason': 'no_parameters_yet'})
    assert progress_line(mon, 11.0).endswith(
        '| controller failsafe (no_parameters_yet), 0 commands on a model')
    mon.add('controller', {'mode': 'normal', 'reason': 'ok', 'commands_normal': 0})
    # a model and no car state yet: nothing commanded on it
    assert progress_line(mon, 12.0).endswith('| controller normal, 0 commands on a model')
    mon.add('controller', {'mode': 'normal', 'reason': 'ok', 'commands_normal': 250})
    assert progress_line(mon, 13.0).endswith('| controller normal, 250 commands on a model')


@pytest.mark.parametrize('bad', [['--duration', '-1'], ['--domain-id', '233'],
                                 ['--rate-factor', '0'], ['--config', 'nope'],
                                 ['--max-restarts', '-1'], ['--restart-window-s', '-5'],
                                 ['--restart-backoff-s', '4', '--restart-backoff-max-s', '2']])
def test_command_line_refusals_exit_2(bad, capsys):
    with pytest.raises(SystemExit) as exc:
        parse_args(bad)
    assert exc.value.code == 2 and 'mr-damper-suite' in capsys.readouterr().err


def test_command_line_defaults():
    args = parse_args([])
    assert args.duration == 30.0 and args.config == 'sim' and args.rate_factor is None


def test_restart_options_make_the_policy():
    args = parse_args(['--max-restarts', '5', '--restart-window-s', '30',
                       '--restart-backoff-s', '0.25', '--restart-backoff-max-s', '2'])
    p = args.restart_policy
    got = (p.max_restarts, p.restart_window_s, p.backoff_s, p.backoff_max_s)
    assert got == (5, 30.0, 0.25, 2.0)
    from mr_damper_bringup.supervisor import RestartPolicy
    assert parse_args([]).restart_policy == RestartPolicy()


def test_hang_timeouts_cover_each_nodes_own_status_period():
    from mr_damper_bringup.launcher import hang_timeouts
    cfg = {'/**': {'ros__parameters': {}},
           'quarter_car_node': {'ros__parameters': {'diagnostics_period_s': 10.0}}}
    corners = {'fl': {'/fl/mr_damper_rig': {'ros__parameters': {'diagnostics_period_s': 20.0}}}}
    got = hang_timeouts(['quarter_car_node', 'mr_damper_record', 'fl.mr_damper_rig'], 15.0,
                        cfg, corners)
    assert got == {'quarter_car_node': 30.0, 'mr_damper_record': 15.0, 'fl.mr_damper_rig': 60.0}
    assert set(hang_timeouts(['quarter_car_node'], 0.0, cfg).values()) == {0.0}


def test_a_new_run_leaves_no_output_of_an_earlier_run_in_its_folder(tmp_path):
    # a run that stops before it writes a summary (a node that cannot start) must not leave
    # the earlier run's summary or body log to be read as its own (a bench once did)
    stale = [*RUN_OUTPUTS, 'suite.mcap', 'suite.1.mcap', 'suite.2.recording']
    for name in stale + ['notes.txt']:
        (tmp_path / name).write_text('earlier run')
    clear_run_outputs(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['notes.txt']
    assert {'summary.json', 'full_car_body.npz', 'process_stats.json'} <= set(RUN_OUTPUTS)
    clear_run_outputs(tmp_path)                     # nothing to remove: no error
