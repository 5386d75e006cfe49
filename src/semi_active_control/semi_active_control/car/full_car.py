"""
Full-vehicle (7-DOF) parameters, corner geometry and sign conventions.

Coordinates (ISO 8855: x forward, y left, z up), all from the static equilibrium on a flat road:

- body heave ``z`` [m] at the centre of gravity (CG), positive up;
- body pitch ``theta`` [rad] about y, positive nose **down** (right hand about y: a front
  corner moves by ``-a theta``, a rear one by ``+b theta``);
- body roll ``phi`` [rad] about x, positive left side **up** (a left corner moves by
  ``+w phi``);
- wheel displacements ``z_u`` [m] of the four corners, positive up.

Corners are in the order of the suite's ``--corners``: ``fl, fr, rl, rr``. Corner ``i`` sits at
``(x_i, y_i)`` = ``(a, +tf/2)``, ``(a, -tf/2)``, ``(-b, +tr/2)``, ``(-b, -tr/2)`` and its body
point moves by ``z - x_i theta + y_i phi``. Suspension travel, damper and tyre forces follow the
quarter car (:mod:`semi_active_control.car.quarter_car`): travel = body point - wheel
(extension +), the damper force acts on the body (+ up), the tyre cannot pull.

Default set :data:`PASSENGER_CAR`: the full vertical car model of Table 1 of "Designing a
Kalman-Bucy state estimator for a full vertical car model", *Mathematical Problems in
Engineering*, vol. 2023, article ID 6941084 (a compact passenger car; the table cites its own
sources): sprung mass 1150 kg, pitch inertia 861.8 kg m^2, roll inertia 330.5 kg m^2, CG to
front axle 1.116 m, to rear axle 1.232 m, CG to each wheel laterally 0.621 m (track 1.242 m),
springs 30 kN/m front and 32.5 kN/m rear, tyres 181 kN/m, unsprung masses 30.2 kg (the
table's wheels 1 and 4, the wheels with the front springs) and 49.7 kg (wheels 2 and 3, rear).
The table's viscous dampers (1400 N s/m front, 1600 rear) are replaced by one MR damper per
corner; they are kept as :data:`PASSENGER_CAR_VISCOUS` for a conventional reference car. The
corner sprung masses (302 kg front, 273 kg rear) are the size of the default quarter car
(300 kg), so the thesis-scale MR damper of the suite fits every corner. No anti-roll bars in
the source: ``k_arb_f``, ``k_arb_r`` default to 0.
"""
import dataclasses

import numpy as np

from semi_active_control.car.quarter_car import check_fields, ParamsError, QuarterCarParams

#: Corner names, in order.
CORNERS = ('fl', 'fr', 'rl', 'rr')

#: Body degrees of freedom, in order, then the four wheels.
DOF_NAMES = ('heave', 'pitch', 'roll', 'z_u_fl', 'z_u_fr', 'z_u_rl', 'z_u_rr')


@dataclasses.dataclass(frozen=True)
class FullCarParams:
    """
    Linear part of the 7-DOF full car (SI units; see the module docstring for conventions).

    Parameters
    ----------
    m_s : float
        Sprung (body) mass [kg].
    i_pitch, i_roll : float
        Body moments of inertia about the lateral (y) and longitudinal (x) axes through the CG
        [kg m^2].
    a, b : float
        Distances CG to front axle and CG to rear axle [m] (wheelbase ``a + b``).
    track_f, track_r : float
        Front and rear track widths [m].
    m_u_f, m_u_r : float
        Unsprung mass of one front / rear corner [kg].
    k_s_f, k_s_r : float
        Suspension spring rate at one front / rear wheel [N/m].
    k_t : float
        Tyre vertical stiffness [N/m] (every wheel).
    c_t : float
        Tyre damping [N s/m] (default 0).
    c_s_f, c_s_r : float
        Linear viscous damping in parallel with each corner's damper plant [N s/m] (default 0:
        all damping from the plants).
    k_arb_f, k_arb_r : float
        Anti-roll bar rate [N/m] at the wheel: the bar pushes the two wheels of an axle
        towards equal travel with ``k_arb (travel_left - travel_right)`` (0: no bar).
    g : float
        Gravity [m/s^2].
    i_min, i_max : float
        Coil current range of every damper [A].

    """

    m_s: float = 1150.0
    i_pitch: float = 861.8
    i_roll: float = 330.5
    a: float = 1.116
    b: float = 1.232
    track_f: float = 1.242
    track_r: float = 1.242
    m_u_f: float = 30.2
    m_u_r: float = 49.7
    k_s_f: float = 30000.0
    k_s_r: float = 32500.0
    k_t: float = 181000.0
    c_t: float = 0.0
    c_s_f: float = 0.0
    c_s_r: float = 0.0
    k_arb_f: float = 0.0
    k_arb_r: float = 0.0
    g: float = 9.81
    i_min: float = 0.0
    i_max: float = 2.0

    def __post_init__(self):
        check_fields(self, positive=('m_s', 'i_pitch', 'i_roll', 'a', 'b', 'track_f',
                                     'track_r', 'm_u_f', 'm_u_r', 'k_s_f', 'k_s_r', 'k_t'),
                     non_negative=('c_t', 'c_s_f', 'c_s_r', 'k_arb_f', 'k_arb_r', 'g', 'i_min'))
        if self.i_max <= self.i_min:
            raise ParamsError(f'`i_max` ({self.i_max}) must be > `i_min` ({self.i_min})')

    @property
    def wheelbase(self):
        """Wheelbase ``a + b`` [m]."""
        return self.a + self.b

    @property
    def x(self):
        """Longitudinal corner positions [m] from the CG (forward +), shape (4,)."""
        return np.array([self.a, self.a, -self.b, -self.b])

    @property
    def y(self):
        """Lateral corner positions [m] from the CG (left +), shape (4,)."""
        return np.array([self.track_f, -self.track_f, self.track_r, -self.track_r]) / 2.0

    @property
    def geometry(self):
        """
        Corner map ``T`` with shape (4, 3): body-point displacements = ``T @ [z, theta, phi]``.

        Its transpose maps four corner forces (up on the body) to heave force [N], pitch moment
        [N m] (nose down +) and roll moment [N m] (left up +).
        """
        return np.column_stack([np.ones(4), -self.x, self.y])

    @property
    def m_u(self):
        """Unsprung masses per corner [kg], shape (4,)."""
        return np.array([self.m_u_f, self.m_u_f, self.m_u_r, self.m_u_r])

    @property
    def k_s(self):
        """Spring rates per corner [N/m], shape (4,)."""
        return np.array([self.k_s_f, self.k_s_f, self.k_s_r, self.k_s_r])

    @property
    def c_s(self):
        """Parallel viscous damping per corner [N s/m], shape (4,)."""
        return np.array([self.c_s_f, self.c_s_f, self.c_s_r, self.c_s_r])

    @property
    def sprung_share(self):
        """Static share of the sprung mass on each corner [kg]: ``m_s b / (2 L)`` front."""
        L = self.wheelbase
        return self.m_s * np.array([self.b, self.b, self.a, self.a]) / (2.0 * L)

    @property
    def static_tyre_loads(self):
        """Static tyre load per wheel [N]: sprung share plus unsprung mass, times g."""
        return (self.sprung_share + self.m_u) * self.g

    @property
    def mass_matrix(self):
        """Diagonal mass matrix (7, 7) [kg, kg m^2] of ``[z, theta, phi, z_u x4]``."""
        return np.diag([self.m_s, self.i_pitch, self.i_roll, *self.m_u])

    def spring_matrix(self):
        """
        Suspension stiffness (4, 4) [N/m] acting on the corner travels (springs + bars).

        Returns
        -------
        ndarray
            ``Ks`` such that the spring forces on the body are ``-Ks @ travel``.

        """
        ks = np.diag(self.k_s)
        for i, j, k in ((0, 1, self.k_arb_f), (2, 3, self.k_arb_r)):
            ks[i, i] += k
            ks[j, j] += k
            ks[i, j] -= k
            ks[j, i] -= k
        return ks

    def corner(self, i):
        """
        Quarter car of corner ``i`` with the corner's static sprung-mass share.

        Returns
        -------
        QuarterCarParams

        """
        return QuarterCarParams(m_s=float(self.sprung_share[i]), m_u=float(self.m_u[i]),
                                k_s=float(self.k_s[i]), k_t=self.k_t, c_t=self.c_t,
                                c_s=float(self.c_s[i]), g=self.g, i_min=self.i_min,
                                i_max=self.i_max)

    def replace(self, **changes):
        """Return a copy with some fields changed (validated)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self):
        """Return the parameters as a plain dict (SI units)."""
        return dataclasses.asdict(self)


#: The default passenger car (see the module docstring for the source).
PASSENGER_CAR = FullCarParams()

#: The same car with the source's viscous dampers (1400 N s/m front, 1600 rear).
PASSENGER_CAR_VISCOUS = FullCarParams(c_s_f=1400.0, c_s_r=1600.0)


def symmetric_car(*, m_s=1200.0, i_pitch=None, i_roll=None, half_wheelbase=1.3,
                  track=1.5, m_u=40.0, k_s=25000.0, k_t=180000.0, k_arb=0.0):
    """
    Make a car symmetric front/rear and left/right (the analytic test cases).

    ``i_pitch`` and ``i_roll`` default to the dynamic index 1 values ``m_s l^2`` and
    ``m_s (track/2)^2``.

    Returns
    -------
    FullCarParams

    """
    l, w = float(half_wheelbase), float(track) / 2.0
    return FullCarParams(
        m_s=m_s, i_pitch=m_s * l * l if i_pitch is None else i_pitch,
        i_roll=m_s * w * w if i_roll is None else i_roll, a=l, b=l, track_f=track,
        track_r=track, m_u_f=m_u, m_u_r=m_u, k_s_f=k_s, k_s_r=k_s, k_t=k_t, k_arb_f=k_arb,
        k_arb_r=k_arb)
