"""
Acceptance of live parameter sets: excitation, model comparison, force offsets; no ROS.

:class:`~mr_damper_model.live.LiveIdentifier` fits a set on every window; a set that passes its
validity checks (bounds, pinned parameters, NRMSE, much worse than the last valid set) is then
reviewed here before it replaces the set in use (the *current* set):

1. **Excitation** (:func:`excitation_shortfall`): per current level of the fit data, the velocity
   amplitude (98th percentile of ``|v|``) must reach ``min_amplitude_ratio`` of the current
   set's at that level; each of ``velocity_bins`` equal bins over ``[-a, a]`` (``a`` the
   level's own amplitude) must hold ``min_velocity_bin_share`` of its samples (both strokes,
   the whole cycle, no decaying motion); and the condition number of the separable
   least-squares problem of the level (Kwok regressors ``v, x, tanh(beta v + delta sgn x), 1``
   at the set's ``beta(i)`` and ``delta``, columns scaled to unit norm) must stay below
   ``max_condition_number`` (``c`` and ``alpha`` or ``k`` and ``f0`` not told apart).
2. **Comparison** (:func:`compare_sets`): on the newest window's samples, and on the samples
   admitted in the ``holdout_s`` before the window's data (held back from the fit: a fit to a
   transient in the newest window cannot win there; reaching back over both ends of the
   stroke when the excitation is slow, :meth:`Acceptance.heldback`; of it only the half cycles
   whose velocity peak reaches ``min_amplitude_ratio`` of the window's amplitude, so a start
   from rest that a first set was fitted on does not keep that set,
   :func:`half_cycle_amplitude`), both at the current
   levels both sets cover, the new set's RMS error must be at most ``1 - replace_margin``
   times the current set's (``replace_margin`` 0: at most :data:`TIE_FRACTION` above it:
   noise-level ties go to the newer set).  With fewer than :data:`MIN_COMPARE_SAMPLES`
   held-back samples (start-up, after a pause) only the window is compared.  A set that
   extends the current range is compared on the common levels with the tolerance of
   ``max_error_ratio`` instead (the previous rule): it claims levels the current set does not
   describe.

A refused set is never published as valid: the identifier re-publishes the current set, valid,
with its own window stamps (its age: the window end of the newest window minus its
``window_end_s``) and counts the reason (``windows_refused``).

3. **Force offsets** (:meth:`Acceptance.offset_flags`): the current set's residual on the new
   samples, less its mean residual in the same current / displacement / velocity cell, smoothed
   by a centred running median over ``offset_window_s``, is a force offset where it exceeds
   ``offset_ratio`` times the set's RMS error plus the error floor while the motion stays within
   the set's amplitude (a step in force without a change in motion: offset step or drifting load
   cell).  Those samples leave the bins and the fit (``samples_flagged['offset']``); the offset
   is reported (``offset`` status), never absorbed into ``f0``.
4. **f0 trend** (:meth:`Acceptance.f0_trend`): the slope of ``f0`` over the accepted sets of the
   last ``drift_window_s`` [N/min]: a slow drift the sets follow, reported, not a fault.
"""
import math

import numpy as np

from mr_damper_model.identification.signals import running_median
from mr_damper_model.io.data import DamperData
from mr_damper_model.models.kwok_current import (kwok_current_coefficients, kwok_current_force,
                                                 KwokCurrent)

#: Keys of ``windows_refused`` this module adds (refused sets; the current set re-published).
ACCEPT_REASONS = ('velocity_amplitude', 'velocity_bins', 'condition', 'worse_on_window',
                  'worse_on_heldback')
#: Fewest samples of a level for its excitation figures to be judged.
MIN_LEVEL_SAMPLES = 50
#: Fewest samples a comparison rests on (window or held-back part).
MIN_COMPARE_SAMPLES = 50
#: RMS errors within this fraction of each other are a tie (noise), which the new set wins.
TIE_FRACTION = 0.005
#: Hysteresis of a velocity reversal (:func:`cycle_start`) [fraction of the amplitude].
REVERSAL_HYSTERESIS = 0.1
#: Fewest accepted sets over which the f0 trend is reported.
MIN_TREND_SETS = 5


def level_keys(i, bin_a):
    """Return the current bin keys of samples (``round(i / bin_a)``, as the identifier's bins)."""
    return np.round(np.asarray(i, dtype=float) / bin_a).astype(np.int64)


def velocity_amplitude(v):
    """Velocity amplitude [m/s]: 98th percentile of ``|v|`` (spikes cannot move it)."""
    v = np.asarray(v, dtype=float)
    return float(np.percentile(np.abs(v), 98.0)) if v.size else 0.0


def velocity_shares(v, amplitude, n_bins):
    """
    Return the share of samples in each of ``n_bins`` equal velocity bins over ``[-a, a]``.

    Samples beyond ``a`` count in the outer bins.
    """
    v = np.asarray(v, dtype=float)
    if not v.size or not amplitude > 0:
        return np.zeros(n_bins)
    k = np.floor((v / amplitude + 1.0) * 0.5 * n_bins).astype(np.int64)
    k = np.clip(k, 0, n_bins - 1)
    return np.bincount(k, minlength=n_bins) / v.size


def reversal_indices(v):
    """
    Return the indices where the velocity reverses (changes sign, with a hysteresis).

    The hysteresis is :data:`REVERSAL_HYSTERESIS` of the velocity amplitude (noise at rest
    reverses nothing).
    """
    v = np.asarray(v, dtype=float)
    h = REVERSAL_HYSTERESIS * velocity_amplitude(v)
    if not h > 0:
        return np.zeros(0, dtype=np.int64)
    sign = np.where(v > h, 1, np.where(v < -h, -1, 0))
    nz = np.flatnonzero(sign)
    s = sign[nz]
    return nz[1:][s[1:] != s[:-1]]


def half_cycle_amplitude(v):
    """
    Return, per sample, the largest ``|v|`` of its half cycle (between velocity reversals).

    The samples before the first reversal and after the last one form half cycles too.
    """
    v = np.asarray(v, dtype=float)
    if not v.size:
        return v.copy()
    edges = np.r_[0, reversal_indices(v), v.size]
    peaks = np.maximum.reduceat(np.abs(v), edges[:-1])
    return np.repeat(peaks, np.diff(edges))


def cycle_start(t, v, reversals=2):
    """
    Time [s] of the ``reversals``-th most recent velocity reversal (-inf with fewer).

    The span from the second most recent one holds both ends of the stroke (half a cycle or
    more): at 0.1 Hz a 2 s window holds one of them only.
    """
    change = reversal_indices(v)
    if change.size < reversals:
        return -math.inf
    return float(np.asarray(t)[change[-reversals]])


def condition_number(params, data, current_a, i_ref_a):
    """
    Condition number of the separable least-squares problem of one current level.

    Parameters
    ----------
    params : dict
        kwok-current parameters (the nonlinear ``beta0``, ``beta1``, ``delta`` are used).
    data : DamperData
        Samples of the level.
    current_a : float
        The level's current [A].
    i_ref_a : float
        Reference current [A].

    Returns
    -------
    float
        ``cond`` of the regressors ``v, x, tanh(beta(i) v + delta sgn x), 1`` with columns
        scaled to unit norm (inf if a column is zero).

    """
    row = np.array([[params[n] for n in KwokCurrent.param_names]], dtype=float)
    _, _, beta = kwok_current_coefficients(row, np.array([current_a / i_ref_a]))
    z = np.tanh(float(beta[0, 0]) * data.v + params['delta'] * np.sign(data.x))
    phi = np.column_stack([data.v, data.x, z, np.ones(data.n)])
    norms = np.linalg.norm(phi, axis=0)
    if np.any(norms == 0):
        return math.inf
    return float(np.linalg.cond(phi / norms))


def level_figures(params, data, config):
    """
    Return the excitation figures of each current level of ``data``.

    Returns
    -------
    dict
        level key -> ``{'n', 'current_a', 'amplitude', 'shares', 'cond'}``.

    """
    keys = level_keys(data.i, config.current_bin_a)
    out = {}
    for key in np.unique(keys):
        part = data.select(keys == key)
        if part.n < MIN_LEVEL_SAMPLES:
            continue
        amp = velocity_amplitude(part.v)
        current = float(np.median(part.i))
        out[int(key)] = {'n': part.n, 'current_a': current, 'amplitude': amp,
                         'shares': velocity_shares(part.v, amp, int(config.velocity_bins)),
                         'cond': condition_number(params, part, current, config.i_ref_a)}
    return out


def excitation_shortfall(figures, reference, config):
    """
    Return why the excitation is too poor for the set fitted on it, or ''.

    Parameters
    ----------
    figures : dict
        :func:`level_figures` of the fit data of the new set.
    reference : dict or None
        Velocity amplitude per level key of the current set ({} or None: none).
    config : LiveConfig
        ``min_amplitude_ratio``, ``min_velocity_bin_share``, ``max_condition_number``.

    Returns
    -------
    str
        '' or ``'velocity_amplitude:<A>'``, ``'velocity_bins:<A>'``, ``'condition:<A>'``
        (``<A>`` the level's current [A]).

    """
    reference = reference or {}
    for key, fig in sorted(figures.items()):
        level = f'{fig["current_a"]:.3g}'
        ref = reference.get(key)
        if ref is not None and fig['amplitude'] < config.min_amplitude_ratio * ref:
            return f'velocity_amplitude:{level}'
        if float(np.min(fig['shares'])) < config.min_velocity_bin_share:
            return f'velocity_bins:{level}'
        if not fig['cond'] <= config.max_condition_number:
            return f'condition:{level}'
    return ''


def rmse(params, data, i_ref_a):
    """RMS force error [N] of a kwok-current set on ``data`` (nan if empty)."""
    if not data.n:
        return math.nan
    f = kwok_current_force(dict(params, i_ref_a=i_ref_a), data.x, data.v, data.i)
    return float(np.sqrt(np.mean((data.f - f) ** 2)))


def compare_sets(new, current, window, heldback, config):
    """
    Compare a new set with the current one; return (reason, figures).

    Parameters
    ----------
    new, current : dict
        kwok-current parameters.
    window, heldback : DamperData
        The newest window's samples and the held-back ones (both at levels both sets cover).
    config : LiveConfig
        ``replace_margin``, ``i_ref_a``.

    Returns
    -------
    reason : str
        '' (the new set is better by ``replace_margin`` on both; with ``replace_margin`` 0 at
        least as good, ties within :data:`TIE_FRACTION` going to the new set), or
        ``'worse_on_window'`` / ``'worse_on_heldback'``.
    figures : dict
        ``{'window': (new, current), 'heldback': (new, current)}`` RMS errors [N]
        (a part with fewer than :data:`MIN_COMPARE_SAMPLES` samples is not judged: absent).

    """
    factor = 1.0 - config.replace_margin if config.replace_margin > 0 else 1.0 + TIE_FRACTION
    figures = {}
    reason = ''
    for name, part in (('window', window), ('heldback', heldback)):
        if part is None or part.n < MIN_COMPARE_SAMPLES:
            continue
        e_new = rmse(new, part, config.i_ref_a)
        e_cur = rmse(current, part, config.i_ref_a)
        figures[name] = (e_new, e_cur)
        if not reason and not e_new <= factor * e_cur:
            reason = f'worse_on_{name}'
    return reason, figures


class Acceptance:
    """
    The current set of a stream, its evidence and the review of new sets.

    Parameters
    ----------
    config : callable
        ``config()`` -> the :class:`~mr_damper_model.live.LiveConfig` in use (it may change
        while running).

    """

    def __init__(self, config):
        self._config = config
        self.current = None         # {'parameters', 'levels', 'amplitude', 'window_end_s', ...}
        self._held = None           # admitted samples, newest last (DamperData)
        self._f0 = []               # (window end [s], f0 [N]) of the accepted sets
        self.last_figures = {}
        self.offset = {'flagged_windows': 0, 'last_n': math.nan, 'last_at_s': math.nan}

    def reset(self):
        """Forget the current set and the held-back samples (new stream, reference reset)."""
        self.current = None
        self._held = None
        self._f0 = []

    # ---------------------------------------------------------------- held-back samples
    def remember(self, clean, newest_s):
        """Keep admitted samples for the held-back comparisons (the last few windows)."""
        cfg = self._config()
        if clean.n:
            self._held = clean if self._held is None else DamperData.concatenate(
                [self._held, clean])
        if self._held is not None:
            keep_from = newest_s - (2.0 * cfg.window_s + max(cfg.holdout_s, cfg.holdout_max_s))
            k = int(np.searchsorted(self._held.t, keep_from, side='left'))
            if k:
                self._held = self._held.select(slice(k, None))

    def forget(self, first_s, last_s):
        """
        Drop the held-back samples stamped in ``[first_s, last_s]`` [s].

        Samples around a force step found in a set's own data (one side of the step is wrong,
        which side no set can tell at the start of a stream) must not keep a set fitted on them
        in use: the held-back comparison favours the set the samples were fitted on.
        """
        if self._held is not None:
            keep = (self._held.t < first_s) | (self._held.t > last_s)
            if not keep.all():
                self._held = self._held.select(keep) if keep.any() else None

    def heldback(self, before_s):
        """
        Admitted samples before ``before_s``: the held-back part of a comparison.

        The ``holdout_s`` before ``before_s``, reaching back to the second most recent velocity
        reversal if that is earlier (both ends of the stroke, :func:`cycle_start`), never more
        than ``holdout_max_s``.  Out of sample for the new set; the current set may have
        been fitted on part of them (an advantage that fades as it ages: the set in use is kept
        when in doubt).
        """
        cfg = self._config()
        if self._held is None:
            return None
        held = self._held.select(slice(0, int(np.searchsorted(self._held.t, before_s,
                                                              side='left'))))
        start = before_s - cfg.holdout_s
        if held.n:
            start = min(start, cycle_start(held.t, held.v))
        start = max(start, before_s - max(cfg.holdout_s, cfg.holdout_max_s))
        return held.select(slice(int(np.searchsorted(held.t, start, side='left')), None))

    # ---------------------------------------------------------------- review
    def _covered(self, data, levels):
        keys = level_keys(data.i, self._config().current_bin_a)
        return np.isin(keys, np.fromiter(levels, dtype=np.int64))

    def review(self, params, fit, window):
        """
        Review a valid new set; return '' (take it) or why the current set stays.

        Parameters
        ----------
        params : dict
            The new kwok-current set.
        fit : DamperData
            The samples it was fitted on (all its current levels).
        window : DamperData
            The newest window's samples (its span; compared on the fitted samples in it).

        Returns
        -------
        str
            '' or a reason ``<key>[:<detail>]`` with ``key`` in :data:`ACCEPT_REASONS`.

        """
        cfg = self._config()
        figures = level_figures(params, fit, cfg)
        self.last_figures = {'condition': max((f['cond'] for f in figures.values()),
                                              default=math.nan)}
        cur = self.current
        reason = excitation_shortfall(figures, cur['amplitude'] if cur else None, cfg)
        if reason or cur is None:
            return reason
        new_levels = set(figures)
        common = new_levels & cur['levels']
        if not common:
            return ''
        w0 = float(window.t[0])
        recent = fit.select(fit.t >= w0)            # the window's screened, admitted samples
        win = recent.select(self._covered(recent, common))
        held = self.heldback(w0)
        if held is not None:
            held = held.select(self._covered(held, common))
            if held.n and recent.n:
                # only the half cycles of full motion judge: a start from rest (where the set
                # in use may have been fitted) would keep any first set
                env = half_cycle_amplitude(held.v)
                held = held.select(env >= cfg.min_amplitude_ratio * velocity_amplitude(recent.v))
        if new_levels - cur['levels']:
            # a wider claim: compared on the common levels with the validity tolerance
            e_new = rmse(params, win, cfg.i_ref_a)
            e_cur = rmse(cur['parameters'], win, cfg.i_ref_a)
            self.last_figures['window'] = (e_new, e_cur)
            if win.n >= MIN_COMPARE_SAMPLES and not e_new <= cfg.max_error_ratio * e_cur:
                return 'worse_on_window'
            return ''
        reason, figs = compare_sets(params, cur['parameters'], win, held, cfg)
        self.last_figures.update(figs)
        return reason

    def take(self, params, fit, window_start_s, window_end_s, rmse_n):
        """Make a reviewed set the current one (with its amplitudes and residual cells)."""
        cfg = self._config()
        keys = level_keys(fit.i, cfg.current_bin_a)
        amplitude = {}
        for key in np.unique(keys):
            v = fit.v[keys == key]
            if v.size >= MIN_LEVEL_SAMPLES:
                amplitude[int(key)] = velocity_amplitude(v)
        resid = fit.f - kwok_current_force(dict(params, i_ref_a=cfg.i_ref_a), fit.x, fit.v,
                                           fit.i)
        grid = _Grid(fit, cfg.current_bin_a)
        self.current = {'parameters': dict(params), 'levels': set(amplitude),
                        'amplitude': amplitude, 'window_start_s': float(window_start_s),
                        'window_end_s': float(window_end_s),
                        'rmse_n': float(rmse_n), 'grid': grid,
                        'cell_mean': grid.means(fit, resid)}
        self._f0.append((float(window_end_s), float(params['f0'])))
        horizon = float(window_end_s) - cfg.drift_window_s
        while self._f0 and self._f0[0][0] < horizon:
            self._f0.pop(0)

    # ---------------------------------------------------------------- offsets
    def offset_flags(self, span, n_new, scale, end_s):
        """
        Return a mask of the new samples (the last ``n_new`` of ``span``) with a force offset.

        ``span``: screened samples in time order, the new ones last (earlier ones give the
        running median its context); ``scale``: robust force range of the current set's data
        (the error floor is ``error_floor_percent`` of it).
        """
        cfg = self._config()
        cur = self.current
        mask = np.zeros(n_new, dtype=bool)
        if cur is None or n_new == 0 or span.n < 3:
            return mask
        resid = span.f - kwok_current_force(dict(cur['parameters'], i_ref_a=cfg.i_ref_a),
                                            span.x, span.v, span.i)
        resid = resid - cur['grid'].lookup(span, cur['cell_mean'])
        dt = float(np.median(np.diff(span.t))) if span.n > 1 else 1.0
        width = max(3, 2 * int(round(0.5 * cfg.offset_window_s / dt)) + 1)
        smooth = running_median(resid, width)
        limit = cfg.offset_ratio * cur['rmse_n'] + 0.01 * cfg.error_floor_percent * scale
        keys = level_keys(span.i, cfg.current_bin_a)
        known = self._covered(span, cur['levels'])
        amp = np.array([cur['amplitude'].get(int(k), 0.0) for k in keys])
        # motion unchanged: within the amplitude the set was fitted on (and known levels)
        calm = known & (np.abs(span.v) <= 1.5 * amp + 1e-12)
        out = calm & (np.abs(smooth) > limit)
        mask = out[span.n - n_new:]
        if mask.any():
            self.offset['flagged_windows'] += 1
            self.offset['last_n'] = float(np.median(smooth[span.n - n_new:][mask]))
            self.offset['last_at_s'] = float(end_s)
        return mask

    # ---------------------------------------------------------------- status
    def f0_trend(self):
        """
        Return the f0 trend of the accepted sets of the last ``drift_window_s``.

        Returns
        -------
        dict
            ``{'n_per_min', 'span_s', 'sets', 'f0_n'}``: least-squares slope of f0 over window
            end [N/min] (nan with fewer than :data:`MIN_TREND_SETS` sets), the time it spans
            [s], the sets it rests on and the newest f0 [N].

        """
        pts = self._f0
        out = {'n_per_min': math.nan, 'span_s': 0.0, 'sets': len(pts),
               'f0_n': pts[-1][1] if pts else math.nan}
        if len(pts) >= MIN_TREND_SETS:
            t = np.array([p[0] for p in pts])
            f0 = np.array([p[1] for p in pts])
            span = float(t[-1] - t[0])
            out['span_s'] = span
            if span > 0:
                out['n_per_min'] = 60.0 * float(np.polyfit(t - t[0], f0, 1)[0])
        return out

    def age_s(self, now_s):
        """Age of the current set at window end ``now_s`` [s] (nan if none)."""
        cur = self.current
        return float(now_s) - cur['window_end_s'] if cur else math.nan


class _Grid:
    """Current level x displacement x velocity cells over a data set's range."""

    CELLS = 8

    def __init__(self, data, bin_a):
        self.bin_a = bin_a
        self.x_edges = np.linspace(float(data.x.min()), float(data.x.max()), self.CELLS + 1)
        self.v_edges = np.linspace(float(data.v.min()), float(data.v.max()), self.CELLS + 1)

    def codes(self, data):
        n = self.CELLS
        ix = np.clip(np.searchsorted(self.x_edges, data.x, side='right') - 1, 0, n - 1)
        iv = np.clip(np.searchsorted(self.v_edges, data.v, side='right') - 1, 0, n - 1)
        return (level_keys(data.i, self.bin_a) * n + ix) * n + iv

    def means(self, data, values):
        codes = self.codes(data)
        uniq, inverse, counts = np.unique(codes, return_inverse=True, return_counts=True)
        sums = np.bincount(inverse, weights=values, minlength=uniq.size)
        return dict(zip(uniq.tolist(), (sums / counts).tolist()))

    def lookup(self, data, means):
        return np.array([means.get(int(c), 0.0) for c in self.codes(data)])
