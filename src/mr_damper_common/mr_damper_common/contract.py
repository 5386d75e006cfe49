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
  :func:`mr_damper_common.messages.corner_state_from_msg`, :func:`~mr_damper_common.messages.
  corner_state_to_msg`). The simulated cars produce it, the estimators publish it, the laws and
  the controller cores read it.

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
