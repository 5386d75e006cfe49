"""
``python -m mr_damper_bringup.reaper GRACE_S``: end a suite's nodes once their launcher is gone.

:class:`mr_damper_bringup.processes.Suite` starts it in a session of its own (a signal to the
launcher's process group does not reach it) with a pipe on its stdin, and writes the process id
of each node it starts, one a line. The pipe ends (EOF) when the launcher exits, however it
exits, SIGKILL included, with no race. Then every node still running gets SIGTERM on its process
group (each node leads its own), and the groups still there after ``GRACE_S`` seconds get
SIGKILL: a node frozen inside the middleware ignores SIGTERM. A node is known by its process id
and its start time (``/proc/PID/stat``), so a process id the system gave to another process
since is never signalled.

The nodes also get SIGTERM from the kernel when the launcher dies (``PR_SET_PDEATHSIG``,
:func:`mr_damper_bringup.processes.die_with_parent`): the reaper is the second line, for the
nodes that do not stop on SIGTERM. After a clean stop of the suite every node has already
exited, and the reaper exits at the EOF without signalling anything. No ROS, no psutil: it
must start fast and never hang.
"""
import os
import signal
import sys
import time


def proc_stat(pid):
    """
    Return ``(state, start_time)`` of process ``pid`` from ``/proc/PID/stat``, or None.

    ``state`` is the one-letter state (``Z``: a zombie, ``X``: dead), ``start_time`` the start
    time in clock ticks since boot (with the process id, a process's identity).
    """
    try:
        with open(f'/proc/{int(pid)}/stat', 'rb') as fh:
            text = fh.read().decode('ascii', 'replace')
    except OSError:
        return None
    # the command name (field 2) is in parentheses and may hold spaces and parentheses
    fields = text[text.rfind(')') + 2:].split()
    try:
        return fields[0], int(fields[19])
    except (IndexError, ValueError):
        return None


def running(pid, start_time):
    """Tell whether process ``pid`` is still the one started at ``start_time`` and not dead."""
    st = proc_stat(pid)
    return st is not None and st[1] == start_time and st[0] not in ('Z', 'X')


def _signal_group(pid, sig):
    try:
        os.killpg(pid, sig)
    except (ProcessLookupError, PermissionError):
        try:
            os.kill(pid, sig)       # not a group leader (started without its own session)
        except (ProcessLookupError, PermissionError):
            pass


def reap(nodes, grace_s, *, poll_s=0.05, clock=time.monotonic, sleep=time.sleep):
    """
    Stop the nodes still running: SIGTERM to each group, SIGKILL to those left after ``grace_s``.

    Parameters
    ----------
    nodes : dict
        Process id -> start time (:func:`proc_stat`); each node leads its process group.
    grace_s : float
        Time [s] the nodes get to end on SIGTERM.
    poll_s : float
        Poll period [s] while waiting.
    clock, sleep : callable
        Time source and wait (tests).

    Returns
    -------
    dict
        ``terminated``: process ids sent SIGTERM; ``killed``: those sent SIGKILL after the grace.

    """
    left = [pid for pid, start in nodes.items() if running(pid, start)]
    for pid in left:
        _signal_group(pid, signal.SIGTERM)
    out = {'terminated': list(left), 'killed': []}
    end = clock() + float(grace_s)
    while left and clock() < end:
        sleep(poll_s)
        left = [pid for pid in left if running(pid, nodes[pid])]
    for pid in left:
        if running(pid, nodes[pid]):
            _signal_group(pid, signal.SIGKILL)
            out['killed'].append(pid)
    return out


def read_nodes(stream):
    """
    Read process ids, one a line, until EOF; return ``{pid: start time}`` of those that run.

    Nodes that ended are dropped as new ones arrive, so the table stays as small as the suite.
    """
    nodes = {}
    for line in stream:
        try:
            pid = int(line.strip())
        except ValueError:
            continue
        st = proc_stat(pid)
        if st is not None:
            nodes[pid] = st[1]
        nodes = {p: s for p, s in nodes.items() if running(p, s)}
    return nodes


def main(argv=None):
    """Wait for the launcher's end (EOF on stdin), then reap its nodes; return 0."""
    argv = sys.argv[1:] if argv is None else argv
    grace_s = float(argv[0]) if argv else 10.0
    signal.signal(signal.SIGINT, signal.SIG_IGN)     # only the pipe's end matters
    nodes = read_nodes(sys.stdin.buffer)
    done = reap(nodes, grace_s)
    if done['terminated']:
        print(f'mr-damper-suite reaper {time.strftime("%H:%M:%S")}: the launcher is gone; '
              f'SIGTERM to {len(done["terminated"])} node process group(s) '
              f'{done["terminated"]}, SIGKILL after {grace_s:g} s to {done["killed"]}',
              file=sys.stderr, flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
