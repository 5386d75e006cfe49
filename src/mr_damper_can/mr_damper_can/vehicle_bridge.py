"""
The vehicle computer's CAN bridge without ROS: chassis sensor cycles in, one command frame out.

:class:`VehicleBridge` is :class:`~mr_damper_can.bridge.CanBridge` (frame checks, fault
counters, driver status, per-corner fail-safe for bus-off, driver faults and a silent driver)
on a full car's bus (``codec.bus_layout('vehicle')``):

- **sensor cycles in**: the sensor cluster sends ``CHASSIS_BODY_ACCEL``, ``_WHEEL_ACCEL`` and
  ``_SUSP_POS`` once per cycle, in that order, their rolling counters in step. The position
  frame ends a cycle: the cycle gets a number (+1 per cycle, the counter's jumps added, so a
  cycle lost on the bus leaves a gap the estimator predicts through), the values of the two
  other frames if their counter is the cycle's (else NaN, flagged missing), the currents sent
  and measured, and the time the frame was received on the bus (its python-can timestamp: the
  kernel's, on the vehicle computer's clock). :attr:`on_cycle` gets it (the reader thread);
- **commands out**: :meth:`VehicleBridge.command_all` puts the four currents of one command
  into one ``DAMPER_CMD_ALL`` frame at once (no queue), each corner clamped to the DBC range
  (a non-finite one refused: that corner's safe current), a corner the bridge itself holds in
  fail-safe (bus off, driver fault, driver silent) on the safe current, every fail-safe corner
  with its ``CMD_FAILSAFE`` bit, and the low byte of the sensor cycle answered in
  ``SENSOR_CYCLE``. From that cycle's bus time to the frame's, every answer's latency is
  counted (:class:`~mr_damper_common.latency.LatencyHistogram`; on time when within
  ``cycle_s``), and cycles never answered are counted too;
- **the reader's duty**: the CPU time the reader thread spends per sensor cycle (from one
  cycle's last frame to the next one's: receiving and decoding the frames, and whatever
  :attr:`on_cycle` runs, the whole control loop in ``vehicle_computer_node``) is counted
  too, :attr:`VehicleBridge.reader_cpu`: the share of a core the bus's cycle needs on the
  computer at hand, which sets how much of each period is left for the rest;
- **managed**: while not :attr:`active` (configured, or deactivated) the bridge forwards no
  command and sends the safe current with every fail-safe bit each ``safe_period_s``
  (:meth:`tick`, well inside the drivers' own command timeout;
  :meth:`deactivate` sends it at once, so the drivers get the safe current within one cycle,
  not the last command). While active it only forwards: a controller that falls silent gets
  nothing re-sent in its name, and the drivers fall back on their own command timeout.

Threads as in :class:`CanBridge`: :meth:`command_all`, :meth:`tick` and the lifecycle calls
from the caller's threads, :meth:`on_frame` from python-can's ``Notifier``; one lock.
"""
from dataclasses import dataclass
import math
import time

import numpy as np

from mr_damper_can.bridge import CanBridge
from mr_damper_can.codec import CORNERS, SENSOR_FRAMES, VEHICLE_COMMAND
from mr_damper_common.latency import LatencyHistogram

#: Bits of :attr:`ChassisCycle.missing` (as ``ChassisSensors.MISSING_*``).
MISSING_BODY_ACCEL, MISSING_WHEEL_ACCEL, MISSING_SUSP_POS = 1, 2, 4
#: Sensor cycles whose bus time is kept for the latency of their answer.
RING = 1024
#: Per sensor frame's signal prefix, its four corners' signal names (``BODY_ACCEL_FL``, ...).
_SENSOR_SIGNALS = {prefix: tuple(f'{prefix}_{c.upper()}' for c in CORNERS)
                   for _, prefix in SENSOR_FRAMES.values()}
#: Per corner, the names of its current and fail-safe bit in ``DAMPER_CMD_ALL``.
_COMMAND_SIGNALS = tuple((f'CMD_CURRENT_{c.upper()}', f'CMD_FAILSAFE_{c.upper()}')
                         for c in CORNERS)


@dataclass
class ChassisCycle:
    """
    One sensor cycle of the chassis bus (SI; corners ``fl, fr, rl, rr``).

    Attributes
    ----------
    sequence : int
        Cycle number (+1 per cycle; gaps are cycles lost on the bus).
    t_bus : float
        When its last frame was received on the bus [s, wall clock, epoch].
    body_accel, wheel_accel : ndarray (4,)
        Vertical accelerations, gravity removed [m/s^2] (NaN: frame missing).
    susp_pos : ndarray (4,)
        Suspension travels [m].
    current_sent_a, current_measured_a : ndarray (4,)
        Last current sent to each driver, and each driver's measured current [A].
    missing : int
        Bits of the frames of this cycle that did not arrive.

    """

    sequence: int
    t_bus: float
    body_accel: np.ndarray
    wheel_accel: np.ndarray
    susp_pos: np.ndarray
    current_sent_a: np.ndarray
    current_measured_a: np.ndarray
    missing: int = 0


class VehicleBridge(CanBridge):
    """
    A full car's chassis bus: sensor cycles in, one command frame per cycle out (module doc).

    Parameters
    ----------
    bus : can.BusABC or None
        The bus (None: frames are only collected, :attr:`sent`).
    cycle_s : float
        Sensor and command cycle [s] (the deadline of an answer).
    safe_period_s : float
        Period of the safe frames while inactive [s].
    safe_current_a, rx_timeout_s, command_timeout_s, db, on_driver, clock
        As :class:`~mr_damper_can.bridge.CanBridge` (``command_timeout_s`` only reports a
        silent controller, ``command_timeout``; nothing is sent in its name).
    on_cycle : callable, optional
        ``on_cycle(ChassisCycle)`` per complete sensor cycle (the reader thread).
    wall : callable
        Wall clock [s, epoch] of the latencies (the clock of python-can's timestamps).
    cpu_clock : callable
        CPU time of the calling thread [s] (:attr:`reader_cpu`; ``time.thread_time``).

    Attributes
    ----------
    reader_cpu : LatencyHistogram
        Per sensor cycle, the CPU time [s] the thread that receives the frames spent since the
        cycle before (over several cycles when some were lost on the bus: shared equally).

    """

    def __init__(self, bus, *, cycle_s=0.002, safe_period_s=0.01, safe_current_a=0.5,
                 rx_timeout_s=0.05,
                 command_timeout_s=0.02, db=None, on_cycle=None, on_driver=None,
                 clock=time.monotonic, wall=time.time, cpu_clock=time.thread_time):
        if not (math.isfinite(cycle_s) and cycle_s > 0):
            raise ValueError(f'`cycle_s` must be > 0, got {cycle_s}')
        super().__init__(bus, CORNERS, safe_current_a=safe_current_a,
                         command_timeout_s=command_timeout_s, rx_timeout_s=rx_timeout_s,
                         resend_period_s=cycle_s, db=db, on_driver=on_driver, clock=clock)
        self.cycle_s = float(cycle_s)
        if not (math.isfinite(safe_period_s) and safe_period_s > 0):
            raise ValueError(f'`safe_period_s` must be > 0, got {safe_period_s}')
        self.safe_period_s = float(safe_period_s)
        self.on_cycle = on_cycle
        self.wall = wall
        self.active = False
        self._all = self.codec.message(VEHICLE_COMMAND)
        self._frames = {}
        self._last_pos = None
        self.cycle_seq = 0
        self._bus_t = np.full(RING, math.nan)
        self._bus_seq = np.full(RING, -1, dtype=np.int64)
        self._bus_active = np.zeros(RING, dtype=bool)
        self.latency = LatencyHistogram()
        self.cpu_clock = cpu_clock
        self.reader_cpu = LatencyHistogram()
        self._cpu_t = None
        self.counts = {'cycles': 0, 'cycles_active': 0, 'cycles_missing_frames': 0,
                       'answered': 0, 'answered_in_time': 0, 'answers_old': 0,
                       'answers_unknown_cycle': 0, 'answers_inactive_cycle': 0,
                       'commands_inactive': 0, 'command_frames': 0, 'safe_frames': 0}
        self._last_answered = 0
        self._last_active_seq = 0
        self._last_all_t = None

    # --- lifecycle -------------------------------------------------------------------------------
    def activate(self, now=None):
        """Forward commands from now on."""
        now = self.clock() if now is None else now
        with self.lock:
            self.active = True
            for c in self.corners:
                self._update_mode(c, now)

    def deactivate(self, now=None):
        """Stop forwarding and send the safe current on every corner at once; frames sent."""
        now = self.clock() if now is None else now
        with self.lock:
            self.active = False
            for c in self.corners:
                self._update_mode(c, now)
            return int(self._send_safe(now))

    def _reason(self, corner, now):
        reason = super()._reason(corner, now)
        if reason in ('bus_off', 'driver_fault', 'driver_timeout') or self.active:
            return reason
        return 'inactive'

    # --- sensor cycles ---------------------------------------------------------------------------
    def _sensor_frame(self, dec, msg, now):
        quantity, prefix = SENSOR_FRAMES[dec.name]
        counter = int(dec.values['COUNTER'])
        names = _SENSOR_SIGNALS[prefix]
        values = np.array([float(dec.values[n]) for n in names])
        for k, c in enumerate(CORNERS):
            self._sensors[c][quantity] = values[k]
        self._frames[quantity] = (counter, values)
        if quantity != 'susp_pos':
            return None, ()
        jump = 0 if self._last_pos is None else (counter - self._last_pos - 1) % 16
        self._last_pos = counter
        self.cycle_seq += jump + 1
        seq = self.cycle_seq
        cpu = self.cpu_clock()
        if self._cpu_t is not None:
            self.reader_cpu.add((cpu - self._cpu_t) / (jump + 1))
        self._cpu_t = cpu
        missing = 0
        out = {}
        for q, bit in (('body_accel', MISSING_BODY_ACCEL), ('wheel_accel', MISSING_WHEEL_ACCEL)):
            got = self._frames.pop(q, None)
            if got is None or got[0] != counter:
                missing |= bit
                out[q] = np.full(4, math.nan)
            else:
                out[q] = got[1]
        self._frames.pop('susp_pos', None)
        stamp = float(getattr(msg, 'timestamp', 0.0) or 0.0)
        t_bus = stamp if stamp > 0 else self.wall()
        self._bus_t[seq % RING] = t_bus
        self._bus_seq[seq % RING] = seq
        self._bus_active[seq % RING] = self.active
        if self.active:
            self._last_active_seq = seq
        self.counts['cycles'] += 1
        self.counts['cycles_active'] += int(self.active)
        self.counts['cycles_missing_frames'] += int(missing != 0)
        sent = np.array([self.state[c].sent_a for c in CORNERS], dtype=float)
        measured = np.array([self.state[c].driver.current_a if self.state[c].driver else
                             math.nan for c in CORNERS])
        cycle = ChassisCycle(seq, t_bus, out['body_accel'], out['wheel_accel'], values, sent,
                             measured, missing)
        return self.on_cycle, (cycle,)

    # --- commands --------------------------------------------------------------------------------
    def command_all(self, currents_a, failsafe, cycle, now=None):
        """
        Send one command of the four corners as one frame at once.

        Parameters
        ----------
        currents_a : sequence of 4 float
            Coil currents [A] (clamped to the DBC range; non-finite: refused, safe current).
        failsafe : sequence of 4 bool
            The controller's fail-safe per corner (sets its ``CMD_FAILSAFE`` bit).
        cycle : int
            The sensor cycle answered (0: none).
        now : float, optional
            Monotonic time [s].

        Returns
        -------
        bool or None
            True when sent, False when the bus refused it, None when inactive (not sent,
            counted ``commands_inactive``).

        """
        now = self.clock() if now is None else now
        with self.lock:
            if not self.active:
                self.counts['commands_inactive'] += 1
                return None
            values, flags = [], []
            for k, c in enumerate(CORNERS):
                st = self.state[c]
                value, _ = self.limiter.apply(currents_a[k])
                st.commands += 1
                refused = value is None
                if not refused:
                    st.command_a = value
                    st.last_command_t = now
                self._update_mode(c, now)
                safe = refused or st.mode != 'normal' or bool(failsafe[k])
                values.append(self.safe_current_a if refused or st.mode != 'normal'
                              else value)
                flags.append(int(safe))
            sent = self._send_all(values, flags, int(cycle), now)
            if sent:
                self.counts['command_frames'] += 1
                self._answered(int(cycle))
            return sent

    def _answered(self, cycle):
        """Count the latency of the answer to ``cycle`` (lock held)."""
        if cycle <= 0:
            return
        if cycle <= self._last_answered:
            self.counts['answers_old'] += 1
            return
        k = cycle % RING
        if self._bus_seq[k] != cycle:
            self.counts['answers_unknown_cycle'] += 1
            return
        self._last_answered = cycle
        if not self._bus_active[k]:
            self.counts['answers_inactive_cycle'] += 1
            return
        latency = self.wall() - self._bus_t[k]
        self.latency.add(latency)
        self.counts['answered'] += 1
        self.counts['answered_in_time'] += int(latency <= self.cycle_s)

    def _send_all(self, values, flags, cycle, now):
        signals = {'SENSOR_CYCLE': cycle & 0xFF}
        for (current, failsafe), v, f in zip(_COMMAND_SIGNALS, values, flags):
            signals[current] = v
            signals[failsafe] = f
        # every value is inside its range: the limiter clamped the currents, the bits are 0 / 1
        frame_id, data = self.codec.encode(VEHICLE_COMMAND, signals, strict=False)
        self._last_all_t = now
        if not self._transmit(frame_id, data):
            return False
        for c, v in zip(CORNERS, values):
            st = self.state[c]
            st.sent_a = v
            st.frames_sent += 1
            st.last_sent_t = now
        return True

    def _send_safe(self, now):
        self.counts['safe_frames'] += 1
        return self._send_all([self.safe_current_a] * 4, [1] * 4, 0, now)

    def tick(self, now=None):
        """
        Check the timeouts; while inactive send the safe frame each ``safe_period_s``.

        Call it at least every ``safe_period_s`` (a timer of half that). Returns the frames
        sent.
        """
        now = self.clock() if now is None else now
        with self.lock:
            self._check_rx_timeouts(now)
            for c in self.corners:
                self._update_mode(c, now)
            if self.active or (self._last_all_t is not None
                               and now - self._last_all_t < 0.99 * self.safe_period_s):
                return 0
            return int(self._send_safe(now))

    # --- status ----------------------------------------------------------------------------------
    def status(self, now=None):
        """
        Return the bridge's status with the vehicle's figures (``/diagnostics`` values).

        Adds to :meth:`CanBridge.status` ``active``, ``cycle_s``, ``cycles`` (counts: cycles
        received, while active, with missing frames; answers, on time, old, of unknown cycles,
        of cycles received while inactive (no latency, not in the fraction); command and safe
        frames; commands refused while inactive), ``control_cycles`` (cycles received while
        active, the newest left out while unanswered: in flight), ``unanswered`` (of those
        no command answered), ``answered_fraction`` (answered on time / ``control_cycles``: at
        most 1), ``latency`` (bus to bus: the sensor cycle's frame to the command frame
        answering it, :class:`LatencyHistogram` summary), ``reader_cpu_s``
        (:attr:`reader_cpu`'s summary) and ``frames_lost`` (frames the counters show missing).
        """
        st = super().status(now)
        with self.lock:
            counts = dict(self.counts)
            in_flight = int(self._last_active_seq > self._last_answered)
            done = counts['cycles_active'] - in_flight
            fraction = counts['answered_in_time'] / done if done else math.nan
            st.update(active=self.active, cycle_s=self.cycle_s, cycles=counts,
                      control_cycles=done, unanswered=max(done - counts['answered'], 0),
                      answered_fraction=fraction,
                      latency=self.latency.summary(),
                      reader_cpu_s=self.reader_cpu.summary(),
                      frames_lost=int(self.faults['frames_missed']))
        return st
