"""
Tests of mr_damper_bringup.report.corners: losses and restart costs of a run with car corners.

A synthetic two-corner recording (the recorder node's CDR bytes, two parts: the recorder was
restarted) with known truths: corner ``fl``'s identifier was killed and restarted, so it lost
the samples between its last count and its new life's start, and the car's ``fl`` corner went
to fail-safe meanwhile; corner ``fr`` lost nothing.
"""
import numpy as np
import pytest

from mr_damper_bringup.recorder import SuiteRecorder
from mr_damper_bringup.report.corners import add_corner_losses
from mr_damper_bringup.topics import namespaced_table, topic_table

T0 = 1000.0                 # epoch of the run's start [s]
RATE = 1000.0               # samples per second per corner
BATCH = 100                 # samples per measurement message
END_S = 30.0
KILL_S, BACK_S = 10.0, 12.0         # fl's identifier: killed, first count of its new life
FS = (10.5, 13.0)                   # fl corner of the car in fail-safe
REC_DOWN = (15.0, 17.0)             # the recorder was down (restarted into suite.1.mcap)


def _write(path, t_from, t_to):
    """Write the part of the run between ``t_from`` and ``t_to`` [s] (recorder's times)."""
    from rclpy.serialization import serialize_message

    from mr_damper_common import messages as mm
    from mr_damper_interfaces.msg import QuarterCarState
    from std_msgs.msg import UInt64
    table = namespaced_table(topic_table(), ['fl', 'fr'])
    with SuiteRecorder(path, table, start_ns=int(T0 * 1e9)) as rec:
        events = []
        for c in ('fl', 'fr'):
            for k in range(int(END_S * RATE / BATCH)):
                t = k * BATCH / RATE
                if not t_from <= t < t_to:
                    continue
                ts = t + np.arange(BATCH) / RATE
                msg = mm.samples_to_msg(ts, *([0.0] * BATCH for _ in range(4)), sequence=k,
                                        first_index=k * BATCH)
                events.append((t + BATCH / RATE, f'{c}/measurement', serialize_message(msg)))
            for k in range(int(END_S * 10)):           # the identifier's count, every 0.1 s
                t = 0.1 * k
                if not t_from <= t < t_to or (c == 'fl' and KILL_S <= t < BACK_S):
                    continue
                n = int(round(t * RATE)) if c == 'fr' or t < KILL_S else \
                    int(round((t - BACK_S) * RATE))
                events.append((t, f'{c}/samples_received', serialize_message(UInt64(data=n))))
            for k in range(int(END_S * 20)):           # the car's corner state, 20 Hz
                t = 0.05 * k
                if not t_from <= t < t_to:
                    continue
                state = QuarterCarState()
                state.fail_safe_mode = int(c == 'fl' and FS[0] <= t < FS[1])
                events.append((t, f'{c}/car_state', serialize_message(state)))
        for t, key, raw in sorted(events, key=lambda e: e[0]):
            rec.write(key, raw, int(round((T0 + t) * 1e9)))


@pytest.mark.slow
def test_corner_losses_count_every_life_and_each_restart_costs_per_corner(tmp_path):
    from mr_damper_bringup.recorder import work_file
    _write(tmp_path / 'suite.mcap', 0.0, REC_DOWN[0])
    _write(tmp_path / 'suite.1.mcap', REC_DOWN[1], END_S)
    # the first recorder's file left in its work folder (as a killed recorder leaves it)
    cut = work_file(tmp_path / 'suite.mcap')
    cut.parent.mkdir()
    (tmp_path / 'suite.mcap').rename(cut)
    supervision = {'restarts': [
        {'node': 'fl.mr_damper_identifier', 'death_s': KILL_S, 'death_epoch_s': T0 + KILL_S,
         'restart_s': KILL_S + 1.0, 'restart_epoch_s': T0 + KILL_S + 1.0, 'reason': 'died'},
        {'node': 'mr_damper_record', 'death_s': REC_DOWN[0], 'death_epoch_s': T0 + REC_DOWN[0],
         'restart_s': REC_DOWN[1], 'restart_epoch_s': T0 + REC_DOWN[1], 'reason': 'hung'}],
        'gave_up': None}
    # what the launcher had from the last statuses: the new recorder's count only
    summary = {'corners': {'fl': {'samples_received': 18000}, 'fr': {}}}
    add_corner_losses(summary, tmp_path, supervision)
    fl, fr = summary['corners']['fl'], summary['corners']['fr']
    # the recorder missed 2 s of each stream: counted as gaps, not as losses
    assert fl['samples_in_span'] == fr['samples_in_span'] == END_S * RATE
    assert fl['samples_recorded'] == fr['samples_recorded'] == (END_S - 2.0) * RATE
    # fl: from its last count (9.9 s) to its new life's start (12 s): 2.1 s of samples
    assert fl['identifier_lives'] == 2 and fr['identifier_lives'] == 1
    assert fl['samples_lost'] == pytest.approx(2.1 * RATE, abs=BATCH)
    assert fr['samples_lost'] == pytest.approx(0, abs=BATCH)
    ident, rec = summary['restarts']
    assert ident['window_s'] == pytest.approx(REC_DOWN[0] - KILL_S)
    assert ident['failsafe_s_by_corner']['fl'] == pytest.approx(FS[1] - FS[0], abs=0.06)
    assert ident['failsafe_s_by_corner']['fr'] == 0.0
    assert ident['failsafe_s'] == pytest.approx(FS[1] - FS[0], abs=0.06)
    assert ident['measurements_lost_by_corner']['fl'] == pytest.approx(2.1 * RATE, abs=BATCH)
    assert ident['measurements_lost'] == ident['measurements_lost_by_corner']['fl']
    # the recorder's restart: no car state recorded while it was down, nothing lost
    assert rec['no_car_state_s'] == pytest.approx(REC_DOWN[1] - REC_DOWN[0], abs=0.06)
    # (the identifiers' counts come every 0.1 s: one batch of resolution per corner)
    for c in ('fl', 'fr'):
        assert rec['measurements_lost_by_corner'][c] == pytest.approx(0, abs=BATCH)
    assert summary['restart_counts'] == {'fl.mr_damper_identifier': 1, 'mr_damper_record': 1}
    assert summary['recording']['complete'] is False
    assert [p['file'] for p in summary['recording']['parts']] == [
        str(cut), str(tmp_path / 'suite.1.mcap')]


def test_without_a_recording_no_loss_is_claimed(tmp_path):
    summary = {'corners': {'fl': {'samples_received': 10}}}
    add_corner_losses(summary, tmp_path, {'restarts': [], 'gave_up': None})
    assert summary['corners']['fl']['samples_lost'] is None
    assert summary['recording']['complete'] is False and summary['restarts'] == []


def test_a_run_without_corners_reports_its_recording_complete_or_cut(tmp_path):
    # a vehicle run on shipped models has no corner stacks: no corner reads the recording,
    # yet its state is the recording's, not "no recording"
    from mr_damper_bringup.recorder import work_file
    _write(tmp_path / 'suite.mcap', 0.0, 2.0)
    summary = {'corners': {}}
    add_corner_losses(summary, tmp_path, {'restarts': [], 'gave_up': None})
    state = summary['recording']
    assert state['complete'] is True and 'note' not in state
    assert state['parts'][0]['messages'] == 2 * (2.0 * RATE / BATCH + 2.0 * 10 + 2.0 * 20)
    # the same file cut short (a killed recorder's work file): read, but not complete
    _write(tmp_path / 'suite.1.mcap', 3.0, 4.0)
    cut = work_file(tmp_path / 'suite.mcap')
    cut.parent.mkdir()
    (tmp_path / 'suite.mcap').rename(cut)
    add_corner_losses(summary, tmp_path, {'restarts': [], 'gave_up': None})
    assert summary['recording']['complete'] is False
    assert len(summary['recording']['parts']) == 2
