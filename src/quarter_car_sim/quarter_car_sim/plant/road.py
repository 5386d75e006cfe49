"""
Road profiles sampled in time for the quarter car: ISO 8608 random roads, bump, sine, step, CSV.

Every profile is a :class:`RoadProfile` with uniformly sampled time ``t`` [s], height ``z`` [m]
(positive up) and its time derivative ``zdot`` [m/s]; the quarter car interpolates ``z``
linearly between samples.

ISO 8608 roads are synthesised from the standard's displacement PSD
``Gd(n) = Gd(n0) (n / n0)^-2`` (waviness w = 2, n0 = 0.1 cycles/m) with the geometric-mean
``Gd(n0)`` of each class (A 16e-6 m^3, each next class x4, H 262144e-6 m^3), as a sum of cosines
on the discrete-Fourier grid ``n_k = k / L`` of the travelled length L with amplitudes
``sqrt(2 Gd(n_k) dn)`` and independent uniform random phases (evaluated with an inverse FFT, so
the one-sided PSD of the profile is Gd(n) on ``n_min <= n <= n_max``, zero outside). The
standard's band is 0.011 to 2.83 cycles/m (the constants: :mod:`semi_active_control.iso8608`).
"""
import csv
import dataclasses
import math
from pathlib import Path

import numpy as np

from semi_active_control.iso8608 import ISO8608_BAND, ISO8608_GD_N0, ISO8608_N0


class RoadError(ValueError):
    """Invalid road request or road file (the message names the argument or file)."""


@dataclasses.dataclass(frozen=True)
class RoadProfile:
    """
    A road height profile sampled uniformly in time.

    Attributes
    ----------
    t : ndarray with shape (n,)
        Time [s], uniform, starting at 0.
    z : ndarray with shape (n,)
        Road height under the tyre [m], positive up.
    zdot : ndarray with shape (n,)
        Vertical road velocity dz/dt [m/s].
    name : str
        Description (e.g. ``'iso8608-C@20m/s seed 1'``).
    speed_m_s : float
        Vehicle speed [m/s] (nan when the profile is given in time only).
    periodic : bool
        The car drives the profile again and again (period ``n * dt``) instead of holding it
        flat after its end. ISO 8608 profiles are synthesised periodic (an inverse FFT), so
        they repeat seamlessly: a drive of any length needs only one period in memory.

    """

    t: np.ndarray
    z: np.ndarray
    zdot: np.ndarray
    name: str = ''
    speed_m_s: float = float('nan')
    periodic: bool = False

    def __post_init__(self):
        t = np.asarray(self.t, dtype=float)
        z = np.asarray(self.z, dtype=float)
        zd = np.asarray(self.zdot, dtype=float)
        if t.ndim != 1 or t.size < 2:
            raise RoadError('`t` must be 1-D with at least 2 samples')
        if z.shape != t.shape or zd.shape != t.shape:
            raise RoadError('`t`, `z` and `zdot` must have the same shape')
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(z)) and np.all(np.isfinite(zd))):
            raise RoadError('road profile contains non-finite values')
        d = np.diff(t)
        if np.any(d <= 0) or np.ptp(d) > 1e-6 * d.mean():
            raise RoadError('`t` must be uniformly spaced and increasing')
        object.__setattr__(self, 't', t)
        object.__setattr__(self, 'z', z)
        object.__setattr__(self, 'zdot', zd)

    @property
    def dt(self):
        """Sample interval [s]."""
        return float(self.t[1] - self.t[0])

    @property
    def duration(self):
        """Duration t[-1] - t[0] [s]."""
        return float(self.t[-1] - self.t[0])

    @property
    def n(self):
        """Number of samples."""
        return int(self.t.size)

    def height(self, t):
        """Road height at time(s) ``t`` [m] (linear interpolation, held beyond the ends)."""
        return np.interp(t, self.t, self.z)


def _n_samples(duration_s, dt):
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise RoadError(f'`duration_s` must be > 0, got {duration_s}')
    if not (math.isfinite(dt) and dt > 0):
        raise RoadError(f'`dt` must be > 0, got {dt}')
    return int(round(duration_s / dt)) + 1


def _check_speed(speed_m_s):
    if not (math.isfinite(speed_m_s) and speed_m_s > 0):
        raise RoadError(f'`speed_m_s` must be > 0, got {speed_m_s}')
    return float(speed_m_s)


def iso8608_psd(n, road_class):
    """
    ISO 8608 displacement PSD Gd(n) of a class [m^3] at spatial frequencies ``n`` [cycles/m].

    Parameters
    ----------
    n : array_like
        Spatial frequency [cycles/m], > 0.
    road_class : str
        'A' ... 'H'.

    Returns
    -------
    ndarray
        ``Gd(n0) (n / n0)^-2`` [m^3].

    """
    gd0 = ISO8608_GD_N0[_check_class(road_class)]
    n = np.asarray(n, dtype=float)
    return gd0 * (n / ISO8608_N0) ** -2.0


def _check_class(road_class):
    c = str(road_class).strip().upper()
    if c not in ISO8608_GD_N0:
        raise RoadError(f'unknown ISO 8608 road class {road_class!r} (use A..H)')
    return c


def iso8608(road_class, speed_m_s, duration_s, dt=1e-3, rng=None, *, n_min=ISO8608_BAND[0],
            n_max=ISO8608_BAND[1]):
    """
    Random ISO 8608 road of a class, as driven at constant speed.

    Parameters
    ----------
    road_class : str
        ISO 8608 class 'A' (very good) ... 'H' (very poor).
    speed_m_s : float
        Vehicle speed [m/s], > 0.
    duration_s : float
        Duration [s].
    dt : float
        Sample interval [s] (default 1 ms); spatial spacing is ``speed_m_s * dt``.
    rng : None, int or numpy Generator
        Seed for the random phases (``np.random.default_rng(rng)``).
    n_min, n_max : float
        Spatial band [cycles/m] (default the standard's 0.011 to 2.83); ``n_max`` is capped at
        the spatial Nyquist frequency ``1 / (2 speed dt)``.

    Returns
    -------
    RoadProfile
        Profile with exact analytic ``zdot``; the one-sided spatial PSD is the class's Gd(n)
        inside the band.

    """
    c = _check_class(road_class)
    v = _check_speed(speed_m_s)
    n = _n_samples(duration_s, dt)
    if not (0 < n_min < n_max):
        raise RoadError(f'need 0 < `n_min` < `n_max`, got {n_min}, {n_max}')
    gen = np.random.default_rng(rng)
    dx = v * dt
    length = n * dx
    k = np.arange(n // 2 + 1)
    nk = k / length
    nyq = 0.5 / dx
    band = (nk >= n_min) & (nk <= min(n_max, nyq)) & (k > 0) & (k < n / 2)
    amp = np.zeros(nk.size)
    amp[band] = np.sqrt(2.0 * iso8608_psd(nk[band], c) / length)
    phase = gen.uniform(0.0, 2.0 * np.pi, nk.size)
    coef = 0.5 * n * amp * np.exp(1j * phase)
    z = np.fft.irfft(coef, n=n)
    dzdx = np.fft.irfft(coef * (2j * np.pi * nk), n=n)
    t = np.arange(n) * dt
    seed_txt = '' if rng is None or not isinstance(rng, (int, np.integer)) else f' seed {rng}'
    return RoadProfile(t, z, dzdx * v, name=f'iso8608-{c}@{v:g}m/s{seed_txt}', speed_m_s=v)


def bump(height=0.05, length=1.0, speed_m_s=10.0, duration_s=3.0, dt=1e-3, *, start_s=0.5):
    """
    Make a single half-sine bump, speed-bump like, of a height and length at constant speed.

    Parameters
    ----------
    height : float
        Bump height [m] (negative for a pothole-like dip).
    length : float
        Bump length along the road [m], > 0.
    speed_m_s : float
        Speed [m/s], > 0.
    duration_s, dt : float
        Duration and sample interval [s].
    start_s : float
        Time at which the tyre reaches the bump [s].

    Returns
    -------
    RoadProfile

    """
    v = _check_speed(speed_m_s)
    if not (math.isfinite(length) and length > 0):
        raise RoadError(f'`length` must be > 0, got {length}')
    if not math.isfinite(height):
        raise RoadError('`height` must be finite')
    t = np.arange(_n_samples(duration_s, dt)) * dt
    s = (t - start_s) * v / length
    inside = (s >= 0) & (s <= 1)
    z = np.where(inside, height * np.sin(np.pi * np.clip(s, 0, 1)), 0.0)
    zd = np.where(inside, height * np.pi * v / length * np.cos(np.pi * np.clip(s, 0, 1)), 0.0)
    return RoadProfile(t, z, zd, name=f'bump {height:g} m x {length:g} m @{v:g}m/s',
                       speed_m_s=v)


def sine(amplitude=0.01, frequency_hz=1.0, duration_s=10.0, dt=1e-3):
    """
    Sinusoidal road input ``amplitude * sin(2 pi f t)`` [m] (frequency in time, [Hz]).

    Returns
    -------
    RoadProfile

    """
    if not (math.isfinite(frequency_hz) and frequency_hz > 0):
        raise RoadError(f'`frequency_hz` must be > 0, got {frequency_hz}')
    if not math.isfinite(amplitude):
        raise RoadError('`amplitude` must be finite')
    t = np.arange(_n_samples(duration_s, dt)) * dt
    w = 2.0 * np.pi * frequency_hz
    return RoadProfile(t, amplitude * np.sin(w * t), amplitude * w * np.cos(w * t),
                       name=f'sine {amplitude:g} m {frequency_hz:g} Hz')


def step(height=0.02, duration_s=3.0, dt=1e-3, *, start_s=0.5):
    """
    Step of a height at ``start_s`` [s] (a kerb: the rise takes one sample interval).

    Returns
    -------
    RoadProfile

    """
    if not math.isfinite(height):
        raise RoadError('`height` must be finite')
    t = np.arange(_n_samples(duration_s, dt)) * dt
    z = np.where(t >= start_s, float(height), 0.0)
    zd = np.zeros_like(z)
    k = int(np.argmax(t >= start_s)) if np.any(t >= start_s) else 0
    if k > 0:
        zd[k - 1] = height / dt
    return RoadProfile(t, z, zd, name=f'step {height:g} m')


_TIME_COLS = ('t', 'time', 'time_s')
_DIST_COLS = ('distance', 'x', 'distance_m', 's')
_HEIGHT_COLS = ('height', 'z', 'height_m', 'z_r', 'elevation')


def from_csv(path, speed_m_s=None, dt=1e-3, duration_s=None):
    """
    Road profile from a CSV file with a header: a time or distance column and a height column.

    Parameters
    ----------
    path : str or Path
        CSV file. Columns (case-insensitive): time ``t`` [s] (or ``time``), or distance
        ``distance`` [m] (or ``x``, ``s``); and height ``height`` [m] (or ``z``, ``elevation``).
    speed_m_s : float, optional
        Speed [m/s]; required for a distance profile.
    dt : float
        Resampling interval [s] (linear interpolation).
    duration_s : float, optional
        Duration [s]; default the profile's length. Beyond its end the last height is held.

    Returns
    -------
    RoadProfile

    Raises
    ------
    RoadError
        One line naming the file and the problem (missing, no header, missing column, too few
        rows, non-numeric or non-finite values, non-increasing time/distance, no speed).

    """
    p = Path(path)
    if not p.is_file():
        raise RoadError(f'{p}: road file not found')
    try:
        with p.open(newline='') as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise RoadError(f'{p}: cannot read road file ({exc})') from None
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise RoadError(f'{p}: road file is empty')
    header = [h.strip().lower() for h in rows[0]]

    def col(names):
        for nm in names:
            if nm in header:
                return header.index(nm)
        return None

    it, ix, iz = col(_TIME_COLS), col(_DIST_COLS), col(_HEIGHT_COLS)
    if iz is None or (it is None and ix is None):
        raise RoadError(f'{p}: need a header with a time (t) or distance column and a height '
                        f'column, got {",".join(header)}')
    ia = it if it is not None else ix
    try:
        data = np.array([[float(r[ia]), float(r[iz])] for r in rows[1:]], dtype=float)
    except (ValueError, IndexError):
        raise RoadError(f'{p}: non-numeric or missing value in the road file') from None
    if data.shape[0] < 2:
        raise RoadError(f'{p}: need at least 2 data rows')
    if not np.all(np.isfinite(data)):
        raise RoadError(f'{p}: road file contains NaN or infinite values')
    a, zz = data[:, 0], data[:, 1]
    if np.any(np.diff(a) <= 0):
        raise RoadError(f'{p}: the {header[ia]} column must be strictly increasing')
    if it is None:
        if speed_m_s is None:
            raise RoadError(f'{p}: a distance profile needs a speed')
        v = _check_speed(speed_m_s)
        tt = (a - a[0]) / v
    else:
        v = float('nan') if speed_m_s is None else _check_speed(speed_m_s)
        tt = a - a[0]
    dur = float(tt[-1]) if duration_s is None else float(duration_s)
    t = np.arange(_n_samples(dur, dt)) * dt
    z = np.interp(t, tt, zz)
    zd = np.gradient(z, dt)
    return RoadProfile(t, z, zd, name=f'file {p.name}', speed_m_s=v)


def make_road(spec, *, speed_m_s=20.0, duration_s=60.0, dt=1e-3, rng=None, road_class='C',
              file='', repeat=False):
    """
    Road from a short text spec: the one road factory (command line, car node, report).

    Parameters
    ----------
    spec : str
        ``'iso8608-C'`` (any class A..H; bare ``'iso8608'`` takes ``road_class``), ``'bump'``
        (0.05 m x 1 m half-sine), ``'sine'`` (10 mm at 1.2 Hz), ``'step'`` (20 mm), ``'file'``
        (the CSV profile ``file``) or a path to a CSV file.
    speed_m_s, duration_s, dt, rng
        As for :func:`iso8608`: vehicle speed [m/s], road length in time [s] (beyond it the
        last height is held, or the road repeats), sample interval [s], seed of a random road.
    road_class : str
        ISO 8608 class A..H of a bare ``'iso8608'``.
    file : str
        CSV road profile of ``spec='file'``.
    repeat : bool
        Drive the road again and again (``RoadProfile.periodic``): memory stays one road
        length for a drive of any length (ISO 8608 roads repeat seamlessly).

    Returns
    -------
    RoadProfile

    """
    road = _make_road(spec, speed_m_s, duration_s, dt, rng, road_class, file)
    return dataclasses.replace(road, periodic=True) if repeat else road


def _make_road(spec, speed_m_s, duration_s, dt, rng, road_class, file):
    s = str(spec).strip()
    low = s.lower()
    if not (math.isfinite(speed_m_s) and speed_m_s > 0):
        raise RoadError(f'speed must be > 0 m/s, got {speed_m_s}')
    if low.startswith('iso8608'):
        cls = low[len('iso8608'):].lstrip('-_: ') or str(road_class)
        return iso8608(cls.upper(), speed_m_s, duration_s, dt, rng)
    if low == 'bump':
        return bump(speed_m_s=speed_m_s, duration_s=duration_s, dt=dt)
    if low == 'sine':
        return sine(duration_s=duration_s, dt=dt, frequency_hz=1.2)
    if low == 'step':
        return step(duration_s=duration_s, dt=dt)
    if low == 'file':
        if not file:
            raise RoadError('road kind "file" needs the parameter `road_file`')
        return from_csv(file, speed_m_s=speed_m_s, dt=dt, duration_s=duration_s)
    if low.endswith('.csv') or Path(s).exists():
        return from_csv(s, speed_m_s=speed_m_s, dt=dt, duration_s=duration_s)
    raise RoadError(f'unknown road {spec!r} (use iso8608-A..H, bump, sine, step or a CSV file)')
