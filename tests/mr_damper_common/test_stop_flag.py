"""
Tests of mr_damper_common.stop_flag: the stop handlers come before the node module's imports.

Each case runs in a child interpreter (signal handlers are process-wide; pytest keeps its own).
The node module of each case is a stand-in written into ``tmp_path`` whose import sends the
process a signal, as a user's Ctrl-C or a launcher's SIGTERM during the seconds rclpy, scipy and
control take to import.
"""
import signal
import subprocess
import sys
import textwrap
import threading

import pytest

from mr_damper_common import stop_flag


def _run(tmp_path, module_text, call):
    (tmp_path / 'fake_node.py').write_text(textwrap.dedent(module_text))
    # Python's own SIGINT handler, as in a terminal: a suite started in the background (or
    # under nohup) passes SIGINT ignored to its children, which then never see a Ctrl-C
    code = ('import signal, sys\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n'
            f'from mr_damper_common import stop_flag\nsys.exit({call})\n')
    return subprocess.run([sys.executable, '-c', code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, env={'PYTHONPATH': str(tmp_path),
                                                       'PATH': '/usr/bin:/bin'})


NODE = """
    import os
    import signal
    os.kill(os.getpid(), signal.{sig})       # arrives while the module is being imported
    def main():
        print('main ran')
        return 3
"""


@pytest.mark.parametrize('sig', ['SIGINT', 'SIGTERM'])
def test_signal_during_the_node_import_exits_0_without_running_the_node(tmp_path, sig):
    proc = _run(tmp_path, NODE.format(sig=sig), "stop_flag.early_main('fake_node')")
    assert proc.returncode == 0, proc.stderr
    assert 'main ran' not in proc.stdout
    assert 'Traceback' not in proc.stderr


def test_without_early_handlers_the_same_signal_is_not_a_clean_exit(tmp_path):
    """The failure early_main prevents: Python's default handler raises in the import."""
    proc = _run(tmp_path, NODE.format(sig='SIGINT'),
                "__import__('fake_node').main()")
    assert proc.returncode != 0 and 'KeyboardInterrupt' in proc.stderr


def test_no_signal_runs_the_node_and_returns_its_status(tmp_path):
    proc = _run(tmp_path, "def main():\n    print('main ran')\n    return 3\n",
                "stop_flag.early_main('fake_node')")
    assert proc.returncode == 3 and 'main ran' in proc.stdout


def test_a_second_install_keeps_a_stop_that_came_in_between(tmp_path):
    code = """
        import os, signal, sys
        from mr_damper_common import stop_flag
        stop_flag.install_stop_handlers()
        os.kill(os.getpid(), signal.SIGINT)
        stop_flag.install_stop_handlers()       # e.g. run_node after early_main
        sys.exit(7 if stop_flag.stop_requested() else 1)
    """
    proc = subprocess.run([sys.executable, '-c', textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 7, proc.stderr


def test_handlers_set_and_restored_in_this_process():
    old = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    try:
        assert stop_flag.install_stop_handlers() is True
        assert signal.getsignal(signal.SIGINT) is stop_flag.request_stop
        assert signal.getsignal(signal.SIGTERM) is stop_flag.request_stop
    finally:
        signal.signal(signal.SIGINT, old[0])
        signal.signal(signal.SIGTERM, old[1])
        stop_flag._STOP.clear()


#: ``traced(func, k, signum, armed)``: call ``func`` with every line and bytecode traced (its
#: own and those of everything it calls); at the k-th event, if ``armed()``, send ``signum`` to
#: this process (handled inside the traced frame). Returns ``(events, sent)``.
TRACED = """
def traced(func, k, signum, armed):
    seen = [0, False]
    def local(frame, event, arg):
        frame.f_trace_opcodes = True
        if event in ('line', 'opcode'):
            seen[0] += 1
            if seen[0] == k and armed():
                seen[1] = True
                os.kill(os.getpid(), signum)
        return local
    def start(frame, event, arg):
        frame.f_trace_opcodes = True
        return local
    sys.settrace(start)
    try:
        func()
    finally:
        sys.settrace(None)
    return seen
"""


#: Child interpreter: call ``target`` again and again; in run k a SIGTERM arrives at the k-th
#: traced event (each line and each bytecode of ``target`` and of everything it calls) once
#: the SIGTERM handler is in. Prints ``events signalled stops_kept``.
AT_EVERY_BYTECODE = """
    import os, signal, sys
    from mr_damper_common import stop_flag

    {traced}
    def fresh():
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        stop_flag._INSTALLED[0] = False
        stop_flag._STOP.clear()

    target = {target}
    # a signal at event k = 1, 2, ... of a run, until a run ends before its k-th event (each
    # run counts its own events: one that differs from another, e.g. a first call that fills
    # a cache, is still signalled at every event it has)
    events = signalled = kept = 0
    for k in range(1, 100000):
        fresh()
        if {installed}:
            stop_flag.install_stop_handlers()
        seen, sent = traced(target, k, signal.SIGTERM,
                            lambda: signal.getsignal(signal.SIGTERM)
                            is stop_flag.request_stop)
        if seen < k:
            events = seen
            break
        signalled += sent
        kept += sent and stop_flag.stop_requested()
    print(events, signalled, kept)
"""


@pytest.mark.parametrize('target, installed', [
    # a SIGTERM while the handlers go in (early_main, run_node)
    ('stop_flag.install_stop_handlers', False),
    # a second signal inside the first one's handler
    ('stop_flag.request_stop', True),
    # a signal while the main thread polls or clears the flag
    ('lambda: [stop_flag.stop_requested(), stop_flag._STOP.clear()]', True),
])
def test_a_signal_at_any_bytecode_sets_the_flag_and_never_blocks(target, installed):
    """
    A SIGTERM that lands anywhere in the flag's own code is kept, and its handler returns.

    With a ``threading.Event`` as the flag, a SIGTERM inside ``install_stop_handlers`` was
    either wiped out by the clearing that followed (the node ran on) or, landing inside
    ``Event.clear()`` which holds the event's lock, ran a handler whose ``Event.set()`` waited
    for that lock forever (the rig_node start-up hang of a CI run under load). The subprocess
    timeout is only a hang guard.
    """
    code = textwrap.dedent(AT_EVERY_BYTECODE).format(target=target, installed=installed,
                                                     traced=TRACED)
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    events, signalled, kept = map(int, proc.stdout.split())
    assert signalled > 0 and events >= signalled, proc.stdout
    # the last case clears the flag itself: a signal before its clear() is legitimately undone
    if 'clear' not in target:
        assert kept == signalled, proc.stdout


#: a supervising main loop (the launcher's): its handler installed, the loop waits and polls;
#: a SIGINT is sent at the k-th traced event of one loop turn, for every k; prints how many
#: were sent, how many were seen by the flag and how many second signals ran ``on_repeat``
LOOP_AT_EVERY_BYTECODE = """
    import os, signal, sys, threading
    from mr_damper_common import stop_flag

    def event_flag():
        # the launcher's old pattern: a threading.Event set by the handler, waited on
        event = threading.Event()
        def handler(signum, frame):
            event.set()
        handler.is_set, handler.wait = event.is_set, event.wait
        return handler

    {traced}
    sent = kept = 0
    for k in range(1, 100000):
        flag = {make}
        signal.signal(signal.SIGINT, flag)
        seen, hit = traced(lambda: [flag.wait(0.0), flag.is_set()], k, signal.SIGINT,
                           lambda: True)
        if seen < k:
            break
        sent += hit
        kept += hit and flag.is_set()
    print(sent, kept)
"""


@pytest.mark.parametrize('make', ['stop_flag.Interrupts()'])
def test_a_signal_at_any_bytecode_of_a_supervising_loop_is_kept_and_never_blocks(make):
    """
    The launcher's Ctrl-C handler and its loop's wait never share a lock.

    With ``threading.Event`` (the launcher's old flag; ``event_flag()`` in the script) a SIGINT
    landing while ``Event.wait`` holds the event's lock runs a handler whose ``Event.set()``
    waits for that lock forever: this script hangs (checked by hand with ``make`` =
    ``event_flag()``; a CI run's launcher hung so after its Ctrl-C). The subprocess timeout is
    a hang guard only.
    """
    code = textwrap.dedent(LOOP_AT_EVERY_BYTECODE).format(make=make, traced=TRACED)
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    sent, kept = map(int, proc.stdout.split())
    assert sent > 0 and kept == sent, proc.stdout


def test_interrupts_second_signal_calls_on_repeat_and_wait_returns_early():
    calls = []
    interrupts = stop_flag.Interrupts(on_repeat=lambda: calls.append(1))
    assert not interrupts.wait(0.0) and not interrupts.is_set()
    interrupts(signal.SIGINT, None)
    assert interrupts.is_set() and calls == [] and interrupts.wait(60.0)   # no sleep once set
    interrupts(signal.SIGTERM, None)
    assert calls == [1] and interrupts.signals == 2


STUCK_STOP = """
    import sys, time
    from mr_damper_common.stop_flag import install_stop_handlers, stop_requested
    install_stop_handlers()
    print('ready', flush=True)
    while not stop_requested():
        time.sleep(0.01)
    def a_shutdown_that_never_ends():
        print('stopping', flush=True)    # from inside: a dump after this line shows the call
        while {stuck}:
            time.sleep(0.01)
    a_shutdown_that_never_ends()
"""


def _stop_with(signals, stuck, guard_s=120.0):
    """Start the script, wait for each of its lines, send ``signals``; return its stderr."""
    proc = subprocess.Popen([sys.executable, '-c', textwrap.dedent(STUCK_STOP.format(
        stuck=stuck))], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True)
    guard = threading.Timer(guard_s, proc.kill)     # a hang guard: the reads below then end
    guard.start()
    try:
        assert proc.stdout.readline() == 'ready\n'
        proc.send_signal(signals[0])
        assert proc.stdout.readline() == 'stopping\n'
        for sig in signals[1:]:
            proc.send_signal(sig)
        if stuck:
            # the dump ends with the main thread's frames; read until the stuck function shows
            lines = []
            for line in proc.stderr:
                lines.append(line)
                if 'a_shutdown_that_never_ends' in line:
                    break
            return ''.join(lines)
        proc.wait(guard_s)
        return proc.stderr.read()
    finally:
        guard.cancel()
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        proc.stdout.close()
        proc.stderr.close()


@pytest.mark.parametrize('first', [signal.SIGINT, signal.SIGTERM])
def test_a_sigterm_during_a_stuck_stop_prints_every_threads_stack(first):
    err = _stop_with([first, signal.SIGTERM], stuck=True)
    assert 'most recent call first' in err and 'a_shutdown_that_never_ends' in err, err


@pytest.mark.parametrize('first', [signal.SIGINT, signal.SIGTERM])
def test_a_stop_that_ends_prints_nothing(first):
    assert _stop_with([first], stuck=False) == ''
