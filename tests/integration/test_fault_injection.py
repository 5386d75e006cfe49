"""
Fault injection on the running suite: SIGSTOP and SIGKILL each node in turn, bad commands.

Real node processes (the console scripts), started by ``mr_damper_bringup.processes.Suite`` like
the launcher does, in the private domain of tests/conftest.py. Every assertion is on the order
of events and on counters in the nodes' status topics, never on how long something took; the
waits are hang guards only. One run, about a minute and a half:

- identifier stopped (SIGSTOP) long enough for the rig's measurement writer to fill up with
  samples it never acknowledges (> 5,000 at 1 kHz): the rig keeps running and publishing (its
  writer is replaced: ``writer_resets``), the car goes fail-safe (stale parameters) and keeps
  stepping; SIGCONT: the car leaves fail-safe again;
- identifier killed (SIGKILL): the same, then restarted from its parameter file;
- quarter car stopped, then killed and restarted: rig and identifier carry on;
- rig stopped, then killed and restarted: identifier and car carry on, the car goes fail-safe
  while no new model comes and recovers afterwards;
- at the end every node exits 0 on SIGINT (SIGTERM for the identifier).

A second test sends out-of-range and non-finite current commands to a rig with
``current_source:=command``: clamped and refused commands are counted, the coil current stays
inside the coil range.
"""
import math
import os
import signal

import pytest

from integration.ros_helpers import fault_test_suite, NodeProcess
from mr_damper_bringup.config import IDENT, NODES, QC, RIG

pytestmark = [pytest.mark.integration, pytest.mark.slow]

GUARD_S = 60.0   # hang guard of every wait (a loaded machine needs seconds, never this long)


def test_each_node_stopped_and_killed_the_others_carry_on(listener, tmp_path):
    suite = fault_test_suite(tmp_path)
    diag = listener.diagnostics()

    def rig():
        return diag.values('mr_damper_rig')

    def ident():
        return diag.values('mr_damper_identifier')

    def ident_count():
        return diag.count('mr_damper_identifier')
    wait = listener.wait_for

    def car_st():
        """Return the car's newest /diagnostics values."""
        return diag.values(QC)

    def car_mode(expected, reason=None):
        def check():
            st = car_st()
            return st.get('mode') == expected and (reason is None or st['reason'] == reason)
        return check

    def grows(latest, key, by=1):
        """Predicate: ``latest()[key]`` exceeds its value now by ``by``."""
        base = latest().get(key, 0)
        return lambda: latest().get(key, 0) >= base + by

    def fresh(count, n=3):
        """Predicate: ``count()`` (a node's statuses) grew by ``n``: alive and publishing."""
        base = count()
        return lambda: count() >= base + n

    def car_count():
        return diag.count(QC)

    def tails():
        return {name: suite.log_tail(name) for name in NODES}

    try:
        suite.start_all()
        assert wait(car_mode('normal'), GUARD_S), (car_st(), tails())

        # -- identifier stopped: its reader stops acknowledging the measurement batches; the
        #    writer keeps them (5,000 messages of 20 samples: 100 s at 1 kHz), the rig goes on
        lost_before = (ident().get('stream') or {}).get('lost', 0)
        os.kill(suite.pid(IDENT), signal.SIGSTOP)
        try:
            assert wait(car_mode('failsafe', 'stale'), GUARD_S), car_st()
            steps = car_st()['steps']
            assert wait(grows(rig, 'samples_published', 2000), GUARD_S), rig()
            assert wait(lambda: car_st()['steps'] > steps + 1000, GUARD_S)
            assert car_st()['mode'] == 'failsafe'
        finally:
            os.kill(suite.pid(IDENT), signal.SIGCONT)
        assert wait(car_mode('normal'), GUARD_S), (car_st(), ident(), tails())
        assert suite.alive(RIG) and suite.alive(IDENT) and suite.alive(QC)
        # the stopped identifier got every sample of its pause afterwards: none lost
        assert (ident().get('stream') or {}).get('lost', 0) == lost_before, ident().get('stream')
        assert rig()['writer_resets'] == 0, rig()

        # -- identifier killed, then restarted from its parameter file
        resets = rig()['writer_resets']
        suite.kill(IDENT, signal.SIGKILL)
        assert wait(car_mode('failsafe', 'stale'), GUARD_S), car_st()
        assert wait(grows(rig, 'samples_published', 6000), GUARD_S), (rig(), tails())
        assert rig()['writer_resets'] >= resets and suite.alive(RIG)
        suite.start(IDENT)
        assert wait(car_mode('normal'), GUARD_S), (car_st(), tails())

        # -- quarter car stopped, then killed and restarted: rig and identifier carry on
        os.kill(suite.pid(QC), signal.SIGSTOP)
        try:
            assert wait(grows(ident, 'windows_fitted', 5), GUARD_S), ident()
            assert wait(grows(rig, 'samples_published', 2000), GUARD_S), rig()
        finally:
            os.kill(suite.pid(QC), signal.SIGCONT)
        assert wait(fresh(car_count), GUARD_S) and suite.alive(QC)
        suite.kill(QC, signal.SIGKILL)
        assert wait(grows(ident, 'windows_fitted', 5), GUARD_S), ident()
        n_car = diag.count(QC)
        suite.start(QC)
        assert wait(lambda: diag.count(QC) > n_car and car_mode('normal')(), GUARD_S), \
            (car_st(), tails())

        # -- rig stopped, then killed and restarted: identifier and car carry on
        os.kill(suite.pid(RIG), signal.SIGSTOP)
        try:
            assert wait(car_mode('failsafe', 'stale'), GUARD_S), car_st()
            assert wait(fresh(ident_count), GUARD_S) and wait(fresh(car_count), GUARD_S)
        finally:
            os.kill(suite.pid(RIG), signal.SIGCONT)
        assert wait(car_mode('normal'), GUARD_S), (car_st(), tails())
        suite.kill(RIG, signal.SIGKILL)
        assert wait(car_mode('failsafe', 'stale'), GUARD_S), car_st()
        assert wait(fresh(ident_count), GUARD_S) and wait(fresh(car_count), GUARD_S)
        suite.start(RIG)
        assert wait(car_mode('normal'), GUARD_S), (car_st(), tails())
        assert suite.poll() == {}, tails()

        # -- SIGTERM and SIGINT: exit 0
        assert suite.kill(IDENT, signal.SIGTERM, wait_s=GUARD_S) == 0, tails()
    finally:
        codes = suite.stop(timeout_s=GUARD_S)
    assert codes[QC] == 0 and codes[RIG] == 0, (codes, tails())


def test_rig_clamps_and_refuses_bad_current_commands(listener):
    from std_msgs.msg import Float64
    params = {'mode': 'sim', 'current_source': 'command', 'current_min_a': 0.0,
              'current_max_a': 2.0, 'diagnostics_period_s': 0.1}
    diag = listener.diagnostics()
    name = 'fi/mr_damper_rig'     # the rig in namespace fi: /fi/mr_damper/current_command
    pub = listener.publisher('/fi/mr_damper/current_command', Float64)
    with NodeProcess('rig_node', params=params, namespace='fi') as rig:
        assert listener.wait_for(lambda: diag.count(name) and pub.get_subscription_count() > 0,
                                 GUARD_S, procs=[rig]), rig.output()
        for k, value in enumerate((-5.0, 1e9, math.nan, math.inf, 1.2)):
            n = diag.count(name)
            pub.publish(Float64(data=value))

            def counted(k=k, n=n):
                st = diag.values(name)
                return diag.count(name) > n + 1 and sum(st['commands'].values()) >= k + 1
            # the status after this command counts it; the coil stays inside its range
            assert listener.wait_for(counted, GUARD_S, procs=[rig]), diag.values(name)
            assert 0.0 <= diag.values(name)['coil_current_a'] <= 2.0
        st = diag.values(name)
        assert st['commands'] == {'accepted': 1, 'clamped_low': 1, 'clamped_high': 1,
                                  'refused_non_finite': 2}
        assert st['current_commands'] == 3          # the three applied commands
        # the clamped and refused commands raised warnings on /diagnostics (level WARN)
        assert 1 in diag.levels(name)
        code = rig.stop()
    assert code == 0, rig.output()


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_identifier_exits_0_on_a_signal_in_the_middle_of_a_burst(listener, sig):
    """Signal sent while a 5,000-message burst (single-sample layout) is taken: exit 0."""
    from sensor_msgs.msg import JointState
    from mr_damper_common.messages import measurement_to_msg
    from mr_damper_common.node_utils import MEASUREMENT_QOS
    ns = f'fi_burst_{int(sig)}'
    diag = listener.diagnostics()
    name = f'{ns}/mr_damper_identifier'
    pub = listener.publisher(f'/{ns}/mr_damper/joint_measurement', JointState, MEASUREMENT_QOS)
    params = {'diagnostics_period_s': 0.05}
    with NodeProcess('identifier_node', params=params, namespace=ns) as ident:
        assert listener.wait_for(lambda: pub.get_subscription_count() > 0 and diag.count(name),
                                 GUARD_S, procs=[ident]), ident.output()
        msg = None
        for k in range(5000):   # 1 s of 5 kHz samples, as fast as the writer takes them
            t = k * 2e-4
            msg = measurement_to_msg(t, 0.01 * math.sin(6.9 * t), 0.07 * math.cos(6.9 * t),
                                     300.0 * math.cos(6.9 * t), 1.0, msg=msg)
            pub.publish(msg)
        # the node is taking the burst (its count moved); the signal comes while it runs
        assert listener.wait_for(lambda: diag.values(name).get('samples_received', 0) > 0,
                                 GUARD_S, procs=[ident]), ident.output()
        ident.proc.send_signal(sig)
        code = ident.wait(GUARD_S)
    out = ident.output()
    assert code == 0, out
    assert 'Traceback' not in out, out
