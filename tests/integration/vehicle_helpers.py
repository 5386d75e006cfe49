"""
The car's side of the vehicle bus in a test process, and what the vehicle tests share.

:class:`Car` is a :class:`mr_damper_can.driver_sim.SimulatedEcu` on ``udp_loopback`` (a port of
the test's own, :func:`_channel`): the sensor frames (synthetic sines) every 2 ms, its drivers'
status every 10 ms, every command it takes recorded. Used by ``test_vehicle_chain.py`` (three
nodes) and ``test_vehicle_computer.py`` (one loop).
"""
import json
import os
import signal
import threading

GUARD_S = 300.0
SAFE_A = 0.5
CORNERS = ('fl', 'fr', 'rl', 'rr')


def model_files(tmp_path, invalid=()):
    """Return the four shipped records' paths; those of ``invalid`` copied marked invalid."""
    from conftest import REPO
    files = []
    for c in CORNERS:
        src = REPO / 'src' / 'semi_active_control' / 'config' / 'models' / f'{c}.json'
        if c in invalid:
            dst = tmp_path / f'{c}_failed.json'
            dst.write_text(json.dumps(dict(json.loads(src.read_text()), valid=False)))
            files.append(str(dst))
        else:
            files.append(str(src))
    return files


class Car:
    """The car's side of the bus in this process: sensor cluster and drivers, frames recorded."""

    def __init__(self, channel, driver_safe_a=SAFE_A):
        from mr_damper_can.bus import make_bus
        from mr_damper_can.driver_sim import SimulatedEcu
        self.lock = threading.Lock()
        self.commands = []                 # (index, corner, current, failsafe bit, cycle)
        self.bus = make_bus('udp_loopback', channel)
        self.ecu = SimulatedEcu(self.bus, CORNERS, safe_current_a=driver_safe_a,
                                command_timeout_s=0.05, status_period_s=0.01,
                                sensor_period_s=0.002, on_command=self._on_command)
        self.ecu.start()

    def _on_command(self, corner, current, counter, failsafe, t):
        # (the ECU's reader thread calls this right after taking the frame: the sensor cycle
        # the frame answers, 0 for a safe frame of no cycle, is the ECU's last one)
        cycle = self.ecu.last_sensor_cycle
        with self.lock:
            self.commands.append((len(self.commands), corner, current, failsafe, cycle))

    def taken(self):
        """Return the commands taken so far."""
        with self.lock:
            return list(self.commands)

    def close(self):
        self.ecu.stop()
        self.bus.shutdown()


def command_frames(commands):
    """Group per-corner commands into frames: corner -> (current, bit), and ``cycle``."""
    frames, cur = [], {}
    for _, corner, current, bit, cycle in commands:
        cur[corner] = (current, bit)
        if corner == CORNERS[-1]:
            frames.append(dict(cur, cycle=cycle))
            cur = {}
    return frames


def all_safe(frame):
    """Return whether every corner of ``frame`` is on the safe current with its bit set."""
    return all(frame[c] == (SAFE_A, 1) for c in CORNERS)


def safe_of_no_cycle(frame):
    """
    Return whether ``frame`` is a safe frame answering no sensor cycle (``SENSOR_CYCLE`` 0).

    Deactivation sends one; so does the bridge while inactive. A frame made safe on its way
    (the bridge lost a driver's status for ``rx_timeout_s``, as on a starved machine) still
    carries the cycle it answers (0 only once in 256 cycles).
    """
    return all_safe(frame) and frame['cycle'] == 0


def normal_but_rr(frame):
    """Return whether ``frame``'s corners but rr (the invalid record's) are on the law."""
    return all(frame[c][1] == 0 for c in CORNERS[:3])


def chain_up(diag, car, frames=40):
    """Return a check: the manager says the chain is up and ``frames`` normal frames were taken."""
    def up():
        return (diag.values('lifecycle_manager').get('up') is True
                and sum(map(normal_but_rr, command_frames(car.taken()))) >= frames)
    return up


def change_state(lis, node, transition):
    """Call ``<node>/change_state``; return its ``success``."""
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState
    ids = {'configure': Transition.TRANSITION_CONFIGURE,
           'activate': Transition.TRANSITION_ACTIVATE,
           'deactivate': Transition.TRANSITION_DEACTIVATE}
    client = lis.node.create_client(ChangeState, f'{node}/change_state')
    assert client.wait_for_service(timeout_sec=GUARD_S), f'{node}: no change_state service'
    req = ChangeState.Request()
    req.transition.id = ids[transition]
    future = client.call_async(req)
    assert lis.wait_for(future.done, GUARD_S), f'{node}: {transition} not answered'
    lis.node.destroy_client(client)
    return future.result().success


def bus_channel(offset):
    """Return a udp_loopback channel of this test's own (its domain, ``offset``)."""
    return f'239.74.163.2:{44000 + offset + int(os.environ["ROS_DOMAIN_ID"])}'


def drivers_time_out_while_stopped(lis, car, proc, drivers_safe_a):
    """
    Stop ``proc`` (SIGSTOP) until every driver counted a command timeout, then let it go on.

    Asserts the drivers fell back on their own safe current (nothing was sent in the stopped
    process's name); returns the number of commands taken when it was let go on.
    """
    timeouts0 = dict(car.ecu.status()['corners'])
    proc.send_signal(signal.SIGSTOP)
    try:
        assert lis.wait_for(lambda: all(
            car.ecu.status()['corners'][c]['command_timeouts']
            > timeouts0[c]['command_timeouts'] for c in CORNERS), GUARD_S)
        assert car.ecu.drive_targets() == [drivers_safe_a] * 4      # the drivers' own
        return len(car.taken())
    finally:
        proc.send_signal(signal.SIGCONT)
