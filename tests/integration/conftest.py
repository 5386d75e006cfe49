"""Fixtures of the multi-process ROS 2 tests."""
import pytest

from integration.ros_helpers import Listener


@pytest.fixture(scope='session', autouse=True)
def node_log_dir(tmp_path_factory):
    """Write the node processes' output into pytest's temporary folder, not ``/tmp`` itself."""
    from integration import ros_helpers
    ros_helpers.LOG_DIR = str(tmp_path_factory.mktemp('node_logs'))
    yield ros_helpers.LOG_DIR
    ros_helpers.LOG_DIR = None


@pytest.fixture(scope='module')
def listener(request):
    """
    Return the test module's :class:`~integration.ros_helpers.Listener` (closed after the module).

    A module that needs more on it (a latched publisher, a helper) overrides ``listener`` with a
    fixture that takes this one and adds to it.
    """
    lis = Listener(request.module.__name__.rpartition('.')[2] + '_listener')
    yield lis
    lis.close()


#: hang guard [s] for the test's suites to let go of the test's ROS domain
DOMAIN_FREE_GUARD_S = 60.0


@pytest.fixture(autouse=True)
def domain_free_after_each_test():
    """
    After each test, wait until every process of the suites it ran has gone (event, not time).

    A launcher holds a lock of its ROS domain that its nodes and its reaper inherit
    (``processes.DomainLock``): the next suite on the domain is refused while any of them
    runs. The lock, not the node list, says when a suite is over (its reaper outlives its
    nodes). Past the hang guard the holders are killed and the test that left them fails, not
    the suites after it: a fresh-clone CI run had eight suite tests refused one after the other
    (an earlier test's in-process launcher had kept the domain locked, fixed in ``main``).
    """
    yield
    import os
    import signal
    import time

    from mr_damper_bringup.processes import DomainLock
    lock = DomainLock(int(os.environ['ROS_DOMAIN_ID']))
    end = time.monotonic() + DOMAIN_FREE_GUARD_S
    while not lock.acquire():
        if time.monotonic() > end:
            holders = _holding(lock.path)
            for pid in holders:
                try:
                    os.kill(pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass
            pytest.fail(f'the test domain stayed locked {DOMAIN_FREE_GUARD_S:g} s after the '
                        f'test by processes {holders} (launcher pid {lock.holder()})')
        time.sleep(0.05)
    lock.release()


def _holding(path):
    """Return the process ids that have ``path`` open (``/proc/PID/fd``)."""
    import os
    pids = []
    for pid in (int(d) for d in os.listdir('/proc') if d.isdigit()):
        try:
            fds = os.listdir(f'/proc/{pid}/fd')
            if any(os.readlink(f'/proc/{pid}/fd/{fd}') == str(path) for fd in fds):
                pids.append(pid)
        except OSError:
            continue
    return pids
