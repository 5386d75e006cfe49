"""
Sim time end to end: a replay publishing ``/clock`` drives the identifier's time.

The rig replays a DAQ file with ``publish_clock`` and the identifier runs with
``use_sim_time:=true``: every window is fitted in order on an iteration budget with a seed per
window, so the published parameter sequence is the same at ``rate_factor`` 4 as at 1, and equal
to the ROS-free core's replay of the same samples. The parameter stamps are recording time.
"""
import pytest

from conftest import QUIROZ_DIR
from integration.ros_helpers import NodeProcess
from mr_damper_interfaces.msg import KwokParameters
from mr_damper_model.live import LiveConfig, LiveIdentifier
from mr_damper_common.messages import identified_set_from_msg

pytestmark = [pytest.mark.integration, pytest.mark.slow]

QUIROZ = QUIROZ_DIR / 'quiroz_sine_5mm3Hz_0p5A.csv.gz'
HANG_GUARD_S = 180.0    # a guard against a hung node, not a time budget


def _replay(listener, rate_factor, n_samples):
    ns = f'simtime{int(rate_factor * 10)}'
    params = listener.subscribe(f'/{ns}/mr_damper/kwok_parameters', KwokParameters)
    diag = listener.diagnostics()
    ident = NodeProcess('identifier_node', {'use_sim_time': True}, namespace=ns)
    rig = NodeProcess('rig_node', {'mode': 'csv', 'file': str(QUIROZ),
                                   'rate_factor': rate_factor, 'publish_clock': True,
                                   'wait_for_subscribers': 1}, namespace=ns)
    name = f'{ns}/mr_damper_identifier'
    with ident, rig:
        assert rig.wait(HANG_GUARD_S) == 0, rig.output()

        def drained():
            st = diag.values(name)
            # every sample of the file taken in, then every due window answered
            return (st.get('samples_received') == n_samples
                    and st.get('windows_due', 0) > 0 and st.get('windows_due') == st.get(
                'windows_fitted', 0) + sum(st.get('windows_skipped', {}).values())
                and len(params) >= st.get('parameters_published', 1))
        keys = ('windows_due', 'windows_fitted', 'windows_skipped', 'windows_superseded',
                'windows_overflow', 'parameters_published', 'samples_received',
                'samples_accepted', 'processed_up_to_s')
        assert listener.wait_for(drained, HANG_GUARD_S, procs=[ident]), \
            ({k: diag.values(name).get(k) for k in keys}, len(params),
             ident.output()[-2000:])
        status = diag.values(name)
    assert status['use_sim_time'] is True
    assert status['windows_superseded'] == 0 and status['windows_overflow'] == 0
    assert status['samples_lost'] == 0
    return [identified_set_from_msg(m).to_dict() for _, m in params], status


def test_replay_gives_the_same_parameter_sequence_at_rate_4_as_at_1(listener):
    from mr_damper_rig.replay import read_csv_stream
    data = read_csv_stream(QUIROZ)
    expected = LiveIdentifier(LiveConfig(backlog_windows=300)).replay(data)
    assert len(expected) >= 10
    fast, fast_status = _replay(listener, 4.0, data.n)
    slow, slow_status = _replay(listener, 1.0, data.n)
    assert fast_status['samples_accepted'] == slow_status['samples_accepted'] == data.n
    assert len(fast) == len(slow) == len(expected)
    for a, b, e in zip(fast, slow, expected):
        assert a['window_end_s'] == b['window_end_s'] == pytest.approx(e.window_end_s, abs=1e-9)
        assert a['parameters'] == b['parameters'] == pytest.approx(e.parameters, rel=1e-12)
        assert a['valid'] == b['valid'] == e.valid
        # stamped on the recording's clock: at or after the window's last sample, never
        # after the last sample of the file
        assert e.window_end_s - 1e-9 <= a['stamp_s'] <= data.t[-1] + 1e-9
