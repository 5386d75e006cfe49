"""
A simulated damper current driver and chassis sensor cluster on the CAN bus (ROS-free).

:class:`SimulatedEcu` plays the other end of the bridge: it takes ``DAMPER_CMD_<C>`` frames
(checksum and rolling counter checked, counted per corner), drives each coil current towards
its command with a first-order lag (time constant ``tau_s``, exact discretisation), falls back
to its own ``safe_current_a`` when no valid command came for ``command_timeout_s`` (fault bit
``FLT_CMD_TIMEOUT``), and sends ``DAMPER_STATUS_<C>`` every ``status_period_s`` and the three
``CHASSIS_*`` sensor frames every ``sensor_period_s``. Sensor values are those last given to
:meth:`SimulatedEcu.set_sensors` (e.g. from a simulated car), else a synthetic ride: sines of
known amplitude and frequency per corner (:func:`synthetic_sensors`). A vehicle computer's
``DAMPER_CMD_ALL`` frame commands every channel at once (one counter and checksum for the
frame; the sensor cycle it answers is kept, ``last_sensor_cycle``).

Faults are injected on request (:meth:`SimulatedEcu.inject`): driver faults (``open_load``,
``short``, ``overcurrent``, ``overtemp``, ``undervoltage``; the channel switches off, reports
state FAULT with its fault bit, until cleared with ``none``) and bus faults of its next frame
(``bad_checksum``, ``bad_counter``, ``unknown_id``, ``error_frame``, ``bus_off``) or of its
status for ``silence_s`` seconds (``silent``).
"""
import math
import threading
import time

import can

from mr_damper_can.codec import (CAN_ERR_BUSOFF, command_name, CORNERS, DRV_FAULT,
                                 DRV_FAILSAFE, DRV_NORMAL, FAULT_SIGNALS, FrameCodec,
                                 HARDWARE_FAULTS, SENSOR_FRAMES, status_name, VEHICLE_COMMAND)
from mr_damper_common.health import ERROR, Rising, WARN, worst
from mr_damper_common.scheduling import fifo_on_first_call

#: Driver faults that :meth:`SimulatedEcu.inject` can set (persistent until ``none``).
DRIVER_FAULTS = HARDWARE_FAULTS
#: Bus faults injected into the next frame(s) of a corner.
BUS_FAULTS = ('bad_checksum', 'bad_counter', 'unknown_id', 'error_frame', 'bus_off', 'silent')
#: Id of the frame sent by ``unknown_id`` (not in the DBC).
UNKNOWN_ID = 0x7E5


def synthetic_sensors(t, corner):
    """
    Synthetic chassis sensor values of ``corner`` at time ``t`` [s]: known sines.

    Body acceleration 2 m/s^2 at 1.5 Hz, wheel acceleration 30 m/s^2 at 12 Hz, suspension
    position 20 mm at 1.5 Hz; each corner shifted by a quarter period more than the last.

    Returns
    -------
    dict
        ``{'body_accel': m/s^2, 'wheel_accel': m/s^2, 'susp_pos': m}``.

    """
    phase = 0.5 * math.pi * CORNERS.index(corner)
    return {'body_accel': 2.0 * math.sin(2 * math.pi * 1.5 * t + phase),
            'wheel_accel': 30.0 * math.sin(2 * math.pi * 12.0 * t + phase),
            'susp_pos': 0.02 * math.sin(2 * math.pi * 1.5 * t + phase)}


class _Channel:
    """One driver channel (corner)."""

    def __init__(self):
        self.target_a = None          # last valid command [A] (None: none yet)
        self.current_a = 0.0          # coil current [A]
        self.last_command_t = None
        self.failsafe_bit = 0
        self.fault = None             # injected driver fault
        self.received = 0             # valid command frames
        self.timeouts = 0             # entries into the command timeout after a command
        self._timed_out = False
        self.bad_checksum = 0
        self.counter_jumps = 0
        self.frames_missed = 0
        self.repeated = 0
        self.invalid_since_status = False
        self.once = []                # bus faults for the next status frame
        self.silent_until = -math.inf
        self.last_counter = None


class SimulatedEcu:
    """
    Simulated damper driver (four channels) and sensor cluster (see the module docstring).

    Parameters
    ----------
    bus : can.BusABC or None
        The bus (None: frames collected in :attr:`sent`, for tests).
    corners : sequence of str
        Driver channels present.
    tau_s : float
        Coil current time constant [s] (> 0).
    safe_current_a : float
        The driver's own current without a valid command [A].
    command_timeout_s : float
        No valid command for this long -> ``safe_current_a`` and ``FLT_CMD_TIMEOUT`` [s].
    status_period_s, sensor_period_s : float
        Periods of the status and sensor frames [s] (the DBC's cycle times: 2 ms).
    sensors : bool
        Send the sensor cluster's frames.
    on_command : callable, optional
        ``on_command(corner, current_a, counter, failsafe, t)`` for each valid command frame.
    clock : callable
        Monotonic time [s].

    """

    def __init__(self, bus, corners=CORNERS, *, tau_s=0.01, safe_current_a=0.0,
                 command_timeout_s=0.05, status_period_s=0.002, sensor_period_s=0.002,
                 sensors=True, db=None, on_command=None, clock=time.monotonic):
        for name, value in (('tau_s', tau_s), ('command_timeout_s', command_timeout_s),
                            ('status_period_s', status_period_s),
                            ('sensor_period_s', sensor_period_s)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'`{name}` must be positive, got {value}')
        self.codec = FrameCodec(db)
        self.corners = tuple(corners)
        self.bus = bus
        self.tau_s = float(tau_s)
        self.safe_current_a = float(safe_current_a)
        self.command_timeout_s = float(command_timeout_s)
        self.status_period_s = float(status_period_s)
        self.sensor_period_s = float(sensor_period_s)
        self.sensors = bool(sensors)
        self.on_command = on_command
        self.clock = clock
        self.lock = threading.RLock()
        self.ch = {c: _Channel() for c in self.corners}
        self._cmd_ids = {self.codec.message(command_name(c)).frame_id: c for c in self.corners}
        self._all_id = self.codec.message(VEHICLE_COMMAND).frame_id
        self.all_frames = 0           # valid DAMPER_CMD_ALL frames
        self.last_sensor_cycle = None
        self._sensor_values = {}
        # per sensor frame: (corner, quantity, signal name, DBC minimum, maximum) of each signal
        self._sensor_signals = {
            name: [(corner, quantity, sig.name, sig.minimum, sig.maximum)
                   for corner in CORNERS
                   for sig in [self.codec.message(name).get_signal_by_name(
                       f'{prefix}_{corner.upper()}')]]
            for name, (quantity, prefix) in SENSOR_FRAMES.items()}
        self.sent = []
        self.frames_sent = 0
        self.send_failed = 0
        self.other_frames = 0
        self._next_status = None
        self._next_sensor = None
        self._thread = None
        self._notifier = None
        self._reader = None           # the reader's FifoOnFirstCall (reader_priority > 0)
        self._stop = threading.Event()
        self.t0 = self._t = clock()

    # --- commands in ---------------------------------------------------------------------------
    def on_frame(self, msg, now=None):
        """Take one received frame (the Notifier's listener); commands of its corners only."""
        now = self.clock() if now is None else now
        if msg.arbitration_id == self._all_id and not msg.is_error_frame:
            corners, suffix = self.corners, '_{}'
        else:
            corner = self._cmd_ids.get(msg.arbitration_id)
            if corner is None or msg.is_error_frame:
                self.other_frames += 1
                return
            corners, suffix = (corner,), ''
        done = []
        with self.lock:
            dec = self.codec.decode(msg.arbitration_id, msg.data)
            for corner in corners:
                end = suffix.format(corner.upper())
                if self._take(self.ch[corner], dec, f'CMD_CURRENT{end}', f'CMD_FAILSAFE{end}',
                              now):
                    ch = self.ch[corner]
                    done.append((corner, ch.target_a, int(dec.values['COUNTER']),
                                 ch.failsafe_bit))
            if suffix and dec.problem is None and dec.counter_jump >= 0:
                self.all_frames += 1
                self.last_sensor_cycle = int(dec.values['SENSOR_CYCLE'])
        if self.on_command is not None:
            for corner, target, counter, failsafe in done:
                self.on_command(corner, target, counter, failsafe, now)

    @staticmethod
    def _take(ch, dec, current, failsafe, now):
        """Check a decoded command frame for one channel; True when its command was taken."""
        if dec.problem is not None:
            ch.bad_checksum += int(dec.problem == 'bad_checksum')
            ch.invalid_since_status = True
            return False
        if dec.counter_jump > 0:
            ch.counter_jumps += 1
            ch.frames_missed += dec.counter_jump
            ch.invalid_since_status = True
        elif dec.counter_jump < 0:
            ch.repeated += 1
            ch.invalid_since_status = True
            return False                 # a repeated counter: the frame is stale
        ch.received += 1
        ch.target_a = float(dec.values[current])
        ch.failsafe_bit = int(dec.values[failsafe])
        ch.last_command_t = now
        return True

    # --- faults --------------------------------------------------------------------------------
    def inject(self, corner, fault, silence_s=0.2):
        """
        Inject ``fault`` on ``corner`` (see the module docstring); ``'none'`` clears a fault.

        Raises
        ------
        ValueError
            Unknown corner or fault (the message lists the known ones).

        """
        if corner not in self.ch:
            raise ValueError(f'unknown corner {corner!r} (have {self.corners})')
        with self.lock:
            ch = self.ch[corner]
            if fault == 'none':
                ch.fault = None
            elif fault in DRIVER_FAULTS:
                ch.fault = fault
            elif fault == 'silent':
                ch.silent_until = self.clock() + float(silence_s)
            elif fault in BUS_FAULTS:
                ch.once.append(fault)
            else:
                raise ValueError(f'unknown fault {fault!r}: one of none, '
                                 f'{", ".join(DRIVER_FAULTS + BUS_FAULTS)}')

    # --- the ECU's cycle -----------------------------------------------------------------------
    def set_sensors(self, corner, body_accel, wheel_accel, susp_pos):
        """Give the sensor cluster the values of ``corner`` (SI) instead of the synthetic ones."""
        with self.lock:
            self._sensor_values[corner] = {'body_accel': body_accel,
                                           'wheel_accel': wheel_accel, 'susp_pos': susp_pos}

    def _target(self, ch, now):
        """Return the current channel ``ch`` drives its coil to at ``now`` [A]; count timeouts."""
        if ch.fault is not None:
            return 0.0                    # the channel is switched off
        timed_out = ch.last_command_t is not None and now - ch.last_command_t > \
            self.command_timeout_s
        if timed_out and not ch._timed_out:
            ch.timeouts += 1
        ch._timed_out = timed_out
        if ch.last_command_t is None or timed_out:
            return self.safe_current_a
        return ch.target_a

    def _advance(self, now):
        dt = max(now - self._t, 0.0)
        self._t = now
        decay = 1.0 - math.exp(-dt / self.tau_s)
        for ch in self.ch.values():
            ch.current_a += decay * (self._target(ch, now) - ch.current_a)

    def commanded(self, now=None):
        """Return True when every channel has a fresh command without its fail-safe bit."""
        now = self.clock() if now is None else now
        with self.lock:
            return all(ch.fault is None and ch.last_command_t is not None
                       and now - ch.last_command_t <= self.command_timeout_s
                       and not ch.failsafe_bit for ch in self.ch.values())

    def drive_targets(self, now=None):
        """
        Return each channel's coil current set point now [A] (``corners`` order).

        The command in force, the driver's own safe current once no valid command came for
        ``command_timeout_s`` (or none yet), 0 A with a driver fault: what a simulated car's
        damper plants take as their coil command (the plants have their coil lag).
        """
        now = self.clock() if now is None else now
        with self.lock:
            return [self._target(self.ch[c], now) for c in self.corners]

    def _status_values(self, corner, now):
        ch = self.ch[corner]
        timed_out = ch.last_command_t is None or now - ch.last_command_t > self.command_timeout_s
        values = {sig: 0 for sig in FAULT_SIGNALS}
        if ch.fault is not None:
            values[f'FLT_{ch.fault.upper()}'] = 1
            state = DRV_FAULT
        elif timed_out or ch.failsafe_bit:
            state = DRV_FAILSAFE
        else:
            state = DRV_NORMAL
        values['FLT_CMD_TIMEOUT'] = int(timed_out and ch.last_command_t is not None)
        values['FLT_CMD_INVALID'] = int(ch.invalid_since_status)
        ch.invalid_since_status = False
        values['MEAS_CURRENT'] = min(max(ch.current_a, 0.0), 4.095)
        values['DRV_STATE'] = state
        return values

    def _send(self, frame_id, data, *, error=False):
        msg = can.Message(arbitration_id=frame_id, data=data, is_extended_id=False,
                          is_error_frame=error)
        try:
            if self.bus is None:
                self.sent.append(msg)
            else:
                self.bus.send(msg)
            self.frames_sent += 1
        except can.CanError:
            self.send_failed += 1

    def _send_status(self, corner, now):
        ch = self.ch[corner]
        if now < ch.silent_until:
            return
        name = status_name(corner)
        values = self._status_values(corner, now)
        faults, ch.once = ch.once, []
        if 'bad_counter' in faults:       # skip two counter values
            self.codec.encode(name, values)
            self.codec.encode(name, values)
        # every value is built within its DBC range (flags, a state, the clamped current)
        frame_id, data = self.codec.encode(name, values, strict=False)
        if 'bad_checksum' in faults:
            data = data[:-1] + bytes([data[-1] ^ 0x5A])
        self._send(frame_id, data)
        if 'unknown_id' in faults:
            self._send(UNKNOWN_ID, bytes(8))
        if 'error_frame' in faults:
            self._send(0x004, bytes(8), error=True)      # CAN_ERR_PROT: a protocol error
        if 'bus_off' in faults:
            self._send(CAN_ERR_BUSOFF, bytes(8), error=True)

    def _send_sensors(self, now):
        t = now - self.t0
        given = {corner: self._sensor_values.get(corner) or synthetic_sensors(t, corner)
                 for corner in CORNERS}
        for name, signals in self._sensor_signals.items():
            # each reading saturates at its signal's DBC range, as a sensor's output does: the
            # encoding then needs no range check of its own (strict=False, half its time)
            values = {sig: min(max(float(given[corner][quantity]), lo), hi)
                      for corner, quantity, sig, lo, hi in signals}
            self._send(*self.codec.encode(name, values, strict=False))

    def step(self, now=None):
        """Advance the coils to ``now`` and send the frames that are due; return frames sent."""
        now = self.clock() if now is None else now
        with self.lock:
            before = self.frames_sent
            self._advance(now)
            if self._next_status is None:
                self._next_status = self._next_sensor = now
            if now >= self._next_status:
                for corner in self.corners:
                    self._send_status(corner, now)
                self._next_status = max(self._next_status + self.status_period_s, now)
            if self.sensors and now >= self._next_sensor:
                self._send_sensors(now)
                self._next_sensor = max(self._next_sensor + self.sensor_period_s, now)
            return self.frames_sent - before

    def run(self, stop=None):
        """Step on the status / sensor schedule until :meth:`stop` (or ``stop()`` is true)."""
        period = min(self.status_period_s, self.sensor_period_s)
        while not self._stop.is_set() and not (stop and stop()):
            self.step()
            due = min(self._next_status, self._next_sensor if self.sensors else math.inf)
            self._stop.wait(max(min(due - self.clock(), period), 0.0))

    def start(self, cycle=True, reader_priority=0):
        """
        Read the bus (Notifier) and run the ECU cycle in a thread of its own.

        With ``cycle`` False only the reader starts: the caller runs the cycle with
        :meth:`step` (a simulated car steps its ECU with its own time). ``reader_priority`` > 0:
        the reader thread puts itself under SCHED_FIFO at that priority on its first frame
        (needs CAP_SYS_NICE; a refusal is in the status: ``reader_priority_error``).
        """
        if self.bus is not None and self._notifier is None:
            listener = self.on_frame
            if reader_priority > 0:
                # a simulated car's bus reader shares the GIL with its real-time control
                # thread: at normal scheduling, preempted by any other process while it holds
                # the GIL, it would hold that thread back (priority inversion)
                listener = self._reader = fifo_on_first_call(self.on_frame, reader_priority)
            self._notifier = can.Notifier(self.bus, [listener], timeout=0.1)
        if cycle and self._thread is None:
            self._stop.clear()
            self._thread = threading.Thread(target=self.run, name='can_ecu', daemon=True)
            self._thread.start()

    def stop(self, drain=False):
        """
        Stop the cycle thread and the reader.

        With ``drain``, the frames still queued on the bus are taken (:meth:`on_frame`) after
        the reader stopped, so the counts hold every frame sent before the stop.
        """
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._notifier is not None:
            self._notifier.stop()
            self._notifier = None
        while drain and self.bus is not None:
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                break
            self.on_frame(msg)

    def status(self):
        """Return the status dict: per corner counts, command, current, fault; frame counts."""
        with self.lock:
            corners = {c: {'received': ch.received, 'command_timeouts': ch.timeouts,
                           'timed_out': ch._timed_out or ch.last_command_t is None,
                           'bad_checksum': ch.bad_checksum,
                           'counter_jumps': ch.counter_jumps, 'frames_missed': ch.frames_missed,
                           'repeated': ch.repeated,
                           'target_a': math.nan if ch.target_a is None else ch.target_a,
                           'current_a': ch.current_a, 'failsafe_bit': ch.failsafe_bit,
                           'fault': ch.fault or ''}
                       for c, ch in self.ch.items()}
            return {'corners': corners, 'frames_sent': self.frames_sent,
                    'all_frames': self.all_frames, 'last_sensor_cycle': self.last_sensor_cycle,
                    'send_failed': self.send_failed, 'other_frames': self.other_frames,
                    'tau_s': self.tau_s, 'safe_current_a': self.safe_current_a,
                    'reader_priority_error': getattr(self._reader, 'error', None)}


class EcuHealth:
    """
    Status rules of the simulated ECU.

    WARN on bad command frames since the last status, ERROR while a driver fault is injected.
    """

    def __init__(self):
        self._rising = Rising()

    def __call__(self, status):
        """Return the :class:`~mr_damper_common.health.Health` of :meth:`SimulatedEcu.status`."""
        problems = []
        for corner, cs in status['corners'].items():
            if cs['fault']:
                problems.append((ERROR, f'{corner}: {cs["fault"]} injected'))
            bad = {k: self._rising.rise(f'{corner}.{k}', cs[k])
                   for k in ('bad_checksum', 'counter_jumps', 'repeated')}
            bad = {k: v for k, v in bad.items() if v}
            if bad:
                problems.append((WARN, f'{corner}: bad command frames since the last status: '
                                 + ', '.join(f'{v} {k}' for k, v in sorted(bad.items()))))
        return worst(problems, status)
