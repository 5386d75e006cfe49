"""
Ride metrics: ISO 2631-1 Wk-weighted and raw body acceleration, suspension travel, tyre load.

The Wk weighting of the body acceleration is :func:`semi_active_control.iso2631.wk_sos` (the
one home of the ISO 2631-1 weightings, which the Wk-weighted laws run too).

Metric keys (both :func:`ride_metrics` and :class:`RunningRideMetrics`):

``rms_body_accel_wk`` [m/s^2], ``rms_body_accel`` [m/s^2], ``rms_suspension_travel`` [m]
(about the static position), ``rms_tyre_load_ratio`` [-] (RMS of (tyre force - static load) /
static load), ``peak_body_accel`` [m/s^2], ``peak_suspension_travel`` [m],
``peak_tyre_load_ratio`` [-] (max |dynamic tyre load| / static load), ``contact_loss_fraction``
[-] (time with zero tyre force), ``rms_damper_force`` [N], ``mean_current_a``,
``max_current_a`` [A] (coil current command; nan when no current is commanded),
``saturated_fraction`` [-] (time the inverse model saturated the command; nan likewise),
``duration_s`` [s], ``n_samples``.
"""
import math

import numpy as np
from scipy import signal

from semi_active_control.iso2631 import wk_filter, wk_sos

METRIC_KEYS = ('rms_body_accel_wk', 'rms_body_accel', 'rms_suspension_travel',
               'rms_tyre_load_ratio', 'peak_body_accel', 'peak_suspension_travel',
               'peak_tyre_load_ratio', 'contact_loss_fraction', 'rms_damper_force',
               'mean_current_a', 'max_current_a', 'saturated_fraction', 'duration_s',
               'n_samples')


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if len(x) else float('nan')


def ride_metrics(result, *, static_load=None):
    """
    Ride metrics of a simulation result.

    Parameters
    ----------
    result : SimResult or mapping
        Needs ``t``, ``a_s``, ``travel``, ``tyre_force``, ``damper_force`` arrays and
        ``static_tyre_load`` (or pass ``static_load``); ``current_cmd`` and ``saturated``
        arrays are used when present (nan commands = no current).
    static_load : float, optional
        Static tyre load [N].

    Returns
    -------
    dict
        Keys :data:`METRIC_KEYS` (see the module docstring).

    """
    def get(name, default=None):
        if isinstance(result, dict):
            return result.get(name, default)
        return getattr(result, name, default)

    t = np.asarray(get('t'), dtype=float)
    if t.size < 2:
        raise ValueError('result needs at least 2 samples')
    dt = float(np.median(np.diff(t)))
    w = float(static_load if static_load is not None else get('static_tyre_load'))
    a = np.asarray(get('a_s'), dtype=float)
    tr = np.asarray(get('travel'), dtype=float)
    ft = np.asarray(get('tyre_force'), dtype=float)
    fd = np.asarray(get('damper_force'), dtype=float)
    dyn = (ft - w) / w
    out = {
        'rms_body_accel_wk': _rms(wk_filter(a, 1.0 / dt)),
        'rms_body_accel': _rms(a),
        'rms_suspension_travel': _rms(tr),
        'rms_tyre_load_ratio': _rms(dyn),
        'peak_body_accel': float(np.max(np.abs(a))),
        'peak_suspension_travel': float(np.max(np.abs(tr))),
        'peak_tyre_load_ratio': float(np.max(np.abs(dyn))),
        'contact_loss_fraction': float(np.mean(ft <= 0.0)),
        'rms_damper_force': _rms(fd),
    }
    cur = get('current_cmd')
    cur = np.full(t.size, np.nan) if cur is None else np.asarray(cur, dtype=float)
    sat = get('saturated')
    if np.all(np.isnan(cur)):
        out.update(mean_current_a=float('nan'), max_current_a=float('nan'),
                   saturated_fraction=float('nan'))
    else:
        out['mean_current_a'] = float(np.nanmean(cur))
        out['max_current_a'] = float(np.nanmax(cur))
        out['saturated_fraction'] = (float('nan') if sat is None
                                     else float(np.mean(np.asarray(sat, dtype=bool))))
    out['duration_s'] = float(t[-1] - t[0] + dt)
    out['n_samples'] = int(t.size)
    return out


class RunningRideMetrics:
    """
    Incremental ride metrics, one sample at a time (for the ROS node).

    Same keys as :func:`ride_metrics`.

    Parameters
    ----------
    fs : float
        Sample rate [Hz] of the updates (sets the digital Wk filter).
    static_load : float
        Static tyre load [N].

    Notes
    -----
    The Wk filter runs sample by sample (plain floats, transposed direct form II per section)
    and matches :func:`wk_filter` on the same samples. ``as_dict()`` can be called at any time.

    """

    def __init__(self, fs, static_load):
        if not static_load > 0:
            raise ValueError(f'`static_load` must be > 0, got {static_load}')
        self.fs = float(fs)
        self.static_load = float(static_load)
        self._sos_array = wk_sos(self.fs)
        self._sos = [tuple(float(v) for v in row) for row in self._sos_array]
        self.reset()

    def reset(self):
        """Clear all sums and the filter state."""
        self._zi = [[0.0, 0.0] for _ in self._sos]
        self.n = 0
        self._s = dict.fromkeys(('wk2', 'a2', 'tr2', 'dyn2', 'fd2', 'cur', 'ncur', 'sat',
                                 'nsat', 'loss'), 0.0)
        self._pk = {'a': 0.0, 'tr': 0.0, 'dyn': 0.0}
        self._maxcur = float('-inf')

    def update(self, state, current_cmd=float('nan'), saturated=None):
        """
        Add one sample.

        Parameters
        ----------
        state : mr_damper_common.contract.CornerState
            Car state (uses ``a_s``, ``travel``, ``tyre_force``, ``damper_force``).
        current_cmd : float
            Coil current command [A] (nan: none).
        saturated : bool or None
            Whether the command was saturated (None: unknown / not applicable).

        """
        y = state.a_s
        for (b0, b1, b2, _, a1, a2), zi in zip(self._sos, self._zi):
            out = b0 * y + zi[0]
            zi[0] = b1 * y - a1 * out + zi[1]
            zi[1] = b2 * y - a2 * out
            y = out
        s = self._s
        s['wk2'] += y * y
        a = state.a_s
        s['a2'] += a * a
        tr = state.travel
        s['tr2'] += tr * tr
        dyn = (state.tyre_force - self.static_load) / self.static_load
        s['dyn2'] += dyn * dyn
        s['fd2'] += state.damper_force ** 2
        if state.tyre_force <= 0.0:
            s['loss'] += 1.0
        pk = self._pk
        pk['a'] = max(pk['a'], abs(a))
        pk['tr'] = max(pk['tr'], abs(tr))
        pk['dyn'] = max(pk['dyn'], abs(dyn))
        if current_cmd == current_cmd:
            s['cur'] += current_cmd
            s['ncur'] += 1.0
            self._maxcur = max(self._maxcur, current_cmd)
        if saturated is not None:
            s['sat'] += 1.0 if saturated else 0.0
            s['nsat'] += 1.0
        self.n += 1

    def update_block(self, a_s, travel, tyre_force, damper_force, current_cmd=None,
                     saturated=None, use=None):
        """
        Add a block of samples at once (vectorised; same sums as :meth:`update` per sample).

        Parameters
        ----------
        a_s, travel, tyre_force, damper_force : array_like with shape (n,)
            Body acceleration [m/s^2], suspension travel [m], tyre load [N], damper force [N].
        current_cmd : array_like with shape (n,), optional
            Coil current commands [A] (nan: none).
        saturated : array_like of bool with shape (n,), optional
            Whether each command was saturated.
        use : array_like of bool with shape (n,), optional
            Samples that count in the metrics; the Wk filter runs over every sample (a window
            inside a run is filtered with the run's history, as :func:`wk_filter` on the whole
            run then cut).

        """
        a = np.asarray(a_s, dtype=float)
        zi = np.asarray(self._zi, dtype=float)
        wk, zf = signal.sosfilt(self._sos_array, a, zi=zi)
        self._zi = zf.tolist()
        sel = slice(None) if use is None else np.asarray(use, dtype=bool)
        a, wk = a[sel], wk[sel]
        tr = np.asarray(travel, dtype=float)[sel]
        ft = np.asarray(tyre_force, dtype=float)[sel]
        fd = np.asarray(damper_force, dtype=float)[sel]
        m = a.size
        if m == 0:
            return
        dyn = (ft - self.static_load) / self.static_load
        s = self._s
        s['wk2'] += float(wk @ wk)
        s['a2'] += float(a @ a)
        s['tr2'] += float(tr @ tr)
        s['dyn2'] += float(dyn @ dyn)
        s['fd2'] += float(fd @ fd)
        s['loss'] += float(np.count_nonzero(ft <= 0.0))
        pk = self._pk
        pk['a'] = max(pk['a'], float(np.max(np.abs(a))))
        pk['tr'] = max(pk['tr'], float(np.max(np.abs(tr))))
        pk['dyn'] = max(pk['dyn'], float(np.max(np.abs(dyn))))
        if current_cmd is not None:
            cur = np.asarray(current_cmd, dtype=float)[sel]
            cur = cur[~np.isnan(cur)]
            if cur.size:
                s['cur'] += float(cur.sum())
                s['ncur'] += float(cur.size)
                self._maxcur = max(self._maxcur, float(cur.max()))
        if saturated is not None:
            sat = np.asarray(saturated, dtype=bool)[sel]
            s['sat'] += float(np.count_nonzero(sat))
            s['nsat'] += float(sat.size)
        self.n += m

    def as_dict(self):
        """Return the metrics so far (nan where no samples)."""
        n = self.n
        s = self._s
        nan = float('nan')
        if n == 0:
            d = dict.fromkeys(METRIC_KEYS, nan)
            d['n_samples'] = 0
            d['duration_s'] = 0.0
            return d
        return {
            'rms_body_accel_wk': math.sqrt(s['wk2'] / n),
            'rms_body_accel': math.sqrt(s['a2'] / n),
            'rms_suspension_travel': math.sqrt(s['tr2'] / n),
            'rms_tyre_load_ratio': math.sqrt(s['dyn2'] / n),
            'peak_body_accel': self._pk['a'],
            'peak_suspension_travel': self._pk['tr'],
            'peak_tyre_load_ratio': self._pk['dyn'],
            'contact_loss_fraction': s['loss'] / n,
            'rms_damper_force': math.sqrt(s['fd2'] / n),
            'mean_current_a': s['cur'] / s['ncur'] if s['ncur'] else nan,
            'max_current_a': self._maxcur if s['ncur'] else nan,
            'saturated_fraction': s['sat'] / s['nsat'] if s['nsat'] else nan,
            'duration_s': n / self.fs,
            'n_samples': n,
        }
