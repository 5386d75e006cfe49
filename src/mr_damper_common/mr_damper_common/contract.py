"""
The wire contracts the cores share with the message conversions (no ROS import).

- :data:`PISTON_JOINT`, :data:`COIL_JOINT`: the joint names of a measurement in a
  ``sensor_msgs/JointState`` (topics and bags): the piston carries x, v and the force, the coil
  carries the current (as its effort);
- :data:`KWOK_CURRENT_NAMES`: the ten parameters of the current-dependent Kwok model in the
  order ``mr_damper_interfaces/KwokParameters`` and the model
  (:class:`mr_damper_model.models.kwok_current.KwokCurrent`) use them;
- :class:`CornerState`: one corner of a vehicle at one instant, the content of
  ``mr_damper_interfaces/QuarterCarState`` (conversions:
  :func:`mr_damper_common.messages.corner_state_from_msg`,
  :func:`~mr_damper_common.messages.corner_state_to_msg`). The simulated cars produce it, the
  estimators publish it, the laws and the controller cores read it;
- :class:`IdentifiedSet`: one identified Kwok-current parameter set, the content of
  ``mr_damper_interfaces/KwokParameters`` and of a parameter file (conversions:
  :meth:`IdentifiedSet.from_flat`, :meth:`IdentifiedSet.from_params_file`,
  :func:`mr_damper_common.messages.identified_set_from_msg`,
  :func:`~mr_damper_common.messages.kwok_parameters_msg`).

Every package may import this module (it depends on nothing of the suite), so a producer and a
consumer of one contract always share one type.
"""
import dataclasses
import math

PISTON_JOINT = 'mr_damper_piston'
COIL_JOINT = 'mr_damper_coil'
KWOK_CURRENT_NAMES = ('c0', 'c1', 'k', 'alpha0', 'alpha1', 'alpha2', 'beta0', 'beta1', 'delta',
                      'f0')

_NAN = math.nan


@dataclasses.dataclass(frozen=True, slots=True)
class CornerState:
    """
    One corner of a vehicle at one instant (SI, positive up, from the static equilibrium).

    What a simulated car computes, an estimator estimates and a ``QuarterCarState`` message
    carries. A field that is not measured is NaN: the laws read ``v_s``, ``a_s``, ``v_u``,
    ``travel`` and ``v_rel`` (and the LQR laws the tyre deflection ``z_u - z_r``), and a
    controller core refuses a state where a field its law reads is not finite. Sign
    conventions: :mod:`semi_active_control.car.quarter_car`.

    Attributes
    ----------
    t : float
        Time stamp [s].
    z_s, v_s, a_s : float
        Body (sprung mass, the body point above the wheel in a full car): absolute vertical
        displacement [m], velocity [m/s] (skyhook, hybrid), acceleration [m/s^2] (ADD).
    z_u, v_u, a_u : float
        Wheel (unsprung mass): displacement [m], velocity [m/s] (groundhook, hybrid),
        acceleration [m/s^2].
    z_r : float
        Road height under the tyre [m].
    travel : float
        Suspension travel ``z_s - z_u`` [m], extension positive (the inverse model).
    v_rel : float
        Suspension (piston) velocity ``v_s - v_u`` [m/s] (every law and the inverse model).
    tyre_force : float
        Total tyre contact force [N] (>= 0; 0 = wheel off the road).
    damper_force : float
        Damper force on the body [N], positive up.
    coil_current : float
        Actual coil current [A].

    """

    t: float
    z_s: float = _NAN
    v_s: float = _NAN
    a_s: float = _NAN
    z_u: float = _NAN
    v_u: float = _NAN
    a_u: float = _NAN
    z_r: float = _NAN
    travel: float = _NAN
    v_rel: float = _NAN
    tyre_force: float = _NAN
    damper_force: float = _NAN
    coil_current: float = _NAN


#: Fields of :class:`CornerState`, in order.
CORNER_FIELDS = tuple(f.name for f in dataclasses.fields(CornerState))


class IdentifiedSetError(ValueError):
    """
    A mapping or file that is not an identified set.

    ``reason`` is the fail-safe supervisor's name for it (``'missing'``: a needed element is
    absent, ``'non_finite'``: an element is not a number).
    """

    def __init__(self, reason, message):
        super().__init__(message)
        self.reason = reason


#: Elements of a set besides the ten parameters, with their default (the message's unknown).
SET_FIELDS = {'i_ref_a': 2.0, 'current_min_a': _NAN, 'current_max_a': _NAN, 'valid': False,
              'reason': '', 'window_start_s': _NAN, 'window_end_s': _NAN, 'rmse_n': _NAN,
              'nrmse_percent': _NAN, 'stamp_s': _NAN}


@dataclasses.dataclass(frozen=True)
class IdentifiedSet:
    """
    One identified Kwok-current parameter set: ``mr_damper_interfaces/KwokParameters`` typed.

    The live identifier produces it, the fail-safe supervisors and estimators take it, a
    parameter file holds one. Conversions: :meth:`from_flat` (a flat name -> value mapping),
    :meth:`from_params_file` (the content of a parameter file),
    :func:`mr_damper_common.messages.identified_set_from_msg` and
    :func:`~mr_damper_common.messages.kwok_parameters_msg` (the message); :meth:`to_flat` and
    :meth:`to_dict` give JSON-ready views.

    Attributes
    ----------
    parameters : dict
        The ten Kwok-current parameters by name (:data:`KWOK_CURRENT_NAMES`, SI units), as
        floats (NaN allowed: the supervisor refuses them).
    i_ref_a : float
        Reference current of the model [A].
    current_min_a, current_max_a : float
        Current range the set was identified over [A] (NaN: unknown).
    valid : bool
        The identifier's verdict.
    reason : str
        Why not valid (``''`` when valid).
    window_start_s, window_end_s : float
        Sample times of the fitted window [s] (NaN: unknown).
    rmse_n, nrmse_percent : float
        Fit quality [N], [%] (NaN: unknown).
    stamp_s : float
        Header stamp of the message [s] (NaN: not from a message).

    """

    parameters: dict
    i_ref_a: float = 2.0
    current_min_a: float = _NAN
    current_max_a: float = _NAN
    valid: bool = False
    reason: str = ''
    window_start_s: float = _NAN
    window_end_s: float = _NAN
    rmse_n: float = _NAN
    nrmse_percent: float = _NAN
    stamp_s: float = _NAN

    def __post_init__(self):
        params = {}
        missing = [n for n in KWOK_CURRENT_NAMES if n not in self.parameters]
        if missing:
            raise IdentifiedSetError('missing', 'missing ' + ', '.join(missing))
        for n in KWOK_CURRENT_NAMES:
            params[n] = _number(n, self.parameters[n])
        object.__setattr__(self, 'parameters', params)
        for n in ('i_ref_a', 'current_min_a', 'current_max_a', 'window_start_s',
                  'window_end_s', 'rmse_n', 'nrmse_percent', 'stamp_s'):
            object.__setattr__(self, n, _number(n, getattr(self, n)))
        object.__setattr__(self, 'valid', bool(self.valid))
        object.__setattr__(self, 'reason', str(self.reason or ''))

    @classmethod
    def from_flat(cls, values):
        """
        Build a set from one flat mapping (the ten parameters and the other elements by name).

        Parameters
        ----------
        values : mapping
            The ten parameters of :data:`KWOK_CURRENT_NAMES` and any of :data:`SET_FIELDS`
            (absent: the default there). ``valid`` is true only when it equals 1 (``True``,
            ``1``, ``1.0``).

        Returns
        -------
        IdentifiedSet

        Raises
        ------
        IdentifiedSetError
            ``'missing'`` (a parameter absent, or ``values`` no mapping), ``'non_finite'`` (an
            element that is not a number).

        """
        if not hasattr(values, 'keys'):
            raise IdentifiedSetError('missing', 'a set is a name -> value mapping, got '
                                     f'{type(values).__name__}')
        extra = {n: values[n] for n in SET_FIELDS if n in values and n != 'valid'}
        return cls({n: values[n] for n in KWOK_CURRENT_NAMES if n in values},
                   valid=valid_flag(values.get('valid', False)), **extra)

    @classmethod
    def from_params_file(cls, content):
        """
        Build a set from a Kwok-current parameter file's content.

        Parameters
        ----------
        content : mapping or object
            The file's dictionary (``parameters``, ``model_options`` with ``i_ref_a``,
            ``current_min_a``, ``current_max_a``, ``valid``), or an object with those
            attributes (``mr_damper_model.io.params_file.ParamsFile``, an identification
            result). A file without a current range is taken as identified over 0-2 A (the
            suite's coil range); one without ``valid`` as valid.

        Returns
        -------
        IdentifiedSet

        """
        if hasattr(content, 'keys'):
            get = content.get
        else:
            def get(name, default=None):
                return getattr(content, name, default)
        opts = dict(get('model_options', None) or {})
        lo, hi = get('current_min_a', None), get('current_max_a', None)
        lo = 0.0 if lo is None or not math.isfinite(float(lo)) else float(lo)
        hi = 2.0 if hi is None or not math.isfinite(float(hi)) else float(hi)
        return cls(dict(get('parameters', None) or {}), i_ref_a=opts.get('i_ref_a', 2.0),
                   current_min_a=lo, current_max_a=hi, valid=get('valid', True))

    def to_flat(self):
        """Return the set as one flat JSON-ready dict (the parameters and every element)."""
        return {**self.parameters, **{n: getattr(self, n) for n in SET_FIELDS}}

    def to_dict(self):
        """Return the set as a JSON-ready dict with the parameters under ``parameters``."""
        return {'parameters': dict(self.parameters),
                **{n: getattr(self, n) for n in SET_FIELDS}}

    def replace(self, **changes):
        """Return a copy with some elements changed (checked as at construction)."""
        return dataclasses.replace(self, **changes)


def _number(name, value):
    """Return ``value`` as a float; IdentifiedSetError('non_finite') naming it if it is none."""
    try:
        return float(value)
    except (TypeError, ValueError):
        raise IdentifiedSetError('non_finite', f'{name} = {value!r}') from None


def valid_flag(value):
    """Return True for a validity flag equal to 1 (a number or a bool), else False."""
    try:
        return float(value) == 1.0
    except (TypeError, ValueError):
        return False
