"""
The vehicle computer in one control loop, without ROS: a sensor cycle in, its command out.

:class:`VehicleLoop` is what ``vehicle_computer_node`` calls. It runs, in one call and one
thread, what the three-node chain (``vehicle_bridge_node`` -> ``vehicle_estimator_node`` ->
``vehicle_controller_node``) runs in three processes: the full-car state estimate of the
cycle's sensors (:class:`~semi_active_control.estimation.VehicleEstimatorCore`), the law with
its four inverses and supervisors and the deadline supervision
(:class:`~semi_active_control.runtime.vehicle_controller.VehicleControllerCore`), then the
command handed to ``send`` (the bus's write: the bridge's ``command_all``). This is the
read -> update -> write loop of ros2_control's controller manager: the control path crosses no
middleware, so a cycle's answer costs the cycle's own computation, not three hops between
processes (docs/vehicle.md, the two layouts and their figures).

The cores are the chain's own, with the same rules: while not active the estimator runs
(so a later activation starts on a converged filter) and nothing is commanded (the bridge then
sends its safe frames); a cycle whose deadline has passed before the loop comes to it (the
loop is behind the bus: a stall, a burst) is estimated but not answered, a deadline miss
(``VehicleControllerCore.skip_late``), so the loop catches up on the newest cycle instead of
answering a queue of stale ones (what KEEP_LAST does for a topic); :meth:`deactivate` sends
one command with every corner on the safe current; :meth:`check` (the caller's timer) sends
the safe command while no cycle comes for the sensor timeout. One lock: :meth:`cycle` comes
from the bus reader's thread, the rest from the caller's.

Each cycle's execution time is counted by stage (:attr:`VehicleLoop.execution`, the status's
``loop.execution_s``), as ros2_control's controller manager reports its controllers' execution
times: ``estimate`` (the filter's step), ``control`` (the law, the inverses, the supervisors),
``send`` (the bus write). Before them, :attr:`VehicleLoop.reception` counts each cycle's time
from its bus time to the loop's start on it (``loop.reception_s``: the frames' reception, and
any wait for the cycle before), and :attr:`VehicleLoop.cycles_queued` the cycles whose frame
came while the loop was still on the cycle before. Together with the bus-to-bus latency the
bridge counts, they say where a cycle's response goes on the computer at hand.
"""
import math
import threading
import time

from mr_damper_common.latency import LatencyHistogram
from semi_active_control.runtime.vehicle_controller import failsafe_flags, full_car_state

#: The stages of a cycle whose execution time :class:`VehicleLoop` counts.
STAGES = ('estimate', 'control', 'send')

#: The causes of a deadline miss :class:`VehicleLoop` names (module docstring).
MISS_CAUSES = ('bunched', 'queued', 'reached_late', 'slow')

#: A cycle whose bus time follows the one before by less than this share of the period is
#: bunched behind it.
BUNCHED = 0.75


class VehicleLoop:
    """
    Estimator, law and bus write on each sensor cycle in one call (see the module docstring).

    Parameters
    ----------
    estimator : VehicleEstimatorCore
        The full-car filter (its cycle is the sensor cycle).
    controller : VehicleControllerCore
        The law, four inverses, four supervisors and the deadline supervision.
    send : callable
        ``send(currents_a, failsafe, cycle)``: put one command on the bus (four currents [A],
        four fail-safe flags: any mode but normal) as the answer to sensor cycle ``cycle``
        (0: none); the bridge's ``command_all``. Called under the lock, so no command can
        follow the deactivation's.
    clock : callable
        Monotonic clock [s] of the execution times (default ``time.perf_counter``).

    Attributes
    ----------
    cycles_inactive : int
        Cycles estimated while not active (not answered).
    cycles_unused : int
        Cycles the estimator did not use (older than or equal to the newest one).
    cycles_queued : int
        Cycles whose bus time came before the loop had finished the cycle before (on the
        caller's clock: its start plus the loop's own execution time).
    misses : dict
        Cause (:data:`MISS_CAUSES`) -> the cycles the deadline supervision judged missed
        (the controller's monitor: answered after their deadline, or skipped late), each named
        by where its time went (the caller's clock at the start minus the bus time, the
        reception; the loop's own time, the execution); they add up to the monitor's count.
    reception : LatencyHistogram
        Per cycle, the caller's clock at the loop's start minus the cycle's bus time [s].
    execution : dict
        Stage (:data:`STAGES`) -> :class:`~mr_damper_common.latency.LatencyHistogram` of its
        execution times [s]: every estimator step, the law of every cycle answered (not
        skipped late), the bus write of every command that answers a cycle.

    """

    def __init__(self, estimator, controller, send, clock=time.perf_counter):
        self.estimator = estimator
        self.controller = controller
        self.send = send
        self.clock = clock
        self.lock = threading.Lock()
        self.cycles_inactive = 0
        self.cycles_unused = 0
        self.cycles_queued = 0
        self.misses = dict.fromkeys(MISS_CAUSES, 0)
        self.reception = LatencyHistogram()
        self.execution = {stage: LatencyHistogram() for stage in STAGES}
        self._done_t = -math.inf          # the cycle before done, on the caller's clock [s]
        self._last_t = -math.inf          # the newest cycle's bus time [s]

    @property
    def active(self):
        """True while commanding."""
        return self.controller.active

    # --- lifecycle ----------------------------------------------------------------------------
    def configure(self, t_clock):
        """Start the filter at rest and load the file corners' models; ``{corner: Verdict}``."""
        with self.lock:
            self.estimator.reset()
            return self.controller.configure(t_clock)

    def activate(self, t_now):
        """Command from the next cycle on."""
        with self.lock:
            self.controller.activate(t_now)

    def deactivate(self, t_now):
        """Send one command with every corner on the safe current; command nothing after it."""
        with self.lock:
            cmd = self.controller.deactivate(t_now)
            self._send(cmd, 0)
            return cmd

    # --- cycles -------------------------------------------------------------------------------
    def cycle(self, sequence, t, body_accel, travel, t_now):
        """
        Run one sensor cycle: estimate, and while active command and send the answer.

        Parameters
        ----------
        sequence : int
            The cycle's number (+1 per cycle; gaps are cycles lost on the bus).
        t : float
            The cycle's time [s] (its bus time: the stamp and the deadline's start).
        body_accel, travel : array_like (4,)
            Body accelerations, gravity removed [m/s^2], and suspension travels [m] (NaN: no
            reading).
        t_now : float
            The caller's clock [s], the clock of ``t``.

        Returns
        -------
        estimate : VehicleEstimate or None
            None when the cycle was not used (old or repeated).
        command : VehicleCommand or None
            The command sent (None: not active, not answered, or skipped late without the
            watchdog tripping).

        """
        with self.lock:
            clock = self.clock
            t0 = clock()
            wait = max(t_now - t, 0.0)
            self.reception.add(wait)
            queued = t < self._done_t
            if queued:
                self.cycles_queued += 1
            monitor = self.controller.monitor
            bunched = queued and t - self._last_t < BUNCHED * monitor.period_s
            self._last_t = max(self._last_t, t)
            judged = monitor.misses
            try:
                return self._cycle(sequence, t, body_accel, travel, t_now, t0)
            finally:
                run = clock() - t0
                self._done_t = t_now + run
                if monitor.misses > judged:        # the deadline supervision's verdict
                    self.misses['bunched' if bunched else 'queued' if queued else
                                'reached_late' if wait > run else 'slow'] += 1

    def _cycle(self, sequence, t, body_accel, travel, t_now, t0):
        """Run :meth:`cycle` under the lock, its clock started at ``t0``."""
        clock, execution = self.clock, self.execution
        est = self.estimator.step(sequence, t, body_accel, travel)
        t1 = clock()
        execution['estimate'].add(t1 - t0)
        if est is None:
            self.cycles_unused += 1
            return None, None
        if not self.controller.active:
            self.cycles_inactive += 1
            return est, None
        if self.controller.monitor.past(t, t_now):
            # past its deadline before it is answered (the loop is behind the bus): the
            # newer cycles behind it come first; a miss, the safe frame if that trips
            cmd = self.controller.skip_late(est.sequence, est.t, t_now)
            if cmd is not None:
                self._send(cmd, 0)
            return est, cmd
        state = full_car_state(self.controller.geometry, est.t, est.body, est.body_rates,
                               est.body_acc, est.travel, est.travel_velocity,
                               est.tyre_deflection, est.wheel_velocity, est.damper_force)
        cmd = self.controller.command(state, est.sequence, est.valid, est.reason, t_now,
                                      judge=False)
        t2 = clock()
        execution['control'].add(t2 - t1)
        if cmd is not None:
            self._send(cmd, est.sequence)
            t3 = clock()
            execution['send'].add(t3 - t2)
            # judged when its command has left: a cycle whose own execution ran past its
            # deadline is a miss, as one reached or skipped late
            self.controller.judge(est.t, t_now + (t3 - t0))
        return est, cmd

    def check(self, t_now):
        """Check the sensor timeout (the caller's timer); send and return a safe command."""
        with self.lock:
            cmd = self.controller.check(t_now)
            if cmd is not None:
                self._send(cmd, 0)
            return cmd

    def offer_parameters(self, corner, values, t_clock):
        """Offer a live identifier's set to corner ``corner`` (index); return the Verdict."""
        with self.lock:
            return self.controller.offer_parameters(corner, values, t_clock)

    def offer_preview(self, fields):
        """Hand a road-preview frame to the preview law (see VehicleControllerCore)."""
        with self.lock:
            self.controller.offer_preview(fields)

    def _send(self, cmd, cycle):
        self.send(cmd.currents_a, failsafe_flags(cmd.modes), cycle)

    def status(self, t_now=None):
        """
        Return ``{'estimator': ..., 'controller': ..., 'loop': ...}`` (JSON-ready).

        ``loop``: ``cycles_inactive``, ``cycles_unused``, ``cycles_queued``, ``misses`` (by
        cause), ``reception_s`` and ``execution_s`` (per stage the execution times; each
        histogram's ``n``, ``mean_s``, ``p50_s``, ``p99_s``, ``p999_s``, ``max_s``).
        """
        with self.lock:
            return {'estimator': self.estimator.status(),
                    'controller': self.controller.status(t_now),
                    'loop': {'cycles_inactive': self.cycles_inactive,
                             'cycles_unused': self.cycles_unused,
                             'cycles_queued': self.cycles_queued,
                             'misses': dict(self.misses),
                             'reception_s': self.reception.summary(),
                             'execution_s': {stage: h.summary()
                                             for stage, h in self.execution.items()}}}
