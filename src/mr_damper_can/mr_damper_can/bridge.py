"""
ROS-free core of the CAN bridge: current commands out, driver status and sensors in, faults.

:class:`CanBridge` turns each coil current command of a corner into one ``DAMPER_CMD_<C>``
frame (clamped to the DBC range and quantised by cantools; a NaN is refused, the previous
command stays; all counted), and checks and decodes every received frame (checksum, rolling
counter, length, unknown ids, error frames, bus-off), counting each fault. A corner is in
fail-safe - the bridge sends its ``safe_current_a`` with ``CMD_FAILSAFE`` set instead of the
controller's command - while its driver reports a hardware fault (or state FAULT), while its
driver status is missing for ``rx_timeout_s``, when no command came for ``command_timeout_s``
(or none yet), and while the bus is off. :meth:`CanBridge.tick`, called periodically, checks
the timeouts and re-sends the command in force of every corner that sent nothing for
``resend_period_s`` (so the driver, which has a command timeout of its own, hears from the
bridge also in fail-safe).

Threads: :meth:`command` and :meth:`tick` from the caller's thread, :meth:`on_frame` from the
python-can ``Notifier`` thread (:meth:`start`); one lock guards the state. The decoded values
go to the ``on_driver`` / ``on_sensors`` callbacks, called in the receiving thread.
"""
from dataclasses import dataclass, field
import math
import threading
import time

import can

from mr_damper_can.codec import (command_name, CORNERS, DRV_FAULT, FAULT_SIGNALS, FrameCodec,
                                 HARDWARE_FAULTS, SENSOR_FRAMES, status_name)
from mr_damper_common.commands import CurrentCommandLimiter
from mr_damper_common.health import dropped_since, ERROR, OK, Rising, WARN, worst
from mr_damper_common.scheduling import fifo_on_first_call

#: The driver faults that put a corner on its safe current (a set: one test per call).
_HARDWARE_FAULTS = frozenset(HARDWARE_FAULTS)

#: Fault counters of the bridge (``faults.<name>`` in its status).
FAULTS = ('unknown_id', 'bad_length', 'bad_checksum', 'bad_counter', 'frames_missed',
          'repeated_frame', 'timeout', 'bus_off', 'error_frame', 'remote_frame', 'send_failed')


@dataclass
class DriverStatus:
    """One decoded ``DAMPER_STATUS_<C>``: measured current [A], state, active fault names."""

    corner: str
    current_a: float
    state: int
    faults: tuple
    t: float


@dataclass
class CornerState:
    """What the bridge knows and did for one corner."""

    command_a: float = math.nan        # last command accepted from the controller [A]
    sent_a: float = math.nan           # last current sent on the bus [A]
    last_command_t: float = None       # when the controller's last command came [s]
    last_sent_t: float = None          # when the last frame of this corner was sent [s]
    last_status_t: float = None        # when the last driver status came [s]
    driver: DriverStatus = None
    mode: str = 'failsafe'
    reason: str = 'no_command_yet'
    failsafe_entries: int = 0
    failsafe_s: float = 0.0
    commands: int = 0                  # controller commands received
    frames_sent: int = 0               # every DAMPER_CMD frame sent (commands and re-sends)
    resent: int = 0                    # frames sent by tick() (keep-alive / fail-safe)
    status_frames: int = 0
    driver_faults: dict = field(default_factory=dict)   # fault name -> rising edges
    _since: float = None


class CanBridge:
    """
    Bridge between a controller's coil current commands and the damper driver on a CAN bus.

    Parameters
    ----------
    bus : can.BusABC or None
        The bus (None: frames are only counted, for tests of the encoding; see ``sent``).
    corners : sequence of str
        Corners handled, a subset of :data:`~mr_damper_can.codec.CORNERS`.
    safe_current_a : float
        Current of a corner in fail-safe [A], inside the DBC command range (MR dampers are
        usually soft at 0 A; a system that is hard at 0 A needs its own safe value).
    command_timeout_s : float
        A corner with no command for this long goes to fail-safe [s].
    rx_timeout_s : float
        A cyclic frame (driver status, sensor frame) missing for this long is counted as a
        timeout, once per outage; a missing driver status puts its corner in fail-safe [s].
    resend_period_s : float
        :meth:`tick` re-sends a corner's current when nothing was sent for this long [s].
    db : cantools database, optional
        The DBC (default the packaged one).
    on_driver : callable, optional
        ``on_driver(DriverStatus)`` for each valid driver status frame.
    on_sensors : callable, optional
        ``on_sensors(quantity, {corner: value}, t)`` for each valid sensor frame
        (``body_accel`` [m/s^2], ``wheel_accel`` [m/s^2], ``susp_pos`` [m]).
    clock : callable
        Monotonic time [s].

    """

    def __init__(self, bus, corners=CORNERS, *, safe_current_a=0.0, command_timeout_s=0.05,
                 rx_timeout_s=0.05, resend_period_s=0.01, db=None, on_driver=None,
                 on_sensors=None, clock=time.monotonic):
        self.codec = FrameCodec(db)
        corners = tuple(corners)
        unknown = [c for c in corners if c not in CORNERS]
        if not corners or unknown or len(set(corners)) != len(corners):
            raise ValueError(f'`corners` must be distinct names of {CORNERS}, got {corners}')
        self.corners = corners
        lo, hi = self.codec.signal_range(command_name(corners[0]), 'CMD_CURRENT')
        self.limiter = CurrentCommandLimiter(lo, hi)
        safe = float(safe_current_a)
        if not lo <= safe <= hi:
            raise ValueError(f'`safe_current_a` must lie in the DBC command range '
                             f'[{lo:g}, {hi:g}] A, got {safe_current_a}')
        for name, value in (('command_timeout_s', command_timeout_s),
                            ('rx_timeout_s', rx_timeout_s),
                            ('resend_period_s', resend_period_s)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'`{name}` must be positive, got {value}')
        self.safe_current_a = safe
        self.command_timeout_s = float(command_timeout_s)
        self.rx_timeout_s = float(rx_timeout_s)
        self.resend_period_s = float(resend_period_s)
        self.bus = bus
        self.on_driver = on_driver
        self.on_sensors = on_sensors
        self.clock = clock
        self.lock = threading.RLock()
        self.state = {c: CornerState() for c in corners}
        self.faults = dict.fromkeys(FAULTS, 0)
        self.timeouts = {}            # message name -> outages
        self.frames_received = 0
        self.own_frames = 0
        self.log_errors = 0           # frames the log's writer refused (the last one's error)
        self.log_error = None
        self.frame_errors = 0         # frames whose handling raised (the last one's error)
        self.frame_error = None
        self.bus_off = False
        self.sent = []                # (frame_id, data) when bus is None
        self.started_t = clock()
        self._rx_last = {}
        self._rx_timed_out = set()
        own = {m.name for m in self.codec.db.messages if 'ROS_BRIDGE' in m.senders}
        self._own_ids = {self.codec.message(n).frame_id for n in own}
        self._status_ids = {self.codec.message(status_name(c)).frame_id: c for c in corners}
        self._cyclic_rx = [status_name(c) for c in corners] + list(SENSOR_FRAMES)
        self._notifier = None
        self._log = None
        self._reader = None           # the reader's FifoOnFirstCall (reader_priority > 0)
        self._sensors = {c: dict.fromkeys(('body_accel', 'wheel_accel', 'susp_pos'), math.nan)
                         for c in corners}
        for corner in corners:
            self.state[corner]._since = self.started_t
            self.state[corner].failsafe_entries = 1

    # --- sending -----------------------------------------------------------------------------
    def command(self, corner, current_a, now=None):
        """
        Take one coil current command of ``corner`` [A] and send its frame.

        Returns the limiter's outcome (``accepted``, ``clamped_low``, ``clamped_high``,
        ``refused_non_finite``: nothing is sent, the previous command stays in force).
        """
        now = self.clock() if now is None else now
        with self.lock:
            st = self.state[corner]
            value, outcome = self.limiter.apply(current_a)
            st.commands += 1
            if value is None:
                return outcome
            st.command_a = value
            st.last_command_t = now
            self._update_mode(corner, now)
            self._send(corner, now)
            return outcome

    def _current_in_force(self, st):
        return st.command_a if st.mode == 'normal' else self.safe_current_a

    def _send(self, corner, now, resend=False):
        st = self.state[corner]
        value = self._current_in_force(st)
        frame_id, data = self.codec.encode(command_name(corner), {
            'CMD_CURRENT': value, 'CMD_FAILSAFE': int(st.mode != 'normal')})
        st.last_sent_t = now
        if not self._transmit(frame_id, data):
            return False
        st.sent_a = value
        st.frames_sent += 1
        st.resent += int(resend)
        return True

    def _transmit(self, frame_id, data):
        """Put one frame on the bus (or into :attr:`sent`); False (counted) when refused."""
        try:
            if self.bus is None:
                self.sent.append((frame_id, data))
            else:
                msg = can.Message(arbitration_id=frame_id, data=data, is_extended_id=False,
                                  is_rx=False)
                self.bus.send(msg)
                if self._log is not None:     # the bus does not give our frames back
                    msg.timestamp = time.time()
                    self._log_frame(msg)
        except can.CanError:
            self.faults['send_failed'] += 1
            return False
        return True

    def _log_frame(self, msg):
        """Write ``msg`` to the frame log; a writer's error is counted, never raised."""
        with self.lock:
            try:
                self._log.on_message_received(msg)
            except Exception as exc:          # noqa: BLE001 - a log must not stop the bus
                self.log_errors += 1
                self.log_error = f'{type(exc).__name__}: {exc}'

    # --- receiving ---------------------------------------------------------------------------
    def on_frame(self, msg, now=None):
        """Check, decode and dispatch one received ``can.Message`` (the Notifier's listener)."""
        now = self.clock() if now is None else now
        with self.lock:
            self.frames_received += 1
            if msg.arbitration_id in self._own_ids and not msg.is_error_frame:
                self.own_frames += 1          # our own frames, looped back by the bus
                return None
            if self._log is not None:
                self._log_frame(msg)
            dec = self.codec.decode(msg.arbitration_id, msg.data,
                                    is_error_frame=msg.is_error_frame,
                                    is_remote_frame=msg.is_remote_frame)
            if dec.problem is not None:
                self.faults[dec.problem] += 1
                if dec.problem == 'bus_off' and not self.bus_off:
                    self.bus_off = True
                    for corner in self.corners:
                        self._update_mode(corner, now)
                return dec
            if self.bus_off:                  # a valid frame: the bus is back
                self.bus_off = False
            if dec.counter_jump > 0:
                self.faults['bad_counter'] += 1
                self.faults['frames_missed'] += dec.counter_jump
            elif dec.counter_jump < 0:
                self.faults['repeated_frame'] += 1
            self._rx_last[dec.name] = now
            self._rx_timed_out.discard(dec.name)
            corner = self._status_ids.get(msg.arbitration_id)
            if corner is not None:
                status = self._on_status(corner, dec.values, now)
                callback, args = self.on_driver, (status,)
            elif dec.name in SENSOR_FRAMES:
                callback, args = self._sensor_frame(dec, msg, now)
            else:
                return dec
        if callback is not None:
            callback(*args)
        return dec

    def _sensor_frame(self, dec, msg, now):
        """Keep a sensor frame's values; return the callback and its arguments (lock held)."""
        quantity, prefix = SENSOR_FRAMES[dec.name]
        values = {c: float(dec.values[f'{prefix}_{c.upper()}']) for c in self.corners}
        for corner, value in values.items():
            self._sensors[corner][quantity] = value
        return self.on_sensors, (quantity, values, now)

    def _on_status(self, corner, values, now):
        st = self.state[corner]
        faults = tuple(name for sig, name in FAULT_SIGNALS.items() if values[sig])
        before = set(st.driver.faults) if st.driver else set()
        for name in set(faults) - before:
            st.driver_faults[name] = st.driver_faults.get(name, 0) + 1
        st.driver = DriverStatus(corner, float(values['MEAS_CURRENT']),
                                 int(values['DRV_STATE']), faults, now)
        st.last_status_t = now
        st.status_frames += 1
        self._update_mode(corner, now)
        return st.driver

    # --- modes, timeouts ---------------------------------------------------------------------
    def _reason(self, corner, now):
        st = self.state[corner]
        if self.bus_off:
            return 'bus_off'
        if st.driver is not None and (not _HARDWARE_FAULTS.isdisjoint(st.driver.faults)
                                      or st.driver.state == DRV_FAULT):
            return 'driver_fault'
        last_status = self.started_t if st.last_status_t is None else st.last_status_t
        if now - last_status > self.rx_timeout_s:
            return 'driver_timeout'
        if st.last_command_t is None:
            return 'no_command_yet'
        if now - st.last_command_t > self.command_timeout_s:
            return 'command_timeout'
        return 'ok'

    def _update_mode(self, corner, now):
        st = self.state[corner]
        reason = self._reason(corner, now)
        mode = 'normal' if reason == 'ok' else 'failsafe'
        if st.mode == 'failsafe':
            st.failsafe_s += now - st._since
        st._since = now
        if mode == 'failsafe' and st.mode == 'normal':
            st.failsafe_entries += 1
        st.mode, st.reason = mode, reason
        return mode

    def tick(self, now=None):
        """
        Check the timeouts and re-send every corner that sent nothing for ``resend_period_s``.

        Returns the number of frames sent.
        """
        now = self.clock() if now is None else now
        sent = 0
        with self.lock:
            self._check_rx_timeouts(now)
            for corner in self.corners:
                st = self.state[corner]
                self._update_mode(corner, now)
                if st.last_sent_t is None or now - st.last_sent_t >= self.resend_period_s:
                    sent += int(self._send(corner, now, resend=True))
        return sent

    def _check_rx_timeouts(self, now):
        """Count each cyclic frame missing for ``rx_timeout_s``, once per outage (lock held)."""
        for name in self._cyclic_rx:
            last = self._rx_last.get(name, self.started_t)
            if now - last > self.rx_timeout_s and name not in self._rx_timed_out:
                self._rx_timed_out.add(name)
                self.faults['timeout'] += 1
                self.timeouts[name] = self.timeouts.get(name, 0) + 1

    def reconfigure(self, *, safe_current_a=None, command_timeout_s=None):
        """Change the safe current or the command timeout; '' or the reason (nothing changed)."""
        with self.lock:
            lo, hi = self.limiter.i_min_a, self.limiter.i_max_a
            if safe_current_a is not None and not lo <= float(safe_current_a) <= hi:
                return f'safe_current_a must lie in the DBC range [{lo:g}, {hi:g}] A'
            if command_timeout_s is not None and not float(command_timeout_s) > 0:
                return 'command_timeout_s must be positive'
            if safe_current_a is not None:
                self.safe_current_a = float(safe_current_a)
            if command_timeout_s is not None:
                self.command_timeout_s = float(command_timeout_s)
            return ''

    def latest(self, corner):
        """
        Return the latest bus values of ``corner``.

        A dict: ``body_accel``, ``wheel_accel`` [m/s^2], ``susp_pos`` [m] (NaN before the
        first sensor frame), ``sent_a`` (current sent), ``measured_a`` (driver) [A], ``mode``
        and ``reason``.
        """
        with self.lock:
            st = self.state[corner]
            return dict(self._sensors[corner], sent_a=st.sent_a, mode=st.mode, reason=st.reason,
                        measured_a=st.driver.current_a if st.driver else math.nan)

    # --- bus reader ----------------------------------------------------------------------------
    def start(self, log_file=None, reader_priority=0):
        """
        Read the bus in a python-can ``Notifier`` thread (frames go to :meth:`on_frame`).

        With ``log_file``, every frame received (but our own, should the bus give them back)
        and every frame sent is also written by ``can.Logger`` (``.blf``, ``.asc``, ``.log`` =
        candump format, ``.csv``, ...; the writer is chosen by the extension), under the lock,
        from the thread that received or sent it.
        ``reader_priority`` > 0: the reader thread goes under SCHED_FIFO at that priority on
        its first frame (the vehicle computer's loop runs in it: above the process's other
        threads); a refusal is in the status (``reader_priority_error``).
        A frame whose handling raises (here or in a callback: the vehicle computer's whole
        loop) is counted, ``frame_errors`` with the last one's ``frame_error``, and the reader
        goes on with the next frame; before, python-can's ``Notifier`` ended its thread and
        the bus was read no more. An error of the bus itself still ends it.
        """
        if self._notifier is None and self.bus is not None:
            take = self.on_frame
            if reader_priority > 0:
                self._reader = fifo_on_first_call(self.on_frame, reader_priority)
                take = self._reader

            def listener(msg):
                try:
                    take(msg)
                except Exception as exc:      # noqa: BLE001 - one frame must not end the reader
                    with self.lock:
                        self.frame_errors += 1
                        self.frame_error = f'{type(exc).__name__}: {exc}'
            if log_file:
                with self.lock:
                    self._log = can.Logger(log_file)
            self._notifier = can.Notifier(self.bus, [listener], timeout=0.1)

    def stop(self):
        """Stop the reader thread and close the log (the bus stays open for its owner)."""
        if self._notifier is not None:
            self._notifier.stop()
            self._notifier = None
        with self.lock:
            if self._log is not None:
                self._log.stop()
                self._log = None

    # --- status --------------------------------------------------------------------------------
    def status(self, now=None):
        """Return the status dict (``/diagnostics`` values; see docs/can.md)."""
        now = self.clock() if now is None else now
        with self.lock:
            corners = {}
            for corner in self.corners:
                st = self.state[corner]
                self._update_mode(corner, now)
                drv = st.driver
                corners[corner] = {
                    'mode': st.mode, 'reason': st.reason, 'command_a': st.command_a,
                    'sent_a': st.sent_a, 'failsafe_s': st.failsafe_s,
                    'failsafe_entries': st.failsafe_entries, 'commands': st.commands,
                    'frames_sent': st.frames_sent, 'resent': st.resent,
                    'status_frames': st.status_frames,
                    'measured_a': drv.current_a if drv else math.nan,
                    'driver_state': drv.state if drv else -1,
                    'driver_faults': ','.join(drv.faults) if drv else '',
                    'driver_fault_edges': dict(st.driver_faults)}
            return {'corners': corners, 'faults': dict(self.faults),
                    'timeouts': dict(self.timeouts), 'commands': dict(self.limiter.counts),
                    'frames_received': self.frames_received, 'own_frames': self.own_frames,
                    'log_errors': self.log_errors, 'log_error': self.log_error,
                    'frame_errors': self.frame_errors, 'frame_error': self.frame_error,
                    'bus_off': self.bus_off, 'safe_current_a': self.safe_current_a,
                    'command_timeout_s': self.command_timeout_s,
                    'reader_priority_error': getattr(self._reader, 'error', None)}


class BridgeHealth:
    """
    Status rules of the bridge (``/diagnostics`` level and message).

    OK: every corner normal, no new fault. WARN: a corner in fail-safe (which and why), fault
    counters, clamped / refused commands or frames the log refused that rose since the last
    status. ERROR: the bus is off, a driver reports a fault, or a frame's handling raised.
    """

    def __init__(self):
        self._rising = Rising()

    def __call__(self, status, dropped=None):
        """Return the :class:`~mr_damper_common.health.Health` of a :meth:`status` dict."""
        problems = []
        if status['bus_off']:
            problems.append((ERROR, 'bus off'))
        for corner, cs in status['corners'].items():
            if cs['reason'] == 'driver_fault':
                what = cs['driver_faults'] or 'state FAULT'
                problems.append((ERROR, f'{corner}: driver fault ({what}), fail-safe '
                                 f'{status["safe_current_a"]:g} A'))
            elif cs['mode'] != 'normal':
                problems.append((WARN, f'{corner}: fail-safe ({cs["reason"]})'))
        new = {k: self._rising.rise(f'faults.{k}', v) for k, v in status['faults'].items()}
        new = {k: v for k, v in new.items() if v}
        if new:
            problems.append((WARN, 'CAN faults since the last status: '
                             + ', '.join(f'{v} {k}' for k, v in sorted(new.items()))))
        cmd = {k: self._rising.rise(f'commands.{k}', v) for k, v in status['commands'].items()
               if k != 'accepted'}
        cmd = {k: v for k, v in cmd.items() if v}
        if cmd:
            problems.append((WARN, 'commands outside the DBC range: '
                             + ', '.join(f'{v} {k}' for k, v in sorted(cmd.items()))))
        raised = self._rising.rise('frame_errors', status.get('frame_errors', 0))
        if raised:
            problems.append((ERROR, f'{raised} frames whose handling raised since the last '
                             f'status (last: {status["frame_error"]})'))
        refused = self._rising.rise('log_errors', status.get('log_errors', 0))
        if refused:
            problems.append((WARN, f'{refused} frames the frame log refused since the last '
                             f'status (last: {status["log_error"]})'))
        finding = dropped_since(self._rising, dropped)
        if finding:
            problems.append(finding)
        return worst(problems or [(OK, 'ok')], status)
