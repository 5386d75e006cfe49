"""
Tests of node_utils.spinning: the spin loop, SIGINT / SIGTERM in run_node, the fast lane.

The spin loop's stop and error handling, and run_node's signal handling in a real process
(exit 0 after finish and destroy, in that order).
"""
import json
import os
import signal
import subprocess
import sys
import textwrap

import pytest
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from mr_damper_common import node_utils
import node_utils_helpers
from process_helpers import popen, stop_group
from ros_context import ros_context

ros = node_utils_helpers.ros      # this module's rclpy context (fixture)


class _Executor:
    """spin_once counts calls, raises ``error`` at call ``fail_at``, stops at ``stop_at``."""

    def __init__(self, stop_at=None, fail_at=None, error=RuntimeError('Unable to convert')):
        self.calls = 0
        self.stop_at, self.fail_at, self.error = stop_at, fail_at, error

    def spin_once(self, timeout_sec):
        self.calls += 1
        if self.calls == self.stop_at:
            node_utils.request_stop()
        if self.calls == self.fail_at:
            raise self.error


@pytest.fixture
def stop_flag():
    """Clear the stop flag; rclpy's default context up (the spin loop asks ``rclpy.ok()``)."""
    node_utils._STOP.clear()
    try:
        with ros_context(default=True):
            yield
    finally:
        node_utils._STOP.clear()


def test_spin_returns_on_stop_request_and_on_done(stop_flag):
    ex = _Executor(stop_at=3)
    node_utils.spin(ex)
    assert ex.calls == 3 and node_utils.stop_requested()
    node_utils._STOP.clear()
    ex = _Executor()
    node_utils.spin(ex, done=lambda: ex.calls >= 5)
    assert ex.calls == 5


def test_spin_error_after_stop_ends_quietly_before_stop_raises(stop_flag):
    ex = _Executor(stop_at=2, fail_at=2)
    node_utils.spin(ex)                                  # the shutdown race: no error
    assert ex.calls == 2
    node_utils._STOP.clear()
    with pytest.raises(RuntimeError, match='Unable to convert'):
        node_utils.spin(_Executor(fail_at=2))


_NODE_SCRIPT = textwrap.dedent('''
    import sys, time
    from rclpy.node import Node
    from mr_damper_common.node_utils import run_node

    class Busy(Node):
        def __init__(self):
            super().__init__('node_utils_signal_test')
            self.ticks = 0
            self.create_timer(0.001, self.tick)

        def tick(self):
            self.ticks += 1
            t = time.perf_counter()
            while time.perf_counter() - t < 0.0008:   # keep the main thread busy
                pass
            if self.ticks == 50:
                print('ready', flush=True)

    def finish(node):
        print(f'finish after {node.ticks} ticks', flush=True)

    sys.exit(run_node(Busy, 'busy', finish=finish))
''')


_STUCK_TEARDOWN = textwrap.dedent('''
    import ctypes, sys, time
    from rclpy.node import Node
    from mr_damper_common.node_utils import spinning

    class StuckInTheMiddleware(Node):
        def __init__(self):
            super().__init__('node_utils_teardown_test')

        def destroy_node(self):
            print('destroying', flush=True)
            if {hold_gil}:
                ctypes.PyDLL(None).sleep(3600)     # a C call that keeps the GIL
            while True:
                time.sleep(0.01)                  # one that releases it, never returning

    def finish(node):
        print('finished', flush=True)
        return 0

    spinning.TEARDOWN_GUARD_S = 0.5
    # no race between the two: the watchdog only where the guard thread cannot run at all
    spinning.TEARDOWN_WATCHDOG_S = 1.0 if {hold_gil} else 3600.0
    sys.exit(spinning.run_node(StuckInTheMiddleware, 'stuck', run=lambda node: None,
                               finish=finish))
''')


def test_run_guarded_says_whether_the_work_ended_and_never_waits_past_its_guard(capsys):
    import threading
    done = []
    assert node_utils.run_guarded(lambda: done.append(1), 60.0, what='quick') is True
    assert done == [1] and capsys.readouterr().err == ''
    # a work that cannot end before the event is set (as a teardown stuck in the middleware):
    # the caller goes on after the guard, the work still running in its daemon thread
    release, ended = threading.Event(), threading.Event()

    def stuck():
        release.wait()
        ended.set()

    assert node_utils.run_guarded(stuck, 0.05, 'stuck_work', what='x: the stuck work') is False
    assert not ended.is_set()
    assert capsys.readouterr().err == ('x: the stuck work did not end within 0.05 s; going on '
                                       'without it\n')
    assert any(t.name == 'stuck_work' and t.daemon for t in threading.enumerate())
    release.set()
    assert ended.wait(60.0)      # hang guard only


@pytest.mark.slow
@pytest.mark.parametrize('hold_gil, code', [(False, 0), (True, 1)])
def test_a_teardown_stuck_in_the_middleware_ends_the_process_with_its_stacks(hold_gil, code):
    # the finished node's exit status when the stuck call lets the guard thread run; the
    # faulthandler watchdog's status 1 when it holds the GIL; the stacks in both cases
    proc = popen([sys.executable, '-c', _STUCK_TEARDOWN.format(hold_gil=hold_gil)],
                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                 env=dict(os.environ))
    try:
        out, err = proc.communicate(timeout=120)          # hang guard only
    finally:
        if proc.poll() is None:
            stop_group(proc, signal.SIGKILL)
    assert proc.returncode == code, (out, err)
    assert out == 'finished\ndestroying\n', (out, err)
    assert 'destroy_node' in err and 'most recent call first' in err, err
    assert ('did not tear the node down' in err) == (not hold_gil), err


@pytest.mark.slow
@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_run_node_exits_0_on_signal_after_finish(sig):
    proc = popen([sys.executable, '-c', _NODE_SCRIPT], stdout=subprocess.PIPE,
                 stderr=subprocess.STDOUT, text=True, env=dict(os.environ))
    try:
        assert proc.stdout.readline().strip() == 'ready'
        proc.send_signal(sig)
        out, _ = proc.communicate(timeout=30)          # hang guard only
    finally:
        if proc.poll() is None:
            stop_group(proc, signal.SIGKILL)
    assert proc.returncode == 0, out
    assert out.startswith('finish after') and 'Traceback' not in out, out


def test_fast_lane_takes_its_topic_in_its_own_thread_with_the_parents_namespace(ros):
    import threading
    import time
    parent = rclpy.create_node('lane_parent', namespace='/corner_fl', context=ros)
    lane = node_utils.FastLane(parent, 'link')
    assert (lane.node.get_name(), lane.node.get_namespace()) == ('lane_parent_link',
                                                                 '/corner_fl')
    # no parameter services on the lane: only the parent answers `ros2 param`
    services = [name for name, _ in lane.node.get_service_names_and_types_by_node(
        'lane_parent_link', '/corner_fl')]
    assert not any(name.endswith('/get_parameters') for name in services), services
    parent_services = parent.get_service_names_and_types_by_node('lane_parent', '/corner_fl')
    assert '/corner_fl/lane_parent/get_parameters' in [name for name, _ in parent_services]
    got, threads = [], set()

    def on_msg(msg):
        got.append(msg.data)
        threads.add(threading.current_thread().name)
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    lane.node.create_subscription(String, 'link_topic', on_msg, qos)   # relative: namespaced
    lane.start()
    pub = parent.create_publisher(String, '/corner_fl/link_topic', qos)
    for _ in range(3000):   # discovery: a hang guard, not a time bound
        if pub.get_subscription_count() == 1:
            break
        time.sleep(0.01)
    for k in range(50):
        pub.publish(String(data=str(k)))
    for _ in range(3000):   # the parent is never spun: the lane's thread takes them
        if len(got) == 50:
            break
        time.sleep(0.01)
    assert got == [str(k) for k in range(50)] and threads == {'lane_parent_link'}
    lane.close()
    assert lane._thread is None
    parent.destroy_node()


@pytest.mark.parametrize('spec, cpus', [('', set()), ('1', {1}), ('0,2-3', {0, 2, 3}),
                                        (' 1 , 3 ', {1, 3}), ('2-2', {2})])
def test_cpu_lists_read_as_taskset_takes_them(spec, cpus):
    assert node_utils.parse_cpu_list(spec) == cpus


@pytest.mark.parametrize('spec', ['a', '3-1', '-1', '1-', '1,x', '0.5'])
def test_a_bad_cpu_list_is_refused(spec):
    with pytest.raises(ValueError, match='CPU list'):
        node_utils.parse_cpu_list(spec)


def test_cpu_affinity_pins_every_thread_and_threads_started_later(tmp_path):
    # in a process of its own (pinning this one would pin the test run): a thread before and
    # one after the call, each thread's mask read back from the kernel; a CPU the process may
    # not use is left out with a warning, and a list of none of its CPUs changes nothing
    script = textwrap.dedent('''
        import json, os, threading
        from mr_damper_common.node_utils import set_cpu_affinity

        class Log:
            warnings = []
            def warning(self, text):
                self.warnings.append(text)

        def masks():
            return sorted({tuple(sorted(os.sched_getaffinity(int(t))))
                           for t in os.listdir('/proc/self/task')})

        allowed = sorted(os.sched_getaffinity(0))
        one = allowed[-1]
        stop = threading.Event()
        before = threading.Thread(target=stop.wait)
        before.start()
        log = Log()
        applied = set_cpu_affinity(f'{one},{one + 4096}', log)
        after = threading.Thread(target=stop.wait)
        after.start()
        pinned = masks()
        none = set_cpu_affinity(str(one + 4096), log)
        unchanged = masks()
        bad = set_cpu_affinity('x', log)
        stop.set()
        print(json.dumps(dict(one=one, applied=sorted(applied), pinned=pinned, none=sorted(none),
                              unchanged=unchanged, bad=sorted(bad), warnings=log.warnings)))
    ''')
    got = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         timeout=120, check=True)
    r = json.loads(got.stdout)
    assert r['applied'] == [r['one']]
    assert r['pinned'] == [[r['one']]]             # the main thread and both others
    assert r['none'] == [] and r['unchanged'] == [[r['one']]]
    assert r['bad'] == []
    assert len(r['warnings']) == 3
    assert 'not available' in r['warnings'][0] and 'nothing pinned' in r['warnings'][1]
    assert 'CPU list' in r['warnings'][2]


def test_realtime_priority_leaves_native_threads_and_later_threads_alone():
    # in a process of its own (the policy would stay on this one): a native thread (made with
    # pthread_create, blocked in pause(): a library's thread, as the middleware's), a Python
    # thread, and one started afterwards by the now SCHED_FIFO main thread; each thread's
    # policy read back from the kernel. As root (CI and this machine) the priority applies;
    # without CAP_SYS_NICE the refusal is checked by its warning
    script = textwrap.dedent('''
        import ctypes, json, os, threading, time
        from mr_damper_common.node_utils import set_realtime_priority

        class Log:
            warnings = []
            def warning(self, text):
                self.warnings.append(text)

        libc = ctypes.CDLL(None, use_errno=True)
        before = set(os.listdir('/proc/self/task'))
        handle = ctypes.c_ulong()
        start = ctypes.cast(libc.pause, ctypes.c_void_p)
        assert libc.pthread_create(ctypes.byref(handle), None, start, None) == 0
        while len(set(os.listdir('/proc/self/task')) - before) < 1:
            time.sleep(0.01)
        native = int((set(os.listdir('/proc/self/task')) - before).pop())
        stop = threading.Event()
        own = threading.Thread(target=stop.wait)
        own.start()
        log = Log()
        applied = set_realtime_priority(7, log, native_threads=False)
        later = threading.Thread(target=stop.wait)
        later.start()
        got = dict(main=os.sched_getscheduler(0), prio=os.sched_getparam(0).sched_priority,
                   own=os.sched_getscheduler(own.native_id), native=os.sched_getscheduler(native),
                   native_nice=os.getpriority(os.PRIO_PROCESS, native),
                   later=os.sched_getscheduler(later.native_id),
                   later_nice=os.getpriority(os.PRIO_PROCESS, later.native_id))
        stop.set()
        own.join()
        later.join()
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        every = set_realtime_priority(7, log)          # the car nodes' call: every thread
        got.update(every_native=os.sched_getscheduler(native), every_applied=every)
        print(json.dumps(dict(applied=applied, warnings=log.warnings, **got)), flush=True)
        os._exit(0)                                     # the native thread never returns
    ''')
    got = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         timeout=120, check=True)
    r = json.loads(got.stdout)
    if not r['applied']:                                # no CAP_SYS_NICE: nothing changed
        assert 'not applied' in r['warnings'][0]
        assert r['main'] == r['own'] == r['native'] == os.SCHED_OTHER
        return
    fifo_reset = os.SCHED_FIFO | os.SCHED_RESET_ON_FORK
    assert r['main'] == r['own'] == fifo_reset and r['prio'] == 7
    assert r['native'] == os.SCHED_OTHER                # a library's thread: time slices,
    assert r['native_nice'] == -20                      # first among the normal ones
    assert r['later'] == os.SCHED_OTHER and r['later_nice'] == 0    # nothing inherited
    assert r['every_applied'] and r['every_native'] == os.SCHED_FIFO
