"""
Rig excitations (piston motion) and coil current schedules.

Every excitation is an analytic function of time: ``exc(t)`` returns ``(x, v)`` (displacement
[m], velocity [m/s], v = dx/dt exactly), for a scalar ``t`` as floats (streaming) or for an array
as arrays. ``center_m`` is the mean position of the motion (the virtual rig starts the Spencer
plant's internal state there, i.e. in its periodic steady state).
"""
import math

import numpy as np

EXCITATION_NAMES = ('cam', 'multisine', 'chirp', 'random')


class ExcitationError(ValueError):
    """Invalid excitation or schedule settings."""


def _positive(value, name):
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise ExcitationError(f'`{name}` must be a positive number, got {value}')
    return value


def _out(t, x, v):
    if np.ndim(t) == 0:
        return float(x), float(v)
    return x, v


class Excitation:
    """Base class: ``__call__(t) -> (x [m], v [m/s])``."""

    name = ''
    center_m = 0.0

    def __call__(self, t):
        """
        Position and velocity at time t.

        Parameters
        ----------
        t : float or array_like
            Time [s].

        Returns
        -------
        tuple
            (x [m], v [m/s]), floats for scalar t, arrays otherwise.

        """
        tt = np.asarray(t, dtype=float)
        x, v = self._eval(tt)
        return _out(t, x, v)

    def position(self, t):
        """Displacement [m] at time t [s]."""
        return self(t)[0]

    def velocity(self, t):
        """Velocity [m/s] at time t [s]."""
        return self(t)[1]


class CamSine(Excitation):
    """
    Cam-driven sine, as on the thesis rig: x = -A cos(2 pi f t) (starts at rest at -A).

    Parameters
    ----------
    freq_hz : float
        Frequency [Hz] (default 1.1).
    amplitude_m : float
        Amplitude [m] (default 0.03; peak velocity 2 pi f A = 0.207 m/s).

    """

    name = 'cam'

    def __init__(self, freq_hz=1.1, amplitude_m=0.03):
        self.freq_hz = _positive(freq_hz, 'freq_hz')
        self.amplitude_m = _positive(amplitude_m, 'amplitude_m')
        self.period_s = 1.0 / self.freq_hz

    def _eval(self, t):
        w = 2.0 * math.pi * self.freq_hz
        return -self.amplitude_m * np.cos(w * t), self.amplitude_m * w * np.sin(w * t)


class _SumOfSines(Excitation):
    """x = sum_k a_k sin(w_k t + phi_k)."""

    def _eval(self, t):
        ph = np.multiply.outer(t, self._w) + self._phi
        x = np.sin(ph) @ self._a
        v = np.cos(ph) @ (self._a * self._w)
        return x, v


class Multisine(_SumOfSines):
    """
    Sum of sines with Schroeder phases (low crest factor).

    Parameters
    ----------
    freqs_hz : sequence of float
        Component frequencies [Hz] (default 0.5, 1.1, 2.3, 4.1).
    amplitudes_m : sequence of float or None
        Component amplitudes [m]; default: equal velocity amplitudes summing to 0.2 m/s.

    """

    name = 'multisine'

    def __init__(self, freqs_hz=(0.5, 1.1, 2.3, 4.1), amplitudes_m=None):
        f = np.asarray(freqs_hz, dtype=float).ravel()
        if f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
            raise ExcitationError('`freqs_hz` must be positive frequencies')
        w = 2 * np.pi * f
        if amplitudes_m is None:
            a = (0.2 / f.size) / w
        else:
            a = np.asarray(amplitudes_m, dtype=float).ravel()
            if a.shape != f.shape or not np.all(np.isfinite(a)) or np.any(a < 0):
                raise ExcitationError('`amplitudes_m` must be one non-negative value per '
                                      'frequency')
        k = np.arange(1, f.size + 1)
        self._w, self._a = w, a
        self._phi = -np.pi * k * (k - 1) / f.size
        self.freqs_hz, self.amplitudes_m = f, a


class BandLimitedRandom(_SumOfSines):
    """
    Band-limited random motion: random-phase multisine with a flat displacement spectrum.

    Parameters
    ----------
    f_lo_hz, f_hi_hz : float
        Band [Hz] (default 0.2 to 5 Hz).
    rms_m : float
        RMS displacement [m] (default 0.01).
    n_components : int
        Number of equally spaced lines in the band (default 200).
    rng : None, int or numpy.random.Generator
        Seed of the phases.

    """

    name = 'random'

    def __init__(self, f_lo_hz=0.2, f_hi_hz=5.0, rms_m=0.01, n_components=200, rng=None):
        f_lo = _positive(f_lo_hz, 'f_lo_hz')
        f_hi = _positive(f_hi_hz, 'f_hi_hz')
        if f_hi <= f_lo:
            raise ExcitationError('`f_hi_hz` must be above `f_lo_hz`')
        n = int(n_components)
        if n < 1:
            raise ExcitationError('`n_components` must be >= 1')
        rms = _positive(rms_m, 'rms_m')
        gen = np.random.default_rng(rng)
        f = np.linspace(f_lo, f_hi, n)
        self._w = 2 * np.pi * f
        self._a = np.full(n, rms * math.sqrt(2.0 / n))
        self._phi = gen.uniform(0.0, 2 * np.pi, n)
        self.rms_m = rms


class Chirp(Excitation):
    """
    Linear chirp x = A sin(phi(t)), frequency f0 -> f1 over ``duration_s``, then f1.

    Parameters
    ----------
    f0_hz, f1_hz : float
        Start and end frequencies [Hz] (default 0.5 and 5).
    duration_s : float
        Sweep time [s] (default 20).
    amplitude_m : float
        Amplitude [m] (default 0.01).

    """

    name = 'chirp'

    def __init__(self, f0_hz=0.5, f1_hz=5.0, duration_s=20.0, amplitude_m=0.01):
        self.f0_hz = _positive(f0_hz, 'f0_hz')
        self.f1_hz = _positive(f1_hz, 'f1_hz')
        self.duration_s = _positive(duration_s, 'duration_s')
        self.amplitude_m = _positive(amplitude_m, 'amplitude_m')

    def _eval(self, t):
        T, f0, f1 = self.duration_s, self.f0_hz, self.f1_hz
        tc = np.minimum(t, T)
        phase = 2 * np.pi * (f0 * tc + 0.5 * (f1 - f0) * tc * tc / T
                             + f1 * np.maximum(t - T, 0.0))
        freq = np.where(t < T, f0 + (f1 - f0) * tc / T, f1)
        A = self.amplitude_m
        return A * np.sin(phase), A * 2 * np.pi * freq * np.cos(phase)


def make_excitation(name='cam', rng=None, *, amplitude_m=None, frequency_hz=None, seed=None,
                    **options):
    """
    Build an excitation by name ('cam', 'multisine', 'chirp', 'random').

    Parameters
    ----------
    name : str
        Excitation name.
    rng : None, int or numpy.random.Generator
        Seed (used by 'random'); ``seed`` is an alias.
    amplitude_m : float or None
        Size of the motion [m]: cam and chirp amplitude, random RMS; multisine: the amplitude of
        every component.
    frequency_hz : float or None
        cam frequency; chirp end frequency; random upper band edge [Hz] (multisine: ignored).
    seed : None or int
        Alias of ``rng``.
    **options
        Other keyword options of the class.

    Returns
    -------
    Excitation

    """
    if rng is None:
        rng = seed
    if name == 'cam':
        if amplitude_m is not None:
            options['amplitude_m'] = amplitude_m
        if frequency_hz is not None:
            options['freq_hz'] = frequency_hz
        return CamSine(**options)
    if name == 'multisine':
        exc = Multisine(**options)
        if amplitude_m is not None:
            exc = Multisine(exc.freqs_hz, np.full(exc.freqs_hz.size, float(amplitude_m)))
        return exc
    if name == 'chirp':
        if amplitude_m is not None:
            options['amplitude_m'] = amplitude_m
        if frequency_hz is not None:
            options['f1_hz'] = frequency_hz
        return Chirp(**options)
    if name == 'random':
        if amplitude_m is not None:
            options['rms_m'] = amplitude_m
        if frequency_hz is not None:
            options['f_hi_hz'] = frequency_hz
        return BandLimitedRandom(rng=rng, **options)
    raise ExcitationError(f'unknown excitation {name!r}; expected one of '
                          f'{", ".join(EXCITATION_NAMES)}')


def step_schedule(levels_a=(0.0, 0.5, 1.0, 1.5, 2.0), hold_s=4 / 1.1):
    """Return ``StepSchedule(levels_a, hold_s)`` (levels [A], time per level [s])."""
    return StepSchedule(levels_a, hold_s)


class CurrentSchedule:
    """Base class: ``__call__(t) -> current [A]``; ``duration_s`` (None if open-ended)."""

    duration_s = None

    def __call__(self, t):
        """Return the current command [A] at time t [s] (float for scalar t)."""
        val = self._eval(np.asarray(t, dtype=float))
        return float(val) if np.ndim(t) == 0 else val


class StepSchedule(CurrentSchedule):
    """
    Current steps, each level held for ``hold_s`` (the last one held afterwards).

    Parameters
    ----------
    levels_a : sequence of float
        Current levels [A] (default 0, 0.5, 1, 1.5, 2, the thesis test conditions).
    hold_s : float
        Time per level [s] (default 4 cam periods at 1.1 Hz, 3.64 s).

    """

    def __init__(self, levels_a=(0.0, 0.5, 1.0, 1.5, 2.0), hold_s=4 / 1.1):
        lv = np.asarray(levels_a, dtype=float).ravel()
        if lv.size == 0 or not np.all(np.isfinite(lv)):
            raise ExcitationError('`levels_a` must be finite currents')
        self.levels_a = lv
        self.hold_s = _positive(hold_s, 'hold_s')
        self.duration_s = lv.size * self.hold_s

    def _eval(self, t):
        k = np.clip(np.floor(t / self.hold_s + 1e-9), 0, self.levels_a.size - 1).astype(int)
        return self.levels_a[k]


class ConstantSchedule(CurrentSchedule):
    """Constant current ``current_a`` [A]."""

    def __init__(self, current_a=0.0):
        self.current_a = float(current_a)
        if not math.isfinite(self.current_a):
            raise ExcitationError('`current_a` must be finite')

    def _eval(self, t):
        return np.full(np.shape(t), self.current_a)


class CommandedSchedule(CurrentSchedule):
    """Externally commanded current: ``set(i)`` changes the value returned from then on."""

    def __init__(self, initial_a=0.0):
        self.current_a = float(initial_a)

    def set(self, current_a):
        """Set the commanded current [A]."""
        current_a = float(current_a)
        if not math.isfinite(current_a):
            raise ExcitationError('commanded current must be finite')
        self.current_a = current_a

    def _eval(self, t):
        return np.full(np.shape(t), self.current_a)
