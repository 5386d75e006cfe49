"""
The vehicle computer's full-car controller without ROS: one state per cycle in, one command out.

:class:`VehicleControllerCore` is what ``vehicle_controller_node`` calls. Each cycle's estimated
state (one ``FullCarState`` message: body modes and four corners) goes through the full-car
law and, per corner, the inverse of that corner's identified model under that corner's
supervisor (:class:`semi_active_control.laws.full_car.FullCarController`, the one home of "law +
four inverses + four supervisors"); the four currents go out as one command with a mode and a
reason per corner. The corners' models come from end-of-line files or live identifiers
(:class:`~semi_active_control.supervision.corner_models.CornerModels`).

All four corners get the safe current, each with the reason, when

- the controller is not active (``inactive``: configured but not activated, or deactivated;
  the deactivation itself answers with one such command, so the drivers get the safe current
  at once, not the last command);
- the estimate is invalid (``estimate_<its reason>``, e.g. ``estimate_too_few_sensors``);
- the deadline supervision (:class:`~semi_active_control.supervision.deadline.DeadlineMonitor`)
  says so: ``deadline_misses`` (that many cycles in a row answered after their deadline) or
  ``sensor_timeout`` (no state for ``input_timeout_s``; :meth:`check` answers with a safe
  command on the caller's timer while it lasts). Both end by themselves.

One corner without a valid, fresh model gets its safe current (its supervisor's reason); the
other three go on with the law. A state older than the newest taken (its sequence number) is
not answered (counted); a gap in the numbers is counted as states lost.
"""
from dataclasses import dataclass, field
import math

import numpy as np

from mr_damper_common.sequence import SequenceTracker
from semi_active_control.laws.registry import make_full_car_law
from semi_active_control.runtime.full_car_controller_core import FullCarController
from semi_active_control.car.full_car_linear import FullCarState
from semi_active_control.car.full_car import CORNERS
from semi_active_control.supervision.deadline import DeadlineMonitor, RECOVER_CYCLES

#: Corner modes of a command (the values of ``FullCarCommand.MODE_*``).
MODE_NORMAL, MODE_FAIL_SAFE, MODE_INACTIVE = 0, 1, 2

_NAN4 = np.full(4, math.nan)


def failsafe_flags(modes):
    """Return each corner's fail-safe flag (its ``CMD_FAILSAFE`` bit): any mode but normal."""
    return [int(m) != MODE_NORMAL for m in modes]


@dataclass
class VehicleCommand:
    """
    One command of the four dampers (what ``FullCarCommand`` carries; SI).

    Attributes
    ----------
    sequence : int
        +1 per command.
    state_sequence : int
        The state's cycle answered (0: none, e.g. a sensor timeout or a deactivation).
    state_t : float
        The state's stamp [s] (NaN: none).
    currents_a, demanded_n : ndarray (4,)
        Coil currents [A]; the law's body forces [N] (NaN on the safe current).
    modes : list of int
        :data:`MODE_NORMAL`, :data:`MODE_FAIL_SAFE` or :data:`MODE_INACTIVE` per corner.
    reasons : list of str
        ``'ok'`` or why each corner is on its safe current.

    """

    sequence: int
    state_sequence: int
    state_t: float
    currents_a: np.ndarray
    demanded_n: np.ndarray
    modes: list
    reasons: list = field(default_factory=list)


def full_car_state(geometry, t, body, body_rates, body_acc, travel, travel_velocity,
                   tyre_deflection, wheel_velocity, damper_force):
    """
    Build the laws' ``FullCarState`` (``semi_active_control.car.full_car_linear``) of an estimate.

    ``geometry`` is the car's corner map ``T`` (``FullCarParams.geometry``, shape (4, 3)).
    Road heights are 0 (the wheel height is the tyre deflection, as the estimator gives it);
    tyre forces and coil currents, which no law reads, are NaN. All arrays SI, corners
    ``fl, fr, rl, rr``; ``body`` is heave [m], pitch, roll [rad].
    """
    T = geometry
    rates = np.asarray(body_rates, dtype=float)
    acc3 = np.asarray(body_acc, dtype=float)
    tyre = np.asarray(tyre_deflection, dtype=float)
    nan4 = _NAN4.copy()                      # (a copy: cheaper than np.full each cycle)
    return FullCarState(
        t=float(t), q=np.concatenate([np.asarray(body, dtype=float), tyre]),
        v=np.concatenate([rates, np.asarray(wheel_velocity, dtype=float)]),
        acc=np.concatenate([acc3, nan4]), z_r=np.zeros(4), zdot_r=np.zeros(4),
        travel=np.asarray(travel, dtype=float), v_rel=np.asarray(travel_velocity, dtype=float),
        tyre_force=nan4, damper_force=np.asarray(damper_force, dtype=float),
        coil_current=nan4.copy(), body_v=T @ rates, body_a=T @ acc3)


class VehicleControllerCore:
    """
    The law, four inverses and four supervisors on one state per cycle (module docstring).

    Parameters
    ----------
    params : FullCarParams
        The car (corner map, the laws' design).
    law : str or law object
        Full-car law (``modal-skyhook``, ``per-corner-<law>``, ``full-car-clipped-optimal``,
        ...; :func:`~semi_active_control.laws.registry.make_full_car_law`).
    models : CornerModels
        The corners' models and supervisors.
    cycle_s : float
        Control cycle [s] (the sensor cycle; the period of a filter inside the law).
    max_consecutive_misses, recover_cycles, input_timeout_s, deadline_s
        Deadline supervision (:class:`DeadlineMonitor`).
    preview : LivePreview, optional
        The road-preview law and its topic input
        (:class:`~semi_active_control.runtime.live_preview.LivePreview`): its law replaces
        ``law``, and every cycle feeds it the frames due before the law runs.

    Attributes
    ----------
    controller : FullCarController
    monitor : DeadlineMonitor
    states : SequenceTracker
        The states' numbers: ``lost`` (gaps), ``out_of_order`` / ``repeated`` (not answered).
    active : bool

    """

    def __init__(self, params, law, models, *, cycle_s=0.002, max_consecutive_misses=5,
                 recover_cycles=RECOVER_CYCLES, input_timeout_s=0.02, deadline_s=None,
                 preview=None):
        self.preview = preview
        if preview is not None:
            law = preview.law
        if isinstance(law, str):
            law = make_full_car_law(law, params, dt=cycle_s)
        self.params = params
        self.geometry = params.geometry
        self.models = models
        self.controller = FullCarController(law, models.supervisors)
        self.monitor = DeadlineMonitor(cycle_s, deadline_s=deadline_s,
                                       max_consecutive_misses=max_consecutive_misses,
                                       recover_cycles=recover_cycles,
                                       input_timeout_s=input_timeout_s)
        self.safe_current_a = float(models.supervisors[0].safe_current_a)
        self.states = SequenceTracker()
        self.active = False
        self.sequence = 0
        self.answered = 0
        self.skipped_late = 0
        self._unjudged = None                  # stamp of the cycle answer() left to sent()
        self.safe_answers = {}                 # reason for all four corners -> commands
        self.states_while_inactive = 0
        self.normal_commands = [0] * 4
        self.first_normal_t = [math.nan] * 4
        self.last = None

    # --- lifecycle ----------------------------------------------------------------------------
    def configure(self, t_clock):
        """Load the file corners' models; return ``{corner: Verdict}`` (see CornerModels)."""
        return self.models.load_files(t_clock)

    def activate(self, t_now):
        """Start commanding from the next state; the deadline supervision starts anew."""
        self.monitor.reset(t_now)
        self.monitor.check(t_now)
        self.controller.reset()
        self.active = True

    def deactivate(self, t_now):
        """Stop commanding; return the command that puts every corner on the safe current."""
        self.active = False
        self.monitor.reset(t_now)
        return self._all_safe('inactive', MODE_INACTIVE, 0, math.nan)

    # --- cycles -------------------------------------------------------------------------------
    def command(self, state, sequence, valid, reason, t_now, judge=True):
        """
        Answer one state; return the :class:`VehicleCommand` (None: not answered).

        With ``judge`` the deadline supervision judges the cycle answered at ``t_now``; a
        caller that can tell when its answer left (after the command is sent) passes False and
        calls :meth:`judge` then, so that a cycle whose own execution ran past its deadline is
        a miss too.

        Parameters
        ----------
        state : FullCarState
            The cycle's estimate (:func:`full_car_state`); ``state.t`` is the cycle's stamp,
            its release for the deadline.
        sequence : int
            The cycle's number.
        valid : bool
            The estimate's validity.
        reason : str
            Why it is not valid ('' when valid).
        t_now : float
            The caller's clock [s] (same clock as the stamps): supervisors and deadline.
        judge : bool
            Judge the deadline at ``t_now`` (False: the caller calls :meth:`judge`).

        """
        if not self.active:
            self.states_while_inactive += 1
            return None
        if self.states.offer(sequence) < 0:
            return None
        self.monitor.input(t_now)
        sup_reason = None
        if not valid:
            sup_reason = f'estimate_{reason or "invalid"}'
        if self.preview is not None:
            self.preview.before(state)
        currents = self.controller.command(state, t_now)
        if self.preview is not None:
            self.preview.after(state)
        cmd = self._from_controller(currents, sequence, state.t)
        watchdog = self.monitor.reason
        if sup_reason is None and watchdog is not None:
            sup_reason = watchdog
        if sup_reason is not None:
            cmd = self._all_safe(sup_reason, MODE_FAIL_SAFE, sequence, state.t)
        else:
            self._count_normal(cmd, state.t)
        if judge:
            self.monitor.cycle(state.t, t_now)
        self.answered += 1
        return cmd

    def answer(self, state, sequence, valid, reason, t_now):
        """
        Answer one state as it arrives; a state already past its deadline gets no law command.

        A state that reaches the controller after its deadline (held up on its way, or the
        controller was) is old: the sensor timeout may already have put every corner on the
        safe current, and a law command from old sensors must not follow it. It is skipped
        as :meth:`skip_late` does (a miss; the safe command while the misses trip). Any other
        state is answered as :meth:`command` does, its deadline judged when the caller calls
        :meth:`sent` after sending the command (the same rules as the loop layout's
        :class:`~semi_active_control.runtime.vehicle_loop.VehicleLoop`).

        Returns
        -------
        VehicleCommand or None
            The command to send (None: nothing to send).

        """
        self._unjudged = None
        if self.active and self.monitor.past(state.t, t_now):
            return self.skip_late(sequence, state.t, t_now)
        cmd = self.command(state, sequence, valid, reason, t_now, judge=False)
        if cmd is not None:
            self._unjudged = state.t
        return cmd

    def sent(self, t_done):
        """
        Judge the deadline of the state :meth:`answer` last answered, sent at ``t_done`` [s].

        Nothing after a skipped state (its miss is counted).
        """
        if self._unjudged is not None:
            self.judge(self._unjudged, t_done)
            self._unjudged = None

    def judge(self, t_state, t_done):
        """Judge the deadline of the cycle stamped ``t_state``, answered at ``t_done`` [s]."""
        if self.active:
            self.monitor.cycle(t_state, t_done)

    def skip_late(self, sequence, t_state, t_now):
        """
        Count a state that came after its deadline and is left unanswered; maybe a safe command.

        A caller behind its input (a loop taking cycles from a queue) skips every cycle whose
        deadline has passed when it comes to it, so that it answers the newest instead of
        falling further behind. The skipped cycle counts as a deadline miss with its lateness
        (and as input: the sensors are there). While the misses hold every corner on the safe
        current (``deadline_misses``), each skipped cycle returns the safe command to be sent
        (cheap: no law), so the drivers keep getting commands while the caller catches up.

        Returns
        -------
        VehicleCommand or None

        """
        if not self.active or self.states.offer(sequence) < 0:
            return None
        self.skipped_late += 1
        self.monitor.input(t_now)
        self.monitor.cycle(t_state, t_now)
        reason = self.monitor.reason
        if reason is not None:
            return self._all_safe(reason, MODE_FAIL_SAFE, sequence, t_state)
        return None

    def check(self, t_now):
        """
        Check the sensor timeout (the caller's timer); return a safe command while it lasts.

        Returns
        -------
        VehicleCommand or None
            Every corner on the safe current with reason ``sensor_timeout`` (None while states
            come, or when not active).

        """
        if not self.active:
            return None
        if self.monitor.check(t_now) != 'sensor_timeout':
            return None
        self.models.update(t_now)
        return self._all_safe('sensor_timeout', MODE_FAIL_SAFE, 0, math.nan)

    def offer_parameters(self, corner, values, t_clock):
        """Offer a live identifier's decoded set to a live corner's supervisor."""
        return self.models.offer_live(corner, values, t_clock)

    def offer_preview(self, fields):
        """
        Take one decoded road-preview message (the preview law's input; counted there).

        ``fields`` is :func:`mr_damper_common.messages.road_preview_fields` of a message, or a
        :class:`~mr_damper_common.messages.MessageError` of one that did not decode (refused
        by its reason). Returns whether the frame was taken (False without a preview law).
        """
        if self.preview is None:
            return False
        if isinstance(fields, Exception):
            self.preview.refuse(getattr(fields, 'reason', 'decode'))
            return False
        return bool(self.preview.offer(fields))

    # --- commands -----------------------------------------------------------------------------
    def _next(self):
        self.sequence += 1
        return self.sequence

    def _from_controller(self, currents, sequence, t_state):
        modes, reasons = [], []
        for core in self.controller.cores:
            mode, why = core.mode_reason()
            modes.append(MODE_NORMAL if mode == 'normal' else MODE_FAIL_SAFE)
            reasons.append(why)
        cmd = VehicleCommand(self._next(), int(sequence), float(t_state),
                             np.asarray(currents, dtype=float),
                             np.asarray(self.controller.demands, dtype=float), modes, reasons)
        self.last = cmd
        return cmd

    def _all_safe(self, reason, mode, sequence, t_state):
        self.safe_answers[reason] = self.safe_answers.get(reason, 0) + 1
        cmd = VehicleCommand(self._next(), int(sequence), float(t_state),
                             np.full(4, self.safe_current_a), np.full(4, math.nan), [mode] * 4,
                             [reason] * 4)
        self.last = cmd
        return cmd

    def _count_normal(self, cmd, t_state):
        for j, mode in enumerate(cmd.modes):
            if mode == MODE_NORMAL:
                self.normal_commands[j] += 1
                if math.isnan(self.first_normal_t[j]):
                    self.first_normal_t[j] = t_state

    def status(self, t_now=None):
        """
        Summarise the controller (``/diagnostics`` values; JSON-ready).

        Returns
        -------
        dict
            ``controller`` (law), ``active``, ``commands`` (sent), ``states_answered``,
            ``states_skipped_late`` (:meth:`skip_late`),
            ``states`` (sequence counts: ``lost``, ``out_of_order``, ...),
            ``states_while_inactive``, ``all_safe`` (commands with every corner safe, by
            reason), ``deadline`` (:meth:`DeadlineMonitor.status`), ``corners`` (per corner:
            the core's status, the model source, ``normal_commands``,
            ``first_normal_t``, ``current_a``, ``mode``, ``reason`` of the last command);
            with a preview, ``preview`` (:meth:`LivePreview.status`).

        """
        corners = self.controller.status()
        models = self.models.status(t_now)
        last = self.last
        for i, c in enumerate(CORNERS):
            corners[c].update(source=models[c]['source'], file=models[c]['file'],
                              normal_commands=self.normal_commands[i],
                              first_normal_t=self.first_normal_t[i])
            if 'load_error' in models[c]:
                corners[c]['load_error'] = models[c]['load_error']
            if last is not None:
                corners[c].update(current_a=float(last.currents_a[i]),
                                  mode='normal' if last.modes[i] == MODE_NORMAL else
                                  ('inactive' if last.modes[i] == MODE_INACTIVE else 'failsafe'),
                                  reason=last.reasons[i])
        return {'controller': self.controller.name, 'active': self.active,
                'commands': self.sequence, 'states_answered': self.answered,
                'states_skipped_late': self.skipped_late,
                'states': self.states.status(),
                'states_while_inactive': self.states_while_inactive,
                'all_safe': dict(self.safe_answers),
                'corners_normal': sum(corners[c].get('mode') == 'normal' for c in CORNERS),
                'deadline': self.monitor.status(t_now), 'corners': corners,
                **({'preview': self.preview.status()} if self.preview is not None else {})}
