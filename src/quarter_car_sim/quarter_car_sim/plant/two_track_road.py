"""
Two-track roads for the full car: left and right ISO 8608 tracks, the rear axle delayed.

:class:`TwoTrackRoad` holds a left and a right track sampled in time as the **rear** axle
drives them; the front axle is ``delay_s = wheelbase / speed`` ahead. :meth:`TwoTrackRoad.at`
gives the heights and vertical velocities under ``fl, fr, rl, rr``: the front wheels read the
tracks at ``t + delay_s`` and the rear wheels at ``t``, so a rear wheel sees exactly what the
front wheel on its side saw ``delay_s`` earlier, and both axles are on generated road from
t = 0.

Coherence of the two tracks: the isotropic road model (Robson, "Road surface description and
its application to vehicle response studies", Journal of Sound and Vibration 1979; Kamash and
Robson, "The application of isotropy in road surface modelling", JSV 1978). An isotropic
surface whose profiles have the ISO 8608 displacement PSD ``G(n) = G0 (n/n0)^-2`` (waviness 2)
has, between two parallel tracks ``B`` apart, the real cross-spectrum ``rho(n) G(n)`` with ::

    rho(n) = u K1(u),   u = 2 pi n B

(K1 the modified Bessel function of the second kind; rho -> 1 for long waves, -> 0 for short
ones). The left track is :func:`quarter_car_sim.plant.road.iso8608` itself; the right track's
Fourier coefficients are ``rho c_L + sqrt(1 - rho^2) |c_L| exp(i psi)`` with independent random
phases ``psi``: its PSD is G(n) and its squared coherence with the left track ``rho^2`` (both in
expectation over the phases).
"""
import dataclasses
import math

import numpy as np
from scipy.special import k1

from quarter_car_sim.plant import road as qroad
from quarter_car_sim.plant.road import RoadError


def isotropic_coherence(n, track_m):
    """
    Coherence function ``rho(n) = u K1(u)``, ``u = 2 pi n B``, of the isotropic ISO road.

    Parameters
    ----------
    n : array_like
        Spatial frequency [cycles/m], >= 0.
    track_m : float
        Distance between the two tracks B [m].

    Returns
    -------
    ndarray
        Real normalised cross-spectrum in [0, 1] (its square is the squared coherence).

    """
    n = np.atleast_1d(np.asarray(n, dtype=float))
    u = 2.0 * math.pi * n * float(track_m)
    out = np.ones_like(u)
    pos = u > 0
    out[pos] = u[pos] * k1(u[pos])
    return out


@dataclasses.dataclass(frozen=True)
class TwoTrackRoad:
    """
    Left and right road tracks sampled in time as the rear axle meets them.

    Attributes
    ----------
    t : ndarray with shape (n,)
        Track time [s], uniform from 0 (the rear axle's time).
    z_left, z_right : ndarray with shape (n,)
        Track heights [m].
    zdot_left, zdot_right : ndarray with shape (n,)
        Their time derivatives [m/s].
    delay_s : float
        Time the front axle is ahead of the rear [s] (wheelbase / speed).
    name : str
        Description.
    speed_m_s : float
        Speed [m/s] (nan for a road given in time only).

    """

    t: np.ndarray
    z_left: np.ndarray
    z_right: np.ndarray
    zdot_left: np.ndarray
    zdot_right: np.ndarray
    delay_s: float = 0.0
    name: str = ''
    speed_m_s: float = float('nan')

    def __post_init__(self):
        # the quarter-car road checks shape, finiteness and a uniform time axis
        for z, zd in ((self.z_left, self.zdot_left), (self.z_right, self.zdot_right)):
            qroad.RoadProfile(self.t, z, zd)
        if not (math.isfinite(self.delay_s) and self.delay_s >= 0.0):
            raise RoadError(f'`delay_s` must be >= 0, got {self.delay_s}')
        for f in ('t', 'z_left', 'z_right', 'zdot_left', 'zdot_right'):
            object.__setattr__(self, f, np.asarray(getattr(self, f), dtype=float))
        object.__setattr__(self, '_dt', float(self.t[1] - self.t[0]))
        object.__setattr__(self, '_lists', (self.z_left.tolist(), self.z_right.tolist(),
                                            self.zdot_left.tolist(), self.zdot_right.tolist()))

    @property
    def dt(self):
        """Sample interval [s]."""
        return self._dt

    @property
    def duration(self):
        """Time [s] both axles are on the generated tracks (track length minus the delay)."""
        return float(self.t[-1] - self.t[0]) - self.delay_s

    def _sample(self, s):
        """Heights and velocities (left, right) at track time ``s`` (held beyond the ends)."""
        zl, zr, dl, dr = self._lists
        u = (s - self.t[0]) / self._dt
        if u <= 0.0:
            return zl[0], zr[0], 0.0, 0.0
        k = int(u)
        if k >= len(zl) - 1:
            return zl[-1], zr[-1], 0.0, 0.0
        a = u - k
        return (zl[k] + a * (zl[k + 1] - zl[k]), zr[k] + a * (zr[k + 1] - zr[k]),
                dl[k] + a * (dl[k + 1] - dl[k]), dr[k] + a * (dr[k + 1] - dr[k]))

    def at(self, t):
        """
        Road under the four wheels at time ``t`` [s].

        Returns
        -------
        z, zdot : ndarray with shape (4,)
            Heights [m] and vertical velocities [m/s] under ``fl, fr, rl, rr``.

        """
        lf, rf, dlf, drf = self._sample(t + self.delay_s)
        lr, rr, dlr, drr = self._sample(t)
        return np.array([lf, rf, lr, rr]), np.array([dlf, drf, dlr, drr])

    def corner_series(self, t):
        """Heights under ``fl, fr, rl, rr`` [m] at the times ``t``, shape (len(t), 4)."""
        t = np.asarray(t, dtype=float)
        out = np.empty((t.size, 4))
        for j, (z, s) in enumerate(((self.z_left, t + self.delay_s),
                                    (self.z_right, t + self.delay_s),
                                    (self.z_left, t), (self.z_right, t))):
            out[:, j] = np.interp(s, self.t, z)
        return out


def _check_geometry(wheelbase_m, track_m):
    for name, v in (('wheelbase_m', wheelbase_m), ('track_m', track_m)):
        if not (math.isfinite(v) and v > 0):
            raise RoadError(f'`{name}` must be > 0, got {v}')


def iso8608_two_tracks(road_class, speed_m_s, duration_s, *, wheelbase_m, track_m, dt=1e-3,
                       rng=None, coherence='isotropic'):
    """
    Two correlated ISO 8608 tracks (isotropic coherence) for a car of a wheelbase and track.

    Parameters
    ----------
    road_class : str
        ISO 8608 class 'A' ... 'H'.
    speed_m_s : float
        Speed [m/s].
    duration_s : float
        Time both axles drive on generated road [s] (the tracks are ``delay`` longer).
    wheelbase_m, track_m : float
        Wheelbase (sets the rear delay) and distance between the tracks [m].
    dt : float
        Sample interval [s].
    rng : None, int or numpy Generator
        Seed (left phases first, then the right track's own phases).
    coherence : {'isotropic', 'identical', 'independent'}
        Isotropic model (default); identical tracks (rho = 1, no roll input); or independent
        tracks (rho = 0).

    Returns
    -------
    TwoTrackRoad

    """
    _check_geometry(wheelbase_m, track_m)
    v = qroad._check_speed(speed_m_s)
    delay = wheelbase_m / v
    gen = np.random.default_rng(rng)
    left = qroad.iso8608(road_class, v, float(duration_s) + delay, dt, gen)
    n = left.n
    length = n * v * dt
    c_l = np.fft.rfft(left.z)
    nk = np.arange(c_l.size) / length
    if coherence == 'isotropic':
        rho = isotropic_coherence(nk, track_m)
    elif coherence == 'identical':
        rho = np.ones(nk.size)
    elif coherence == 'independent':
        rho = np.zeros(nk.size)
    else:
        raise RoadError(f"`coherence` must be 'isotropic', 'identical' or 'independent', "
                        f'got {coherence!r}')
    psi = gen.uniform(0.0, 2.0 * math.pi, nk.size)
    c_r = rho * c_l + np.sqrt(1.0 - rho ** 2) * np.abs(c_l) * np.exp(1j * psi)
    z_r = np.fft.irfft(c_r, n=n)
    zd_r = np.fft.irfft(c_r * (2j * math.pi * nk), n=n) * v
    seed = f' seed {rng}' if isinstance(rng, (int, np.integer)) else ''
    return TwoTrackRoad(left.t, left.z, z_r, left.zdot, zd_r, delay_s=delay,
                        name=f'iso8608-{road_class.upper()}@{v:g}m/s two tracks{seed}',
                        speed_m_s=v)


#: Events of :func:`event_road`: (height [m], length [m], sides).
EVENTS = {
    'bump': (0.05, 1.0, 'both'),          # speed bump across the road
    'pothole': (-0.05, 0.6, 'left'),      # one wheel track drops into a hole
    'single-bump': (0.05, 1.0, 'left'),   # a bump under the left wheels only
}


def event_road(kind, speed_m_s=10.0, duration_s=3.0, *, wheelbase_m, dt=1e-3, start_s=0.5,
               height=None, length=None, side=None):
    """
    Discrete event: a bump, a pothole or a single-side bump, as half sines.

    Parameters
    ----------
    kind : str
        ``'bump'`` (5 cm x 1 m, both tracks), ``'pothole'`` (5 cm deep x 0.6 m, left track) or
        ``'single-bump'`` (5 cm x 1 m, left track); see :data:`EVENTS`.
    speed_m_s, duration_s, dt : float
        Speed [m/s], time on the road [s], sample interval [s].
    wheelbase_m : float
        Wheelbase [m] (rear delay).
    start_s : float
        Time the front wheels reach the event [s].
    height, length : float, optional
        Override the event's height [m] (negative: a hole) and length [m].
    side : {'both', 'left', 'right'}, optional
        Override the tracks that carry the event.

    Returns
    -------
    TwoTrackRoad

    """
    if kind not in EVENTS:
        raise RoadError(f'unknown event {kind!r} (use {", ".join(EVENTS)})')
    _check_geometry(wheelbase_m, 1.0)
    h0, l0, s0 = EVENTS[kind]
    h = h0 if height is None else float(height)
    ln = l0 if length is None else float(length)
    sd = s0 if side is None else side
    if sd not in ('both', 'left', 'right'):
        raise RoadError(f"`side` must be 'both', 'left' or 'right', got {sd!r}")
    v = qroad._check_speed(speed_m_s)
    delay = wheelbase_m / v
    ev = qroad.bump(h, ln, v, float(duration_s) + delay, dt, start_s=float(start_s) + delay)
    flat = np.zeros(ev.n)
    zl, dl = (ev.z, ev.zdot) if sd in ('both', 'left') else (flat, flat)
    zr, dr = (ev.z, ev.zdot) if sd in ('both', 'right') else (flat, flat)
    return TwoTrackRoad(ev.t, zl, zr, dl, dr, delay_s=delay,
                        name=f'{kind} {h:g} m x {ln:g} m ({sd}) @{v:g}m/s', speed_m_s=v)


def same_road_all_wheels(profile):
    """
    One quarter-car road under all four wheels at once (no rear delay): heave input only.

    Parameters
    ----------
    profile : quarter_car_sim.plant.road.RoadProfile
        Road under every wheel.

    Returns
    -------
    TwoTrackRoad

    """
    return TwoTrackRoad(profile.t, profile.z, profile.z, profile.zdot, profile.zdot,
                        delay_s=0.0, name=f'{profile.name} (all wheels)',
                        speed_m_s=profile.speed_m_s)


def make_two_track_road(spec, params, *, speed_m_s=20.0, duration_s=30.0, dt=1e-3, rng=None):
    """
    Two-track road from a short spec (the command line's).

    Parameters
    ----------
    spec : str
        ``'iso8608-C'`` (any class), or an event of :data:`EVENTS`.
    params : FullCarParams
        Car (wheelbase, track).
    speed_m_s, duration_s, dt, rng
        As for :func:`iso8608_two_tracks`.

    Returns
    -------
    TwoTrackRoad

    """
    s = str(spec).strip().lower()
    track = 0.5 * (params.track_f + params.track_r)
    if s.startswith('iso8608'):
        cls = s[len('iso8608'):].lstrip('-_: ') or 'C'
        return iso8608_two_tracks(cls.upper(), speed_m_s, duration_s,
                                  wheelbase_m=params.wheelbase, track_m=track, dt=dt, rng=rng)
    if s in EVENTS:
        return event_road(s, speed_m_s, duration_s, wheelbase_m=params.wheelbase, dt=dt)
    raise RoadError(f'unknown road {spec!r} (use iso8608-A..H, {", ".join(EVENTS)})')
