"""
ISO 2631-1 frequency weightings: Wk (vertical) and We (rotational), analog and digital.

The one home of the weightings: the laws designed on the weighted body acceleration
(``clipped-optimal-wk``, ``full-car-clipped-optimal-wk``) run them inside the law, and the
simulator's ride metrics (:mod:`quarter_car_sim.metrics`) weight with the same filters.

The Wk frequency weighting (ISO 2631-1:1997, Annex A, vertical whole-body vibration, seated) is
the product of

- band limiting: 2nd-order Butterworth high pass at f1 = 0.4 Hz and low pass at f2 = 100 Hz;
- acceleration-velocity transition ``(1 + s/w3) / (1 + s/(Q4 w4) + s^2/w4^2)`` with
  f3 = f4 = 12.5 Hz, Q4 = 0.63;
- upward step ``(w5/w6)^2 (1 + s/(Q5 w5) + s^2/w5^2) / (1 + s/(Q6 w6) + s^2/w6^2)`` with
  f5 = 2.37 Hz, Q5 = 0.91, f6 = 3.35 Hz, Q6 = 0.91;

made digital with the bilinear transform (``scipy.signal.bilinear_zpk``) at the sample rate and
run as second-order sections. At 1 kHz its gain is within 2 % of the analog weighting up to
31.5 Hz (frequency warping grows above; the tests state the tolerances). The rotational We
(Table A.2, ISO 8041) has band limiting 0.4-100 Hz, an a-v transition at f3 = f4 = 1 Hz with
Q4 = 0.63 and no upward step.

``scipy.signal`` and ``control`` (seconds to import) are imported by the functions that use
them, so a node whose law needs no weighting starts without them.
"""
import functools
import math

import numpy as np

WK_CONSTANTS = {'f1': 0.4, 'f2': 100.0, 'q1': 1.0 / math.sqrt(2.0), 'f3': 12.5, 'f4': 12.5,
                'q4': 0.63, 'f5': 2.37, 'q5': 0.91, 'f6': 3.35, 'q6': 0.91}
"""ISO 2631-1 Table A.2 constants of the Wk weighting [Hz] and quality factors [-]."""

WE_CONSTANTS = {'f1': 0.4, 'f2': 100.0, 'q1': 1.0 / math.sqrt(2.0), 'f3': 1.0, 'f4': 1.0,
                'q4': 0.63, 'f5': math.inf, 'q5': 1.0, 'f6': math.inf, 'q6': 1.0}
"""ISO 2631-1 Table A.2 (= ISO 8041) constants of the rotational We weighting (no upward step)."""


def weighting_sections(constants):
    """
    Analog ISO 2631-1 frequency weighting as second-order sections (rad/s).

    Band limiting high pass (f1) and low pass (f2), acceleration-velocity transition (f3, f4,
    Q4) and upward step (f5, Q5, f6, Q6; left out when f5 and f6 are infinite, as for We),
    each with a gain near 1 in its band (ISO 2631-1:1997 Annex A, ISO 8041).

    Parameters
    ----------
    constants : dict
        ``f1`` ... ``f6`` [Hz], ``q1``, ``q4``, ``q5``, ``q6`` [-] (:data:`WK_CONSTANTS`,
        :data:`WE_CONSTANTS`).

    Returns
    -------
    list of (num, den)
        Polynomial coefficients in ``s`` [rad/s], highest power first, of each section.

    """
    c = constants
    w = {n: 2.0 * math.pi * c[n] for n in ('f1', 'f2', 'f3', 'f4', 'f5', 'f6')}
    out = [
        (np.array([1.0, 0.0, 0.0]), np.array([1.0, w['f1'] / c['q1'], w['f1'] ** 2])),
        (np.array([w['f2'] ** 2]), np.array([1.0, w['f2'] / c['q1'], w['f2'] ** 2])),
        (np.array([1.0, w['f3']]) * w['f4'] ** 2 / w['f3'],
         np.array([1.0, w['f4'] / c['q4'], w['f4'] ** 2])),
    ]
    if math.isfinite(w['f5']) and math.isfinite(w['f6']):
        out.append((np.array([1.0, w['f5'] / c['q5'], w['f5'] ** 2]),
                    np.array([1.0, w['f6'] / c['q6'], w['f6'] ** 2])))
    return out


def weighting_sos(constants, fs):
    """
    Digital ISO 2631-1 weighting at sample rate ``fs`` [Hz] (bilinear) as second-order sections.

    Returns
    -------
    ndarray with shape (n_sections, 6)

    """
    from scipy import signal
    if not fs > 250.0:
        raise ValueError(f'`fs` must be > 250 Hz for the ISO 2631-1 weightings (f2 = 100 Hz), '
                         f'got {fs}')
    num, den = np.array([1.0]), np.array([1.0])
    for b, a in weighting_sections(constants):
        num, den = np.polymul(num, b), np.polymul(den, a)
    z, p, k = signal.tf2zpk(num, den)
    zd, pd, kd = signal.bilinear_zpk(z, p, k, fs)
    return signal.zpk2sos(zd, pd, kd)


def weighting_state_space(constants):
    """
    ISO 2631-1 weighting of ``constants`` as a ``control.StateSpace`` (analog, SI).

    The series connection of the second-order sections of :func:`weighting_sections` (2 states
    each, so the realisation stays well scaled), e.g. Wk (:data:`WK_CONSTANTS`, 8 states) or
    the rotational We (:data:`WE_CONSTANTS`, 6 states).
    """
    import control
    sys = None
    for num, den in weighting_sections(constants):
        sec = control.ss(control.tf(num, den))
        sys = sec if sys is None else control.series(sys, sec)
    return sys


def wk_sections():
    """
    Analog Wk weighting as its four second-order sections (rad/s).

    :func:`weighting_sections` of :data:`WK_CONSTANTS` (the product is :func:`wk_analog`).

    Returns
    -------
    list of (num, den)
        Polynomial coefficients in ``s`` [rad/s], highest power first, of each section.

    """
    return weighting_sections(WK_CONSTANTS)


def wk_analog():
    """
    Analog Wk weighting as zeros, poles and gain (rad/s).

    Returns
    -------
    z, p : ndarray
        Zeros and poles [rad/s].
    k : float
        Gain.

    """
    from scipy import signal
    num, den = np.array([1.0]), np.array([1.0])
    for b, a in wk_sections():
        num, den = np.polymul(num, b), np.polymul(den, a)
    return signal.tf2zpk(num, den)


def wk_gain(f_hz):
    """Analog Wk weighting magnitude at frequencies ``f_hz`` [Hz]."""
    from scipy import signal
    z, p, k = wk_analog()
    _, h = signal.freqs_zpk(z, p, k, worN=2.0 * np.pi * np.atleast_1d(f_hz))
    return np.abs(h)


@functools.lru_cache(maxsize=16)
def _designed_sos(weighting, fs):
    """Design :func:`wk_sos` / :func:`we_sos` once per rate (read-only; callers copy)."""
    sos = weighting_sos(WK_CONSTANTS if weighting == 'wk' else WE_CONSTANTS, fs)
    sos.flags.writeable = False
    return sos


def wk_sos(fs):
    """
    Digital Wk filter at sample rate ``fs`` [Hz] (bilinear transform) as second-order sections.

    Designed once per rate (a live node's status asks for it every period), a copy returned.

    Returns
    -------
    ndarray with shape (n_sections, 6)

    """
    return _designed_sos('wk', float(fs)).copy()


def we_sos(fs):
    """Digital We (rotational) weighting at sample rate ``fs`` [Hz] as second-order sections."""
    return _designed_sos('we', float(fs)).copy()


def wk_filter(a, fs):
    """Wk-weighted acceleration (zero initial filter state) [m/s^2] for ``a`` sampled at fs."""
    from scipy import signal
    return signal.sosfilt(wk_sos(fs), np.asarray(a, dtype=float))


def wk_state_space():
    """
    ISO 2631-1 Wk weighting as an 8-state ``control.StateSpace`` (analog, SI).

    The series connection of the four sections of :func:`wk_sections` (each a 2-state block);
    its transfer function is :func:`wk_analog`. Input body acceleration [m/s^2], output
    Wk-weighted acceleration [m/s^2].
    """
    return weighting_state_space(WK_CONSTANTS)
