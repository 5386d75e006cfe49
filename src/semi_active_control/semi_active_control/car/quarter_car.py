"""
Quarter-car parameters (SI units) and sign conventions.

Sign conventions used everywhere in :mod:`quarter_car_sim`:

- vertical displacements ``z_s`` (body / sprung mass), ``z_u`` (wheel / unsprung mass) and
  ``z_r`` (road) are positive **up** [m], measured from the static equilibrium on a flat road;
- suspension travel ``travel = z_s - z_u`` [m] (positive = extension), and its rate
  ``v_rel = v_s - v_u`` [m/s] is the damper piston velocity (extension positive);
- ``damper_force`` is the force the damper applies **on the body**, positive up [N]. A damper
  model force ``F`` (positive when resisting extension, the load-cell convention of the rig) acts
  on the body as ``-F``; a passive damper therefore always has ``damper_force * v_rel <= 0``;
- ``tyre_force`` is the total (static + dynamic) vertical contact force [N], never negative: the
  tyre cannot pull the wheel down, so the wheel may leave the road.

The default set is a generic passenger-car corner of the size used throughout the quarter-car
literature (a few hundred kg sprung, sprung/unsprung mass ratio 5, body bounce near 1.1 Hz and
wheel hop near 9 Hz): m_s = 300 kg, m_u = 60 kg, k_s = 16 kN/m, k_t = 190 kN/m, no tyre damping.
"""
import dataclasses
import math


class ParamsError(ValueError):
    """Invalid quarter-car parameter (the message names the parameter)."""


def check_fields(params, *, positive=(), non_negative=()):
    """
    Coerce every field of a frozen parameter dataclass to a finite float and check signs.

    Parameters
    ----------
    params : dataclass instance
        Parameters (changed in place with ``object.__setattr__``).
    positive, non_negative : sequence of str
        Fields that must be > 0 and >= 0.

    Raises
    ------
    ParamsError
        Naming the first bad field.

    """
    for f in dataclasses.fields(params):
        val = getattr(params, f.name)
        try:
            val = float(val)
        except (TypeError, ValueError):
            raise ParamsError(f'`{f.name}` must be a number, got {val!r}') from None
        if not math.isfinite(val):
            raise ParamsError(f'`{f.name}` must be finite, got {val}')
        object.__setattr__(params, f.name, val)
    for name in positive:
        if getattr(params, name) <= 0.0:
            raise ParamsError(f'`{name}` must be > 0, got {getattr(params, name)}')
    for name in non_negative:
        if getattr(params, name) < 0.0:
            raise ParamsError(f'`{name}` must be >= 0, got {getattr(params, name)}')


@dataclasses.dataclass(frozen=True)
class QuarterCarParams:
    """
    Linear part of the quarter car.

    Parameters
    ----------
    m_s : float
        Sprung (body) mass [kg].
    m_u : float
        Unsprung (wheel, hub, brake) mass [kg].
    k_s : float
        Suspension spring stiffness [N/m].
    k_t : float
        Tyre vertical stiffness [N/m].
    c_t : float
        Tyre damping [N s/m] (default 0).
    c_s : float
        Linear viscous damping in parallel with the damper plant [N s/m] (default 0: all the
        suspension damping comes from the damper plant; used for linear reference cases).
    g : float
        Gravity [m/s^2] (sets the static tyre load and so the lift-off threshold).
    i_min, i_max : float
        Coil current range of the damper [A] (the command is saturated to it).

    """

    m_s: float = 300.0
    m_u: float = 60.0
    k_s: float = 16000.0
    k_t: float = 190000.0
    c_t: float = 0.0
    c_s: float = 0.0
    g: float = 9.81
    i_min: float = 0.0
    i_max: float = 2.0

    def __post_init__(self):
        check_fields(self, positive=('m_s', 'm_u', 'k_s', 'k_t'),
                     non_negative=('c_t', 'c_s', 'g', 'i_min'))
        if self.i_max <= self.i_min:
            raise ParamsError(f'`i_max` ({self.i_max}) must be > `i_min` ({self.i_min})')

    @property
    def static_tyre_load(self):
        """Static tyre load (m_s + m_u) g [N]."""
        return (self.m_s + self.m_u) * self.g

    def replace(self, **changes):
        """Return a copy with some fields changed (validated)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self):
        """Return the parameters as a plain dict (SI units)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d):
        """Build from a dict; unknown keys raise :class:`ParamsError` naming them."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ParamsError(f'unknown quarter-car parameter(s): {", ".join(unknown)}')
        return cls(**d)
