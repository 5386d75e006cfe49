"""
Model supervisor of the quarter-car controller: accept identified damper models or fail safe.

The controller turns a demanded damper force into a coil current through the inverse of the
current-dependent Kwok model identified live. This module decides, message by message and tick
by tick, whether such a model may be used. A parameter set is accepted only if

- the identifier marked it valid (``valid == 1``),
- every element needed by the inverse model is present and finite,
- every Kwok-current parameter lies inside the physical box bounds of the model
  (``get_model('kwok-current').default_bounds()`` of ``mr_damper_model``),
- ``i_ref_a`` is positive and the identified current range ``[current_min_a, current_max_a]``
  is ordered, inside the coil's range (small tolerance) and at least ``min_current_span_a``
  wide: a model fitted at one current level (the identifier publishes it as kwok-current with
  zero current slopes) cannot say which current makes a force, so using it would be a guess;
  the caller also keeps its inverse inside the identified range (no extrapolation),
- no parameter is pinned at a non-zero bound of that box (within ``pinned_fraction`` of the
  bound span; the identifier's rule, :mod:`mr_damper_model.models.validity`): a fit stopped at
  the edge of the search box is one that data outside the physical range (typically a sensor
  fault) pushed there, whatever the identifier concluded,

and it stays usable only while it is younger than ``timeout_s``. Its age counts from its
header stamp when the stamp is on the caller's clock, from its receipt otherwise: a set that sat
in a queue (a starved machine) is as old as its stamp says, and one received already older than
``timeout_s`` is refused (``'stale_on_arrival'``), never used. A stamp that is unset (zero),
ahead of the caller's clock, or more than ``max_transit_s`` behind it is taken for another
clock's (a replay's simulated time, an unsynchronised host) and the age counts from receipt
(counted in ``stamps_not_used``). Otherwise the supervisor is in fail-safe mode and the caller
commands ``safe_current_a``: never a guess from a stale or rejected model. An invalid or
out-of-range message drops the model in use at once (the identifier has just said the damper no
longer matches it), unless ``hold_on_reject`` is set, in which case the previous model stays in
use until it goes stale.

The module is pure Python/numpy (no ROS): the node feeds it decoded sets
(:class:`mr_damper_common.contract.IdentifiedSet`) and times.
"""
from dataclasses import dataclass, field, replace
import math

import numpy as np

from mr_damper_common.contract import (IdentifiedSet, IdentifiedSetError, KWOK_CURRENT_NAMES,
                                       valid_flag)
from mr_damper_model.models.validity import check_parameter_values, PINNED_FRACTION


#: Reasons the supervisor reports (``mode == 'failsafe'``) or counts (rejections).
REASONS = (
    'ok',                 # normal mode: a valid, fresh model is in use
    'no_parameters_yet',  # nothing accepted since start
    'stale',              # the model in use is older than the timeout
    'invalid_flag',       # the identifier published valid != 1
    'missing',            # an element the inverse model needs is absent
    'non_finite',         # NaN or inf in a needed element
    'out_of_bounds',      # a parameter outside the physical box bounds
    'bad_i_ref',          # i_ref_a <= 0 (checked, or refused when the message is decoded)
    'bad_current_range',  # current_min_a/current_max_a disordered / off-range
    'narrow_current_range',  # identified over less than min_current_span_a
    'pinned_at_bound',    # a parameter at a non-zero bound of the box (fit pushed off range)
    'undecodable',        # the message could not be decoded (bad layout); see :meth:`refuse`
    'stale_on_arrival',   # received already older than the timeout (by its header stamp)
)

#: Default of :attr:`ModelSupervisor.max_transit_s` [s]: a set stamped longer than this before
#: its receipt was stamped on another clock; its age counts from receipt.
MAX_TRANSIT_S = 60.0


class SupervisorError(ValueError):
    """Invalid configuration of a :class:`ModelSupervisor`."""


def kwok_current_bounds():
    """
    Physical box bounds of the current-dependent Kwok model, by parameter name.

    Returns
    -------
    dict
        ``{name: (low, high)}`` from ``mr_damper_model``'s ``KwokCurrent.default_bounds()``.

    """
    from mr_damper_model.models import get_model  # lazy: keeps this module light to import
    model = get_model('kwok-current')
    lo, hi = model.default_bounds()
    return {n: (float(a), float(b)) for n, a, b in zip(model.param_names, lo, hi)}


@dataclass
class Verdict:
    """
    Outcome of offering one parameter message to the supervisor.

    Attributes
    ----------
    accepted : bool
        True when the set passed every check and is now the model in use.
    reason : str
        ``'ok'`` or the first failed check (one of :data:`REASONS`).
    detail : str
        Human-readable detail (parameter name and value for bound violations).

    """

    accepted: bool
    reason: str
    detail: str = ''


#: The suite's coil current settings of a supervised damper [A]: the fail-safe current, the
#: driver's range and the narrowest identified current range accepted. The defaults of the
#: controller nodes' parameters (``semi_active_control.nodes.common``) and of the offline
#: vehicle chain (``quarter_car_sim.simulate.vehicle_chain``).
COIL_SETTINGS = {'safe_current_a': 0.5, 'i_min_a': 0.0, 'i_max_a': 2.0, 'min_current_span_a': 1.0}


@dataclass
class ModelSupervisor:
    """
    Accept identified Kwok-current parameter sets, or fall back to a safe constant current.

    Parameters
    ----------
    timeout_s : float
        Maximum age [s] of the model in use, counted from its stamp (module docstring) or its
        receipt; older means fail-safe.
    safe_current_a : float
        Coil current [A] commanded in fail-safe mode (a passive damper setting).
    i_min_a, i_max_a : float
        Coil current range [A] of the damper driver.
    bounds : dict, optional
        ``{name: (low, high)}`` physical bounds; default :func:`kwok_current_bounds`.
    current_tol_a : float
        Tolerance [A] on the identified current range against ``[i_min_a, i_max_a]``.
    hold_on_reject : bool
        Keep the model in use when a later message is rejected (until it goes stale).
    min_current_span_a : float
        Minimum width [A] of the identified current range ``current_max_a - current_min_a``.
    pinned_fraction : float
        A parameter within this fraction of its bound span from a non-zero bound is pinned
        (refused, ``'pinned_at_bound'``); same rule as the identifier's.
    max_transit_s : float
        Longest time [s] from a set's header stamp to its receipt taken as transit on one
        clock; a stamp further behind is another clock's (age from receipt).

    Raises
    ------
    SupervisorError
        On a non-positive timeout, a disordered current range, or a safe current outside it.

    """

    timeout_s: float = 1.0
    safe_current_a: float = 0.0
    i_min_a: float = 0.0
    i_max_a: float = 2.0
    bounds: dict = None
    current_tol_a: float = 0.05
    hold_on_reject: bool = False
    min_current_span_a: float = 1.0
    pinned_fraction: float = PINNED_FRACTION
    max_transit_s: float = MAX_TRANSIT_S
    # state (not constructor arguments in practice)
    params: IdentifiedSet = field(default=None, init=False)
    accepted_at: float = field(default=None, init=False)
    first_valid_at: float = field(default=None, init=False)
    mode: str = field(default='failsafe', init=False)
    reason: str = field(default='no_parameters_yet', init=False)
    failsafe_s: float = field(default=0.0, init=False)
    n_accepted: int = field(default=0, init=False)
    n_failsafe_entries: int = field(default=0, init=False)
    rejected: dict = field(default_factory=dict, init=False)
    stamps_not_used: dict = field(default_factory=dict, init=False)
    last_detail: str = field(default='', init=False)
    _last_t: float = field(default=None, init=False)

    def __post_init__(self):
        for name in ('timeout_s', 'safe_current_a', 'i_min_a', 'i_max_a', 'current_tol_a',
                     'min_current_span_a', 'pinned_fraction', 'max_transit_s'):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise SupervisorError(f'`{name}` must be a finite number, got {value!r}.')
        if not 0 <= self.pinned_fraction < 0.5:
            raise SupervisorError(
                f'`pinned_fraction` must be in [0, 0.5), got {self.pinned_fraction}.')
        if self.max_transit_s <= 0:
            raise SupervisorError(f'`max_transit_s` must be > 0 s, got {self.max_transit_s}.')
        if self.timeout_s <= 0:
            raise SupervisorError(f'`timeout_s` must be > 0 s, got {self.timeout_s}.')
        if not self.i_min_a < self.i_max_a:
            raise SupervisorError(
                f'`i_min_a` ({self.i_min_a}) must be below `i_max_a` ({self.i_max_a}).')
        if not self.i_min_a <= self.safe_current_a <= self.i_max_a:
            raise SupervisorError(
                f'`safe_current_a` ({self.safe_current_a} A) must lie in '
                f'[{self.i_min_a}, {self.i_max_a}] A.')
        if self.bounds is None:
            self.bounds = kwok_current_bounds()
        missing = [n for n in KWOK_CURRENT_NAMES if n not in self.bounds]
        if missing:
            raise SupervisorError(f'`bounds` lacks {", ".join(missing)}.')
        self.rejected = {r: 0 for r in REASONS[3:]}
        self.stamps_not_used = {'unset': 0, 'future': 0, 'other_clock': 0}

    #: Settings :meth:`reconfigure` may change while the supervisor runs.
    RECONFIGURABLE = ('timeout_s', 'safe_current_a', 'hold_on_reject', 'min_current_span_a',
                      'current_tol_a', 'pinned_fraction')

    def reconfigure(self, **changes):
        """
        Change settings while running, all or nothing, validated as at construction.

        Parameters
        ----------
        **changes
            Any of :data:`RECONFIGURABLE` (same meaning and units as the constructor's).
            The new values apply from the next :meth:`update` / :meth:`offer`: a shorter
            ``timeout_s`` can make the model in use stale at once, a stricter threshold
            applies to the next message (the model in use stays).

        Raises
        ------
        SupervisorError
            An unknown setting or an invalid value (nothing changed).

        """
        self.check_settings(**changes)
        for name, value in changes.items():
            setattr(self, name, bool(value) if name == 'hold_on_reject' else value)

    def check_settings(self, **changes):
        """Raise :class:`SupervisorError` if :meth:`reconfigure` would refuse ``changes``."""
        unknown = sorted(set(changes) - set(self.RECONFIGURABLE))
        if unknown:
            raise SupervisorError(f'cannot change {", ".join(unknown)} while running '
                                  f'(only {", ".join(self.RECONFIGURABLE)})')
        replace(self, **changes)          # runs __post_init__: raises on an invalid value

    # ------------------------------------------------------------------ checks
    def check(self, identified):
        """
        Check one identified set without changing the supervisor.

        Parameters
        ----------
        identified : mr_damper_common.contract.IdentifiedSet or mapping
            The set, as decoded from ``/mr_damper/kwok_parameters``
            (:func:`mr_damper_common.messages.identified_set_from_msg`); a flat name -> value
            mapping is converted first (:func:`as_identified_set`: a missing element or one
            that is not a number is refused as ``'missing'`` / ``'non_finite'``).

        Returns
        -------
        Verdict

        """
        identified, refusal = as_identified_set(identified)
        if refusal is not None:
            return refusal
        s = identified
        if not s.valid:
            return Verdict(False, 'invalid_flag',
                           'valid = False' + (f' ({s.reason})' if s.reason else ''))
        params = s.parameters
        for name, value in (*params.items(), ('i_ref_a', s.i_ref_a),
                            ('current_min_a', s.current_min_a),
                            ('current_max_a', s.current_max_a)):
            if not math.isfinite(value):
                return Verdict(False, 'non_finite', f'{name} = {value}')
        lo = [self.bounds[n][0] for n in KWOK_CURRENT_NAMES]
        hi = [self.bounds[n][1] for n in KWOK_CURRENT_NAMES]
        # the identifier's rule for the values (mr_damper_model.models.validity), same tolerances
        values_check = check_parameter_values(
            KWOK_CURRENT_NAMES, [params[n] for n in KWOK_CURRENT_NAMES], lo, hi,
            pinned_fraction=self.pinned_fraction)
        if values_check.reason == 'out_of_bounds':
            return Verdict(False, 'out_of_bounds', ', '.join(
                f'{n} = {params[n]:g} not in [{self.bounds[n][0]:g}, {self.bounds[n][1]:g}]'
                for n in values_check.names))
        lo_a, hi_a = s.current_min_a, s.current_max_a
        tol = self.current_tol_a
        if s.i_ref_a <= 0:
            return Verdict(False, 'bad_i_ref', f'i_ref_a = {s.i_ref_a:g} <= 0')
        if not (self.i_min_a - tol <= lo_a <= hi_a <= self.i_max_a + tol):
            return Verdict(False, 'bad_current_range',
                           f'identified current range [{lo_a:g}, {hi_a:g}] A not ordered inside '
                           f'[{self.i_min_a:g}, {self.i_max_a:g}] A')
        if hi_a - lo_a < self.min_current_span_a - tol:
            return Verdict(False, 'narrow_current_range',
                           f'identified over [{lo_a:g}, {hi_a:g}] A only (need a span of '
                           f'{self.min_current_span_a:g} A)')
        if values_check.reason == 'pinned_at_bound':
            return Verdict(False, 'pinned_at_bound',
                           ', '.join(f'{n} = {params[n]:g} at a bound {self.bounds[n]}'
                                     for n in values_check.names))
        return Verdict(True, 'ok')

    # ------------------------------------------------------------------ events
    def offer(self, identified, t_now):
        """
        Offer a received identified set; accept it or count the reason it is refused.

        Parameters
        ----------
        identified : mr_damper_common.contract.IdentifiedSet or mapping
            Decoded set, see :meth:`check`.
        t_now : float
            Receipt time [s] on the caller's clock (the clock later passed to :meth:`update`).

        Returns
        -------
        Verdict
            An accepted set received already older than ``timeout_s`` by its stamp is
            refused as ``'stale_on_arrival'``.

        """
        identified, refusal = as_identified_set(identified)
        if refusal is not None:
            return self._apply(refusal, None, t_now)
        verdict = self.check(identified)
        since = float(t_now)
        if verdict.accepted:
            since = self._stamp_or_receipt(identified.stamp_s, since)
            if t_now - since > self.timeout_s:
                verdict = Verdict(False, 'stale_on_arrival',
                                  f'stamped {t_now - since:.3f} s before its receipt '
                                  f'(timeout {self.timeout_s:g} s)')
        return self._apply(verdict, identified, t_now, since)

    def _stamp_or_receipt(self, stamp_s, t_now):
        """Return the time a set's age counts from: its stamp on this clock, else ``t_now``."""
        if not (math.isfinite(stamp_s) and stamp_s > 0):
            kind = 'unset'
        elif stamp_s > t_now:
            kind = 'future'
        elif t_now - stamp_s > self.max_transit_s:
            kind = 'other_clock'
        else:
            return float(stamp_s)
        self.stamps_not_used[kind] += 1
        return t_now

    def offer_decoded(self, decode, raw, t_now):
        """
        Decode a received message with ``decode`` and offer the set; refuse what fails to decode.

        Parameters
        ----------
        decode : callable
            ``decode(raw)`` -> :class:`~mr_damper_common.contract.IdentifiedSet`, raising
            ValueError (with a ``reason`` attribute when it has one, e.g. ``'bad_i_ref'``) for
            a message it cannot decode
            (:func:`mr_damper_common.messages.identified_set_from_msg`).
        raw : object
            The received message.
        t_now : float
            Receipt time [s].

        Returns
        -------
        Verdict
            A message the decoder refuses is refused by the decoder's reason when the
            supervisor knows it, else as ``'undecodable'``.

        """
        try:
            identified = decode(raw)
        except ValueError as exc:
            reason = getattr(exc, 'reason', None)
            return self.refuse(reason if reason in self.rejected else 'undecodable', str(exc),
                               t_now)
        return self.offer(identified, t_now)

    def refuse(self, reason, detail, t_now):
        """
        Count a message the caller could not even decode, as a rejection with ``reason``.

        Parameters
        ----------
        reason : str
            One of the rejection :data:`REASONS` (``'undecodable'``, or the decoder's own
            reason when it names one of them, e.g. ``'bad_i_ref'``).
        detail : str
            Human-readable detail.
        t_now : float
            Receipt time [s].

        Returns
        -------
        Verdict

        """
        if reason not in self.rejected:
            raise SupervisorError(
                f'`reason` must be one of {sorted(self.rejected)}, got {reason!r}.')
        return self._apply(Verdict(False, reason, detail), None, t_now)

    def _apply(self, verdict, identified, t_now, since=None):
        if verdict.accepted:
            self.params = identified
            self.accepted_at = float(t_now if since is None else since)
            self.n_accepted += 1
            if self.first_valid_at is None:
                self.first_valid_at = float(t_now)
        else:
            self.rejected[verdict.reason] += 1
            self.last_detail = verdict.detail
            if not self.hold_on_reject:
                self.params = None
                self.accepted_at = None
                self._set_mode('failsafe', verdict.reason)
        self.update(t_now)
        return verdict

    def update(self, t_now):
        """
        Advance the supervisor to time ``t_now`` and return the mode.

        Accumulates the time spent in fail-safe (the interval since the previous call counts
        towards the mode that held during it) and drops a model older than ``timeout_s``.

        Parameters
        ----------
        t_now : float
            Time [s] on the caller's clock; non-decreasing between calls.

        Returns
        -------
        str
            ``'normal'`` or ``'failsafe'``.

        """
        t_now = float(t_now)
        if self._last_t is not None and t_now > self._last_t and self.mode == 'failsafe':
            self.failsafe_s += t_now - self._last_t
        if self._last_t is None or t_now > self._last_t:
            self._last_t = t_now
        if self.params is not None and t_now - self.accepted_at > self.timeout_s:
            self.params = None
            self.accepted_at = None
            self._set_mode('failsafe', 'stale')
        elif self.params is not None:
            self._set_mode('normal', 'ok')
        return self.mode

    def _set_mode(self, mode, reason):
        if mode == 'failsafe' and self.mode != 'failsafe':
            self.n_failsafe_entries += 1
        self.mode = mode
        if mode == 'normal' or reason != 'ok':
            self.reason = reason

    # ------------------------------------------------------------------ outputs
    @property
    def active(self):
        """
        Return the identified set in use, or None in fail-safe mode.

        An :class:`~mr_damper_common.contract.IdentifiedSet`: the ten Kwok-current parameters,
        ``i_ref_a``, ``current_min_a``, ``current_max_a`` and what the identifier said.
        """
        return self.params if self.mode == 'normal' else None

    def age(self, t_now):
        """Return the age [s] of the model in use at ``t_now``, or NaN if none."""
        return float(t_now) - self.accepted_at if self.accepted_at is not None else math.nan

    def status(self):
        """
        Summarise the supervisor as a JSON-ready dict.

        Returns
        -------
        dict
            ``mode``, ``reason``, ``failsafe_s`` [s], ``failsafe_entries``, ``params_accepted``,
            ``params_rejected`` (reason -> count), ``stamps_not_used`` (``unset``, ``future``,
            ``other_clock``: sets aged from receipt), ``last_reject_detail``,
            ``safe_current_a``.

        """
        return {
            'mode': self.mode,
            'reason': self.reason,
            'failsafe_s': self.failsafe_s,
            'failsafe_entries': self.n_failsafe_entries,
            'params_accepted': self.n_accepted,
            'params_rejected': dict(self.rejected),
            'stamps_not_used': dict(self.stamps_not_used),
            'last_reject_detail': self.last_detail,
            'safe_current_a': self.safe_current_a,
        }


def as_identified_set(values):
    """
    Return ``(set, None)`` for an identified set or a flat mapping, or ``(None, Verdict)``.

    A mapping (the flat layout of :meth:`~mr_damper_common.contract.IdentifiedSet.from_flat`)
    is refused as ``'invalid_flag'`` when its ``valid`` is not 1, whatever else it holds; as
    ``'missing'`` when it lacks one of the ten parameters, ``i_ref_a``, ``current_min_a``,
    ``current_max_a`` or ``valid`` (the supervisor takes no default for them); as
    ``'non_finite'`` when an element is not a number.
    """
    if isinstance(values, IdentifiedSet):
        return values, None
    if not hasattr(values, 'keys'):
        return None, Verdict(False, 'missing', 'message is not a name -> value mapping')
    if 'valid' in values and not valid_flag(values['valid']):
        return None, Verdict(False, 'invalid_flag', f'valid = {values["valid"]!r}')
    needed = KWOK_CURRENT_NAMES + ('i_ref_a', 'current_min_a', 'current_max_a', 'valid')
    missing = [n for n in needed if n not in values]
    if missing:
        return None, Verdict(False, 'missing', 'missing ' + ', '.join(missing))
    try:
        return IdentifiedSet.from_flat(values), None
    except IdentifiedSetError as exc:
        return None, Verdict(False, exc.reason, str(exc))


def clip_current(i_cmd, i_min_a, i_max_a, fallback_a):
    """
    Clip a current command to the coil range; a non-finite command becomes ``fallback_a``.

    Parameters
    ----------
    i_cmd : float or array_like
        Requested coil current [A].
    i_min_a, i_max_a : float
        Coil current range [A].
    fallback_a : float
        Current [A] used where ``i_cmd`` is NaN or infinite.

    Returns
    -------
    float or numpy.ndarray
        Command [A] within ``[i_min_a, i_max_a]``.

    """
    if isinstance(i_cmd, (float, int)):
        # a scalar, each control step: plain floats (numpy's scalar overhead was 40 % of the
        # car's command; the same values as the array path)
        i = float(i_cmd)
        if not math.isfinite(i):
            i = float(fallback_a)
        return min(max(i, i_min_a), i_max_a)
    arr = np.asarray(i_cmd, dtype=float)
    out = np.where(np.isfinite(arr), arr, fallback_a)
    out = np.clip(out, i_min_a, i_max_a)
    return float(out) if out.ndim == 0 else out
