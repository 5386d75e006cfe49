"""
Semi-active controller core without ROS: a vehicle state in, a supervised coil current out.

The one home of "law + identified inverse + fail-safe supervisor" for one control step. Both
the simulated car's built-in loop (:class:`quarter_car_sim.simulate.live_loop.ClosedLoop`) and the
stand-alone ``semi_active_controller_node`` (state from a car or a vehicle over a topic) call
:class:`ControllerCore`. The simulated car's side of an external controller (the latest command
received, its timeout and the checks a command passes before it reaches the coil) is
:class:`quarter_car_sim.runtime.command_input.CommandInput`.

One step of :meth:`ControllerCore.command`:

1. the supervisor (:class:`semi_active_control.supervision.failsafe.ModelSupervisor`) is
   advanced to the caller's clock; it holds the latest valid, fresh identified Kwok-current
   parameters or none;
2. a state whose fields the laws use (:data:`LAW_FIELDS` and the law's own ``state_fields``,
   e.g. the tyre deflection of the LQR laws) are not all finite is refused
   (counted ``state_rejected.non_finite``) and answered with the safe current; so is a state
   whose stamp :class:`mr_damper_common.stamps.StampGuard` refuses (the one home of stamp
   sanity): one older than the newest state taken (``out_of_order``), or stamped more than
   ``max_future_s`` ahead of the caller's clock (``future_stamp``). A refused stamp never
   becomes the reference, so one bad stamp costs one safe-current answer; after
   ``rebase_after`` consecutive out-of-order (or future) states increasing among themselves
   (a vehicle clock that jumped) the stamps are re-based (counted ``stamp_rebases``). While
   the last answer was the safe current for a state reason, :meth:`ControllerCore.status`
   says ``mode`` failsafe with ``reason`` ``state_<reason>``;
3. with a model: the law's demanded body force (positive up) goes through the inverse of the
   identified model (kept inside the identified current range) to a coil current, saturated to
   the coil range; without one: the safe current. A passive law (``passive@<I>A``) gives its
   current directly, in both modes.

Pure Python (no ROS): the node converts messages into
:class:`~mr_damper_common.contract.CornerState` and calls it.
"""
import contextlib
import json
import math

from mr_damper_common.stamps import StampGuard
from mr_damper_model.models.inverse import KwokCurrentInverse
from mr_damper_model.models.scalar_inverse import scalar_kernels
from semi_active_control.laws.registry import make_controller
from semi_active_control.supervision.failsafe import clip_current, SupervisorError

#: Fields of the state the control laws read (see :mod:`semi_active_control.laws`):
#: body velocity and acceleration, wheel velocity, suspension travel and its rate.
LAW_FIELDS = ('v_s', 'a_s', 'v_u', 'travel', 'v_rel')

#: Reasons a state is refused (counted in :attr:`ControllerCore.state_rejected`).
STATE_REJECTIONS = ('non_finite', 'future_stamp', 'out_of_order')

#: Default horizon [s]: a state stamped further ahead of the caller's clock is refused.
MAX_FUTURE_S = 1.0

#: Default run of consecutive out-of-order (or future) states that re-bases the stamps.
REBASE_AFTER = 50


class ControllerCore:
    """
    One semi-active control step: supervised law + inverse, with counters.

    Parameters
    ----------
    controller : semi_active_control.laws.Controller
        Kind ``'current'`` (commanded as is) or ``'semi-active'`` (body force through the
        inverse model of the supervisor's active parameters).
    supervisor : semi_active_control.supervision.failsafe.ModelSupervisor
        Gatekeeper of the identified parameters; holds the safe current and coil range.
    inverse_tol_a : float
        Current tolerance [A] of the inverse model.
    max_future_s : float
        A state stamped more than this [s] ahead of the caller's clock is refused
        (``future_stamp``; :class:`mr_damper_common.stamps.StampGuard`).
    rebase_after : int
        Consecutive out-of-order (or future) states, increasing among themselves, after which
        the stamps are re-based on the last of them (a vehicle clock jump).

    Attributes
    ----------
    i_cmd : float
        Last command [A] (the safe current before the first).
    f_demand : float
        Last demanded body force [N] (NaN without a model or with a passive law).
    saturated : int
        Commands the inverse could not deliver exactly (demand out of reach).
    last_saturated : bool or None
        Whether the last command was saturated (None without a model).
    n_commands, n_normal : int
        Commands computed, and those computed with a model in use.
    state_rejected : dict
        ``{reason: count}`` of :data:`STATE_REJECTIONS`.
    last_refusal : str or None
        Why the last state was answered with the safe current (None: it was taken).
    non_finite_demands : int
        States taken whose law demand was not finite (a law coupling the corners, a full-car
        law, fed a non-finite input of another corner, or failing itself): answered with the
        safe current, never handed to the inverse.
    stamps : mr_damper_common.stamps.StampGuard
        The stamp checks (re-bases in ``stamps.rebases``).

    """

    def __init__(self, controller, supervisor, *, inverse_tol_a=1e-4,
                 max_future_s=MAX_FUTURE_S, rebase_after=REBASE_AFTER):
        self.sup = supervisor
        self.inverse_tol_a = float(inverse_tol_a)
        self._use(controller)
        self.i_cmd = supervisor.safe_current_a
        self.f_demand = math.nan
        self.saturated = 0
        self.last_saturated = None
        self.n_commands = 0
        self.n_normal = 0
        self.state_rejected = dict.fromkeys(STATE_REJECTIONS, 0)
        self.last_refusal = None
        self.non_finite_demands = 0
        self._demand_refused = False
        # equal stamps are in order: a car publishes its settling states all stamped 0 s
        self.stamps = StampGuard(max_future_s=max_future_s, rebase_after=rebase_after,
                                 accept_equal=True)
        self._inverse = None
        self._inverse_of = None
        # the compiled inverse, loaded (or compiled) now: not in the cycle of the first model
        scalar_kernels()

    def _inverse_for(self, identified):
        if identified is not self._inverse_of:
            # the inverse stays inside the current range the model was identified on
            lo = max(self.sup.i_min_a, identified.current_min_a)
            hi = min(self.sup.i_max_a, identified.current_max_a)
            if not hi > lo:
                lo, hi = self.sup.i_min_a, self.sup.i_max_a
            self._inverse = KwokCurrentInverse(
                identified.parameters, i_ref_a=identified.i_ref_a, i_min=lo, i_max=hi,
                tol_a=self.inverse_tol_a, sign_convention='body')
            self._inverse_of = identified
        return self._inverse

    @property
    def last_state_t(self):
        """Stamp [s] of the newest state taken (NaN before the first and after a re-base)."""
        last = self.stamps.last
        return last if math.isfinite(last) else math.nan

    def _state_refusal(self, state, t_clock):
        for name in self._fields:
            if not math.isfinite(getattr(state, name)):
                return 'non_finite'
        verdict = self.stamps.offer(state.t, t_clock)
        return verdict if verdict in STATE_REJECTIONS else None

    def _safe(self):
        self.f_demand = math.nan
        self.last_saturated = None
        self.i_cmd = self.sup.safe_current_a
        return self.i_cmd

    def command(self, state, t_clock):
        """
        Return the coil current [A] for a measured state, given the caller's clock.

        Parameters
        ----------
        state : mr_damper_common.contract.CornerState
            The corner (anything with ``t`` and the :data:`LAW_FIELDS` attributes).
        t_clock : float
            Caller's clock [s] (the parameter timeout and the stamp horizon; <= 0: no
            stamp horizon, a clock not started).

        Returns
        -------
        float
            Coil current command [A] within the coil range.

        """
        sup = self.sup
        sup.update(t_clock)
        self.n_commands += 1
        refusal = self._state_refusal(state, t_clock)
        self.last_refusal = refusal
        self._demand_refused = False
        if refusal is not None:
            self.state_rejected[refusal] += 1
            return self._safe()
        if self.passive:
            self.f_demand = math.nan
            self.i_cmd = clip_current(self.controller.demand(state), sup.i_min_a, sup.i_max_a,
                                      sup.safe_current_a)
            return self.i_cmd
        # the law sees every accepted state, also without a model: a law with a state of its
        # own (the Wk filter of clipped-optimal-wk) then follows the car through a fail-safe
        # episode instead of resuming from where it stopped
        f_body = float(self.controller.demand(state))
        self._demand_refused = not math.isfinite(f_body)
        if self._demand_refused:
            # never to the inverse (it raises on a non-finite demand): the safe current
            self.non_finite_demands += 1
            return self._safe()
        params = sup.active
        if params is None:
            return self._safe()
        self.n_normal += 1
        self.f_demand = f_body
        current, saturated = self._inverse_for(params).current(f_body, state.travel, state.v_rel)
        self.saturated += bool(saturated)
        self.last_saturated = bool(saturated)
        self.i_cmd = clip_current(current, sup.i_min_a, sup.i_max_a, sup.safe_current_a)
        return self.i_cmd

    def set_controller(self, controller):
        """
        Replace the control law while running (e.g. new gains); the next command uses it.

        Parameters
        ----------
        controller : semi_active_control.laws.Controller
            Kind ``'current'`` or ``'semi-active'``.

        Raises
        ------
        ValueError
            A law of another kind (an active law cannot drive an MR damper).

        """
        kind = getattr(controller, 'kind', None)
        if kind not in ('current', 'semi-active'):
            raise ValueError(f'controller {getattr(controller, "name", controller)!r} is '
                             f'{kind}: it cannot drive an MR damper')
        self._use(controller)

    def _use(self, controller):
        """Take ``controller`` as the law (its kind and the state fields it reads)."""
        self.controller = controller
        self.passive = getattr(controller, 'kind', '') == 'current'
        self._fields = LAW_FIELDS + tuple(getattr(controller, 'state_fields', ()))

    def mode_reason(self):
        """
        Return ``(mode, reason)`` of the last answer: a state refusal wins over the supervisor.

        Returns
        -------
        tuple of str
            ``('failsafe', 'state_<reason>')`` when the last state was answered with the safe
            current because it was refused (:data:`STATE_REJECTIONS`), ``('failsafe',
            'non_finite_demand')`` when the law's demand was not finite, else the supervisor's
            ``(mode, reason)``.

        """
        if self.last_refusal is not None:
            return 'failsafe', f'state_{self.last_refusal}'
        if self._demand_refused:
            return 'failsafe', 'non_finite_demand'
        return self.sup.mode, self.sup.reason

    def offer_parameters(self, values, t_clock):
        """Offer an identified set (or its flat mapping) to the supervisor; return its verdict."""
        return self.sup.offer(values, t_clock)

    def status(self):
        """
        Summarise the core as a JSON-ready dict.

        Returns
        -------
        dict
            The supervisor's status (``failsafe_s``, ``params_rejected``, ...) with ``mode``
            and ``reason`` of :meth:`mode_reason`, plus ``controller``, ``current_a``,
            ``commands``, ``commands_normal``, ``saturated_steps``, ``state_rejected``,
            ``non_finite_demands``,
            ``last_state_t``, ``stamp_rebases`` and ``last_stamp_rebase`` (``{direction,
            from_s, to_s}`` or None).

        """
        st = self.sup.status()
        st['mode'], st['reason'] = self.mode_reason()
        st.update({'controller': getattr(self.controller, 'name', str(self.controller)),
                   'current_a': self.i_cmd, 'commands': self.n_commands,
                   'commands_normal': self.n_normal, 'saturated_steps': self.saturated,
                   'state_rejected': dict(self.state_rejected),
                   'non_finite_demands': self.non_finite_demands,
                   'last_state_t': self.last_state_t, 'stamp_rebases': self.stamps.rebases,
                   'last_stamp_rebase': self.stamps.last_rebase})
        return st


#: Node parameters applied while running, and the supervisor setting each one sets.
SUPERVISOR_PARAMETERS = {'param_timeout_s': 'timeout_s', 'safe_current_a': 'safe_current_a',
                         'hold_on_reject': 'hold_on_reject',
                         'min_current_span_a': 'min_current_span_a'}


def make_node_law(name, car_params, rate_hz, options):
    """
    Build a node's control law: the one factory, damper laws only, at the node's control rate.

    Parameters
    ----------
    name : str
        Law name (:data:`semi_active_control.laws.DAMPER_LAW_NAMES`).
    car_params : QuarterCarParams
        Car of the LQR-designed laws.
    rate_hz : float
        Control rate [Hz]: ``dt = 1/rate_hz`` is the sample time of a filter inside the law
        (``clipped-optimal-wk``); an explicit ``dt`` in ``options`` wins.
    options : dict
        Keyword options (gains) of the law (``controller_options``).

    Raises
    ------
    ValueError
        Unknown or fully active law, bad options.

    """
    return make_controller(name, params=car_params, damper_only=True,
                           **{'dt': 1.0 / float(rate_hz), **options})


def reconfigure(changes, supervisor, *, core=None, make_law=None, command_input=None,
                lock=None):
    """
    Apply changed node parameters to the controller cores, all or nothing.

    The one place the car and the controller node turn a ``ros2 param set`` into core calls:
    every change is validated first (the new law built, the supervisor and command input
    settings checked), then all are applied, so a refused change leaves everything as it was.

    Parameters
    ----------
    changes : dict
        Parameter name -> new value; names of :data:`SUPERVISOR_PARAMETERS`,
        ``controller_options`` (JSON object of the law's keyword options) and
        ``command_timeout_s`` [s].
    supervisor : semi_active_control.supervision.failsafe.ModelSupervisor
        Gets the supervisor settings.
    core : ControllerCore, optional
        Gets the new law (``controller_options``); None: no built-in law.
    make_law : callable, optional
        ``make_law(options_dict)`` -> law; raises ValueError on bad options.
    command_input : quarter_car_sim.runtime.command_input.CommandInput, optional
        Gets ``command_timeout_s`` and ``safe_current_a`` (external controller): anything with
        ``timeout_s``, ``safe_current_a``, ``check_settings(timeout_s, safe_current_a)``
        (raises ValueError) and ``reconfigure(timeout_s=..., safe_current_a=...)``.
    lock : context manager, optional
        Held while the changes are applied only, not while the new law is built and the
        settings checked (an LQR design takes milliseconds: a control loop that needs the
        lock every step must not wait for it).

    Returns
    -------
    str
        ``''`` when applied, else the reason nothing was.

    """
    unknown = sorted(set(changes) - set(SUPERVISOR_PARAMETERS)
                     - {'controller_options', 'command_timeout_s'})
    if unknown:
        return f'not changeable while running: {", ".join(unknown)}'
    law = None
    if 'controller_options' in changes:
        if core is None or make_law is None:
            return 'controller_options: no built-in controller (controller:=external)'
        try:
            options = json.loads(changes['controller_options'] or '{}')
            if not isinstance(options, dict):
                raise ValueError('not a JSON object')
            law = make_law(options)
            if getattr(law, 'kind', None) not in ('current', 'semi-active'):
                raise ValueError(f'a {getattr(law, "kind", "?")} law cannot drive an MR damper')
        except (ValueError, TypeError) as exc:
            return f'controller_options refused: {exc}'
    if 'command_timeout_s' in changes and command_input is None:
        return 'command_timeout_s: only with controller:=external'
    sup_changes = {SUPERVISOR_PARAMETERS[k]: v for k, v in changes.items()
                   if k in SUPERVISOR_PARAMETERS}
    try:
        supervisor.check_settings(**sup_changes)
        if command_input is not None:
            command_input.check_settings(
                changes.get('command_timeout_s', command_input.timeout_s),
                changes.get('safe_current_a', command_input.safe_current_a))
    except (SupervisorError, ValueError) as exc:
        return str(exc)
    with lock if lock is not None else contextlib.nullcontext():
        if sup_changes:
            supervisor.reconfigure(**sup_changes)
        if command_input is not None:
            command_input.reconfigure(timeout_s=changes.get('command_timeout_s'),
                                      safe_current_a=changes.get('safe_current_a'))
        if law is not None:
            core.set_controller(law)
    return ''
