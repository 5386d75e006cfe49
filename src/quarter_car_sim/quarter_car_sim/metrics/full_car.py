"""
Full-car ride metrics: ISO 2631-1 at the seat, tyre load per wheel, travel per corner.

ISO 2631-1:1997 comfort evaluation of a seated person at one point of the body (the CG by
default, or a seat at ``(x, y)`` from it):

- vertical acceleration at the seat ``a_z - x thetadd + y phidd`` weighted with Wk
  (:func:`quarter_car_sim.metrics.quarter_car.wk_sos`, the quarter car's filter);
- pitch and roll angular accelerations [rad/s^2] weighted with We (rotational; Table A.2 /
  ISO 8041: band limiting 0.4-100 Hz, a-v transition f3 = f4 = 1 Hz, Q4 = 0.63, no upward step;
  :data:`quarter_car_sim.metrics.quarter_car.WE_CONSTANTS`);
- axis multiplying factors for comfort, seat surface (clause 8.2.2.2): vertical k_z = 1,
  roll r_x k = 0.63 m/rad, pitch r_y k = 0.40 m/rad (:data:`AXIS_FACTORS`);
- the vibration total value (clause 6.5, eq. 9) ``a_v = sqrt(a_wz^2 + (0.40 a_w,pitch)^2 +
  (0.63 a_w,roll)^2)`` [m/s^2];
- crest factor (peak / RMS of each weighted signal): above 9 (clause 6.2.1) the basic RMS
  method may underestimate, and the fourth-power vibration dose value
  ``VDV = (integral a_w^4 dt)^(1/4)`` [m/s^1.75] is the one to quote (clause 6.3.2);
  ``vdv_total`` combines the axes as ``(sum (k VDV)^4)^(1/4)``.

Horizontal seat accelerations (x, y), which pitch and roll also cause at a seat above the CG,
are not modelled (the car has no longitudinal or lateral DOF).

Per wheel: RMS dynamic tyre load over the static load; per corner: RMS and peak suspension
travel.
"""
import math

import numpy as np
from scipy import signal

from semi_active_control.car.full_car import CORNERS
from semi_active_control.iso2631 import we_sos, wk_sos

#: ISO 2631-1 clause 8.2.2.2 comfort multiplying factors (seated, seat surface).
AXIS_FACTORS = {'z': 1.0, 'roll': 0.63, 'pitch': 0.40}

#: Crest factor above which ISO 2631-1 (6.2.1) calls for the VDV.
CREST_LIMIT = 9.0


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


class RunningIso2631:
    """
    ISO 2631-1 figures of :func:`iso2631_seat` over a run fed in chunks (the live car's status).

    Each chunk is weighted with the filters' state carried over from the chunk before
    (``scipy.signal.sosfilt`` with ``zi``), and only sums (squares, fourth powers, peaks) are
    kept: the figures cover the whole run in constant memory, and each call costs its new
    samples, not the run so far. :func:`iso2631_seat` is this fed with one chunk.

    Parameters
    ----------
    dt : float
        Sample period [s] (uniform).

    """

    def __init__(self, dt):
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f'`dt` must be > 0, got {dt}')
        self.dt = float(dt)
        fs = 1.0 / self.dt
        self._sos = (wk_sos(fs), we_sos(fs), we_sos(fs))
        self._zi = [np.zeros((len(sos), 2)) for sos in self._sos]
        self.n = 0
        self._sq = np.zeros(3)
        self._p4 = np.zeros(3)
        self._peak = np.zeros(3)

    def add(self, a_z, theta_dd, phi_dd):
        """Add the next samples: seat vertical [m/s^2], pitch and roll [rad/s^2] (n,)."""
        axes = [np.asarray(a, dtype=float).ravel() for a in (a_z, theta_dd, phi_dd)]
        n = axes[0].size
        if any(a.size != n for a in axes):
            raise ValueError('`a_z`, `theta_dd` and `phi_dd` must have the same length')
        if n == 0:
            return
        for i, (sos, a) in enumerate(zip(self._sos, axes)):
            aw, self._zi[i] = signal.sosfilt(sos, a, zi=self._zi[i])
            self._sq[i] += float(np.dot(aw, aw))
            self._p4[i] += float(np.sum(np.square(np.square(aw))))
            self._peak[i] = max(self._peak[i], float(np.max(np.abs(aw))))
        self.n += n

    def as_dict(self):
        """Return the keys of :func:`iso2631_seat` over the samples so far (NaN: none)."""
        axes = []
        for i in range(3):
            rms = math.sqrt(self._sq[i] / self.n) if self.n else math.nan
            peak = float(self._peak[i]) if self.n else math.nan
            axes.append({'rms': rms, 'peak': peak,
                         'crest': peak / rms if rms > 0 else math.nan,
                         'vdv': float(self._p4[i] * self.dt) ** 0.25 if self.n else math.nan})
        z, p, r = axes
        k = AXIS_FACTORS
        a_v = math.sqrt(z['rms'] ** 2 + (k['pitch'] * p['rms']) ** 2
                        + (k['roll'] * r['rms']) ** 2)
        vdv_total = (z['vdv'] ** 4 + (k['pitch'] * p['vdv']) ** 4
                     + (k['roll'] * r['vdv']) ** 4) ** 0.25
        crest = max(z['crest'], p['crest'], r['crest'])
        return {'a_wz': z['rms'], 'a_w_pitch': p['rms'], 'a_w_roll': r['rms'], 'a_v': a_v,
                'crest_z': z['crest'], 'crest_pitch': p['crest'], 'crest_roll': r['crest'],
                'crest_max': crest, 'vdv_z': z['vdv'], 'vdv_pitch': p['vdv'],
                'vdv_roll': r['vdv'], 'vdv_total': vdv_total,
                'vdv_required': bool(crest > CREST_LIMIT)}


def iso2631_seat(t, a_z, theta_dd, phi_dd):
    """
    ISO 2631-1 comfort metrics from the seat's vertical and the body's angular accelerations.

    Parameters
    ----------
    t : array_like with shape (n,)
        Uniform time [s].
    a_z : array_like with shape (n,)
        Vertical acceleration at the seat [m/s^2].
    theta_dd, phi_dd : array_like with shape (n,)
        Pitch and roll angular accelerations [rad/s^2].

    Returns
    -------
    dict
        ``a_wz`` [m/s^2], ``a_w_pitch``, ``a_w_roll`` [rad/s^2] (weighted RMS), ``a_v``
        (vibration total value) [m/s^2], ``crest_z``, ``crest_pitch``, ``crest_roll``,
        ``crest_max`` [-], ``vdv_z`` [m/s^1.75], ``vdv_pitch``, ``vdv_roll``
        [rad/s^1.75], ``vdv_total`` [m/s^1.75], ``vdv_required`` (a crest factor above 9).

    """
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        raise ValueError('need at least 2 samples')
    metrics = RunningIso2631(float(np.median(np.diff(t))))
    metrics.add(a_z, theta_dd, phi_dd)
    return metrics.as_dict()


def body_a_v(t, acc):
    """
    Return the ISO 2631-1 vibration total value a_v [m/s^2] of the body at its CG.

    ``acc`` holds a run's body accelerations by column (``FullCarResult.acc``: heave
    [m/s^2], pitch, roll [rad/s^2], then any others), ``t`` its uniform time [s]: the a_v
    of :func:`iso2631_seat` with the seat at the CG, the figure the vehicle computer's
    summary and benches compare.
    """
    acc = np.asarray(acc, dtype=float)
    return iso2631_seat(t, acc[:, 0], acc[:, 1], acc[:, 2])['a_v']


def full_car_metrics(result, params, *, seat=(0.0, 0.0)):
    """
    Ride metrics of a full-car run.

    Parameters
    ----------
    result : FullCarResult
        Time series (``t``, ``acc``, ``travel``, ``tyre_force``, ``current_cmd``).
    params : FullCarParams
        Car (static tyre loads).
    seat : (float, float)
        Seat position ``(x, y)`` [m] from the CG (forward, left).

    Returns
    -------
    dict
        The keys of :func:`iso2631_seat`, plus ``rms_tyre_load_ratio`` and
        ``rms_suspension_travel`` (dicts per corner, [-] and [m]), ``peak_suspension_travel``
        [m] per corner, ``contact_loss_fraction`` per wheel, ``max_rms_tyre_load_ratio``,
        ``mean_current_a`` per corner, ``rms_pitch_rate``, ``rms_roll_rate`` [rad/s],
        ``duration_s``.

    """
    acc = np.asarray(result.acc)
    x, y = seat
    a_z = acc[:, 0] - x * acc[:, 1] + y * acc[:, 2]
    out = iso2631_seat(result.t, a_z, acc[:, 1], acc[:, 2])
    w = params.static_tyre_loads
    dyn = (np.asarray(result.tyre_force) - w) / w
    tr = np.asarray(result.travel)
    out['rms_tyre_load_ratio'] = {c: _rms(dyn[:, i]) for i, c in enumerate(CORNERS)}
    out['max_rms_tyre_load_ratio'] = max(out['rms_tyre_load_ratio'].values())
    out['rms_suspension_travel'] = {c: _rms(tr[:, i]) for i, c in enumerate(CORNERS)}
    out['peak_suspension_travel'] = {c: float(np.max(np.abs(tr[:, i])))
                                     for i, c in enumerate(CORNERS)}
    out['contact_loss_fraction'] = {c: float(np.mean(np.asarray(result.tyre_force)[:, i] <= 0))
                                    for i, c in enumerate(CORNERS)}
    cur = np.asarray(result.current_cmd)
    out['mean_current_a'] = {c: (float(np.nanmean(cur[:, i])) if np.any(np.isfinite(cur[:, i]))
                                 else math.nan) for i, c in enumerate(CORNERS)}
    v = np.asarray(result.v)
    out['rms_pitch_rate'] = _rms(v[:, 1])
    out['rms_roll_rate'] = _rms(v[:, 2])
    t = np.asarray(result.t)
    out['duration_s'] = float(t[-1] - t[0] + (t[1] - t[0]))
    return out
