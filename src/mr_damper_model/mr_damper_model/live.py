"""
Live (sliding-window) identification of the current-dependent Kwok model; no ROS.

The identifier node feeds samples in as they arrive and asks for windows; this module does all
the work, so it can be tested and benchmarked without ROS:

1. **Sample validation** (:meth:`LiveIdentifier.add_sample`): NaN/inf values and out-of-order or
   duplicate stamps are rejected and counted by reason (``rejected``); values outside the
   configured sensor ranges (``force_limit_n``, ``velocity_limit_m_s``, ``displacement_limit_m``,
   ``current_limit_min_a`` .. ``current_limit_max_a``) are rejected and counted by channel
   (``out_of_range``); bad samples never reach the buffer.  A stream that restarts from an
   earlier time (a replay started again) is detected by a run of ``restart_samples``
   consecutive, increasing, out-of-order samples: the buffer restarts.
2. **Sliding window** (:meth:`LiveIdentifier.next_window`): a window of ``window_s`` seconds of
   *sample* time becomes due every ``hop_s``; when the fitter is slower than the hop, only the
   newest due window is fitted and the others are counted as superseded (with
   ``backlog_windows`` > 0, for replays under sim time, every window is fitted in order).
   Every window also carries the samples that arrived since the previous one (``new``), however
   many windows were superseded, so each accepted sample is judged and binned exactly once.
   New samples older than the window's own span are screened, judged, binned and fitted one
   window length at a time, in time order, before it (``catch_up_fits``, not published): no
   sample is judged against a reference fitted more than ``window_s`` before it, however long
   the fitter was delayed (:meth:`LiveIdentifier._catch_up_parts`).
3. **Window checks**: windows spanning a time gap longer than ``max_gap_s`` (``gap``), with too
   few samples, no motion (velocity RMS), no force variation or motion in one direction only are
   skipped and counted by reason; their new samples that the next window holds are offered
   again with it, the older ones are not binned (``samples_unbinned``).
4. **Sensor-fault screening of the new samples** (:func:`flag_samples`): a force sample far from
   the 5-sample running median of its neighbours (beyond ``outlier_mad_k`` robust standard
   deviations, from the median absolute deviation, and ``outlier_floor_fraction`` of the robust
   force range) is an ``outlier``; a force exactly constant for ``stuck_s`` or longer is a
   ``stuck`` load cell (``dropout`` when the constant is zero).  Flagged samples leave the fit
   and the bins and are counted by reason (``samples_flagged``).  Then the last valid model of
   this stream (if any) must explain the new samples of the current levels it covers about as
   well as it explained the data it was fitted on (:meth:`LiveIdentifier._consistency`):
   otherwise the data changed abruptly (force offset step, current sensor stuck, load cell sign
   flip, a dropout) and the window is skipped (``inconsistent``) without binning them.
5. **Current bins**: the screened new samples are filed by coil current into bins of width
   ``current_bin_a``; each bin keeps its newest samples (as many as one window holds) and bins
   older than ``bin_max_age_s`` are dropped.  The Kwok model is algebraic (no internal state),
   so the union of the bins is a valid data set even though it joins different moments.
6. **Fit** (:func:`fit_data`, the same :func:`~mr_damper_model.identify.identify` call as the
   offline tool): separable PSO warm-started from the last solution, within ``budget_s``.  One
   usable bin: plain Kwok (mapped to kwok-current with zero current slopes, the covered range
   being that single current); two or more bins: kwok-current on their union.
7. **Validity**: finite parameters within the model bounds; no parameter pinned at a bound
   (:func:`pinned_parameters`); the fit RMSE divided by the robust force range of the fit data
   (0.5-99.5 percentile range, which single outliers cannot move) at most
   ``max_nrmse_percent``; and, on the fitted samples of the current levels covered by the last
   valid set of this stream, an RMSE at most ``max_error_ratio`` times that set's plus
   ``error_floor_percent`` of the robust force range (``worse_than_last_valid``).
8. **Acceptance** (``acceptance_checks``, :mod:`~mr_damper_model.acceptance`): a valid set
   replaces the set in use only if its window excites what it claims (velocity amplitude,
   velocity bins, condition number) and it predicts at least as well on the newest window and
   on held-back recent data; otherwise the set in use is re-published (valid, ``held``) and the
   reason counted in ``windows_refused``.  Admitted samples with a force offset against the set
   in use are flagged ``offset``; the f0 trend of the sets taken is reported.

Threading: ``add_sample`` and ``next_window`` may be called from one thread and ``process``
(the fit) from another; the sample buffer is protected by a lock, the bins and the warm start
belong to the fitting thread.
"""
from dataclasses import dataclass, field, fields, replace
import math
import os
import pickle
import subprocess
import sys
import threading
import time

import numpy as np

from .acceptance import Acceptance
from .data import DamperData
from .kwok_current import KwokCurrent, kwok_current_coefficients, kwok_current_force
from .stamps import ACCEPTED, REBASED, StampGuard

KWOK_CURRENT_NAMES = KwokCurrent.param_names

#: Keys of the sample rejection counters.
REJECT_REASONS = ('nonfinite', 'out_of_order', 'duplicate', 'future_stamp', 'joint_names',
                  'layout')
#: Keys of the out-of-range sample counters (the channel whose range check failed).
RANGE_CHANNELS = ('force', 'velocity', 'displacement', 'current')
#: Keys of the skipped-window counters.
SKIP_REASONS = ('gap', 'few_samples', 'no_motion', 'no_force', 'one_direction', 'inconsistent',
                'no_bins')
#: Keys of the flagged-sample counters (samples kept out of the fit and the bins).
FLAG_REASONS = ('outlier', 'stuck', 'dropout', 'offset', 'inconsistent')
#: Width of the running median of the outlier screen [samples] (isolates bursts of <= 2).
MEDIAN_WIDTH = 5
#: Fewest screened samples on which the last valid set's consistency is judged.
MIN_CHECK_SAMPLES = 20
#: Cells per axis of the (displacement, velocity) grid of the consistency reference.
STATE_CELLS = 8
#: Fewest fitted samples in a reference cell for its error to count as known.
MIN_CELL_SAMPLES = 10


@dataclass
class LiveConfig:
    """
    Settings of the live identifier (the identifier node's ROS parameters of the same names).

    Attributes
    ----------
    window_s : float
        Window length [s]; 2 s holds > 2 cycles of the 1.1 Hz cam rig and 2000 samples at 1 kHz.
    hop_s : float
        Window hop [s]; 0.2 s gives 5 parameter updates per second.
    budget_s : float
        Compute budget of one fit [s] (0: none); below ``hop_s`` so fits keep pace.
    maxiter : int
        Swarm iterations per window (0: identify's default); warm starts converge in few.
    swarm_size : int
        PSO particles.
    seed : int
        Swarm seed of every window (same seed as an offline run reproduces a window's fit).
    warm_start : bool
        Start each window's swarm from the previous solution.
    unbounded : bool
        Use the wide thesis-comparison bounds instead of the physical ones.
    i_ref_a : float
        Reference current of the kwok-current model [A].
    max_nrmse_percent : float
        Validity threshold on the window fit's NRMSE [%].
    current_bin_a : float
        Current bin width [A].
    min_bin_fraction : float
        A bin is used once it holds this fraction of a window's samples.
    bin_max_age_s : float
        Bins whose newest sample is older than this [s] are dropped (0: never).
    max_fit_samples : int
        Fit data are decimated (every k-th sample) above this count (0: never).
    max_rate_hz : float
        Highest expected sample rate [Hz] (sizes the buffer).
    min_window_samples : int
        Fewer samples in a window: skipped (``few_samples``).
    min_velocity_rms_m_s : float
        Velocity RMS below this [m/s]: skipped (``no_motion``).
    min_force_std_n : float
        Force standard deviation below this [N]: skipped (``no_force``).
    min_direction_fraction : float
        Fraction of samples needed in each velocity direction (``one_direction``).
    restart_samples : int
        Consecutive increasing out-of-order samples that restart the stream.
    max_future_s : float
        Samples stamped more than this [s] ahead of the node clock (the stamps advancing this
        much further than the clock, :class:`~mr_damper_model.stamps.StampGuard`) are
        refused (``rejected['future_stamp']``) and never become the reference; 0: no such
        check (the default: a replay at ``rate_factor`` > 1 on wall time stamps its samples
        ahead of the clock by design). Set it when the samples are stamped on the node's clock
        (a DAQ at real time, or a replay under ``use_sim_time``).
    force_limit_n : float
        Samples with ``|f|`` above this [N] are rejected (``out_of_range['force']``); dampers
        of this class make 1-2 kN (thesis damper about 850 N at 2 A, Quiroz damper 1.7 kN).
    velocity_limit_m_s : float
        Samples with ``|v|`` above this [m/s] are rejected (``out_of_range['velocity']``).
    displacement_limit_m : float
        Samples with ``|x|`` above this [m] are rejected (``out_of_range['displacement']``).
    current_limit_min_a, current_limit_max_a : float
        Samples with a current outside this range [A] are rejected
        (``out_of_range['current']``); the coil takes 0-2 A.
    max_gap_s : float
        Windows with a stamp step above this [s] are skipped (``gap``).
    outlier_mad_k : float
        Outlier threshold in robust standard deviations (1.4826 MAD) of the force's distance
        from its running median.
    outlier_floor_fraction : float
        Outlier threshold floor as a fraction of the window's robust force range (so that the
        curvature of noise-free or coarsely sampled data is no outlier).
    stuck_s : float
        A force exactly constant for this long [s] or longer is a stuck load cell (``stuck``,
        ``dropout`` at zero); real load cells have noise (the Quiroz records repeat a value
        for at most 0.105 s).
    max_error_ratio : float
        A new set is refused (``worse_than_last_valid``) when its RMSE on the fitted samples
        covered by the last valid set exceeds this times that set's RMSE on them, plus the floor.
    max_shift_ratio : float
        New samples are inconsistent with the last valid set when its RMSE on them exceeds this
        times its RMSE on the data it was fitted on (same current levels), plus the floor.
    error_floor_percent : float
        Floor of both comparisons [% of the robust force range].
    pinned_fraction : float
        A parameter within this fraction of its bound span from a non-zero bound is pinned
        (zero bounds of non-negative coefficients mean "term absent" and are allowed).
    inconsistent_reset_s : float
        After this long [s of sample time] of consecutive inconsistent windows, forget the
        reference and the bins and identify afresh (``reference_resets``); 0: never.  A real,
        abrupt damper change then recovers, but so does a persistent sensor fault (an offset
        step becomes f0): leave it 0 unless an operator watches the resets.
    backlog_windows : int
        0 (real time): only the newest due window is fitted, older due windows are superseded.
        N > 0 (replays, ``use_sim_time``): every due window is fitted in order, whatever the
        fitter's pace; the buffer holds N hops of due windows besides the current one, and
        windows whose samples left it meanwhile are counted in ``windows_overflow``.  Each
        window's fit then stops on ``maxiter`` (no wall-time ``budget_s``) with a seed derived
        from ``seed`` and the window's index (:func:`window_seed`), so the estimate sequence
        does not depend on the replay speed.
    acceptance_checks : bool
        Review every valid set before it replaces the set in use
        (:mod:`~mr_damper_model.acceptance`): excitation, comparison with the set in use on
        the newest window and on held-back data, force-offset flags and the f0 trend.  A refused
        set is counted in ``windows_refused`` and the set in use is re-published (valid, its
        own window stamps).  False: the previous rules (every valid set is published).
    min_amplitude_ratio : float
        A window's velocity amplitude (98th percentile of ``|v|``) at a current level must reach
        this fraction of the set in use's at that level (``velocity_amplitude``).
    velocity_bins : int
        Equal velocity bins over +- the level's own amplitude.
    min_velocity_bin_share : float
        Each velocity bin must hold this share of the level's samples (``velocity_bins``; a
        sine gives at least 0.1 with 6 bins).
    max_condition_number : float
        Largest condition number of a level's separable least-squares problem (Kwok
        regressors at the set's beta and delta, unit-norm columns; ``condition``).
    replace_margin : float
        A new set replaces the one in use only if its RMS error is at most ``1 -
        replace_margin`` times that set's on the newest window and on the held-back samples
        (``worse_on_window``, ``worse_on_heldback``); 0: at least as good.
    holdout_s : float
        Held-back part: the admitted samples of this long [s] before a window's own samples.
    offset_window_s : float
        Running-median length of the force-offset screen [s].
    offset_ratio : float
        A force offset: the smoothed residual of the set in use (less its mean in the state
        cell) beyond this times its RMS error, plus the error floor.
    drift_window_s : float
        The f0 trend is the slope over the accepted sets of this long [s].

    """

    window_s: float = 2.0
    hop_s: float = 0.2
    budget_s: float = 0.15
    maxiter: int = 30
    swarm_size: int = 20
    seed: int = 1
    warm_start: bool = True
    unbounded: bool = False
    i_ref_a: float = 2.0
    max_nrmse_percent: float = 10.0
    current_bin_a: float = 0.1
    min_bin_fraction: float = 0.25
    bin_max_age_s: float = 120.0
    max_fit_samples: int = 4000
    max_rate_hz: float = 5000.0
    min_window_samples: int = 200
    min_velocity_rms_m_s: float = 0.002
    min_force_std_n: float = 2.0
    min_direction_fraction: float = 0.1
    restart_samples: int = 500
    max_future_s: float = 0.0
    force_limit_n: float = 5000.0
    velocity_limit_m_s: float = 2.0
    displacement_limit_m: float = 0.15
    current_limit_min_a: float = -0.1
    current_limit_max_a: float = 2.5
    max_gap_s: float = 0.05
    outlier_mad_k: float = 6.0
    outlier_floor_fraction: float = 0.05
    stuck_s: float = 0.2
    max_error_ratio: float = 1.5
    max_shift_ratio: float = 3.0
    error_floor_percent: float = 2.0
    pinned_fraction: float = 1e-3
    inconsistent_reset_s: float = 0.0
    backlog_windows: int = 0
    acceptance_checks: bool = True
    min_amplitude_ratio: float = 0.7
    velocity_bins: int = 6
    min_velocity_bin_share: float = 0.03
    max_condition_number: float = 100.0
    replace_margin: float = 0.0
    holdout_s: float = 2.0
    offset_window_s: float = 0.2
    offset_ratio: float = 3.0
    drift_window_s: float = 300.0

    def __post_init__(self):
        positive = ('window_s', 'hop_s', 'i_ref_a', 'max_nrmse_percent', 'current_bin_a',
                    'max_rate_hz', 'force_limit_n', 'velocity_limit_m_s',
                    'displacement_limit_m', 'max_gap_s', 'outlier_mad_k', 'stuck_s',
                    'max_error_ratio', 'max_shift_ratio', 'max_condition_number',
                    'holdout_s', 'offset_window_s', 'offset_ratio', 'drift_window_s')
        for name in positive:
            value = float(getattr(self, name))
            if not math.isfinite(value) or value <= 0:
                raise ValueError(f'`{name}` must be a positive finite number, got {value!r}')
        for name in ('budget_s', 'bin_max_age_s', 'min_velocity_rms_m_s', 'min_force_std_n',
                     'min_bin_fraction', 'min_direction_fraction', 'outlier_floor_fraction',
                     'error_floor_percent', 'pinned_fraction', 'inconsistent_reset_s',
                     'max_future_s', 'min_amplitude_ratio', 'min_velocity_bin_share',
                     'replace_margin'):
            value = float(getattr(self, name))
            if not math.isfinite(value) or value < 0:
                raise ValueError(f'`{name}` must be >= 0, got {value!r}')
        for name in ('maxiter', 'max_fit_samples', 'min_window_samples', 'backlog_windows'):
            if int(getattr(self, name)) < 0:
                raise ValueError(f'`{name}` must be >= 0')
        if int(self.swarm_size) < 2:
            raise ValueError('`swarm_size` must be >= 2')
        if int(self.restart_samples) < 1:
            raise ValueError('`restart_samples` must be >= 1')
        if self.hop_s > self.window_s:
            raise ValueError(f'`hop_s` ({self.hop_s}) must not exceed `window_s` '
                             f'({self.window_s})')
        if not float(self.current_limit_min_a) < float(self.current_limit_max_a):
            raise ValueError(f'`current_limit_min_a` ({self.current_limit_min_a}) must be below '
                             f'`current_limit_max_a` ({self.current_limit_max_a})')
        if int(self.velocity_bins) < 2:
            raise ValueError(f'`velocity_bins` must be >= 2, got {self.velocity_bins!r}')
        if self.min_velocity_bin_share * int(self.velocity_bins) > 1.0:
            raise ValueError('`min_velocity_bin_share` times `velocity_bins` must not exceed 1')
        if self.replace_margin >= 1.0:
            raise ValueError(f'`replace_margin` must be below 1, got {self.replace_margin}')
        if self.pinned_fraction >= 0.5:
            raise ValueError(f'`pinned_fraction` must be below 0.5, got {self.pinned_fraction}')


@dataclass
class Window:
    """
    Samples of one due window (copies), its scheduled end [s] and the samples new to it.

    ``span`` holds the samples from the older of the window start and the first new sample up
    to ``end_s`` (time order); its last ``n_new`` samples are the ones no earlier window handed
    out (more than a window's worth when windows were superseded).  ``index`` is the
    window's position ``m`` in its stream (end ``t0 + window_s + m * hop_s``).
    """

    data: DamperData
    end_s: float
    span: DamperData = None
    n_new: int = 0
    first_new_seq: int = 0
    index: int = 0

    @property
    def new(self):
        """Samples handed out for the first time (the last ``n_new`` of ``span``)."""
        span = self.span if self.span is not None else self.data
        return span.select(slice(span.n - self.n_new, None))


@dataclass
class LiveEstimate:
    """
    One published estimate: kwok-current parameters and what they rest on.

    Attributes
    ----------
    parameters : dict
        The ten kwok-current parameters (SI units).
    valid : bool
        Passed the validity checks.
    reason : str
        Why not valid ('' if valid).
    model_fitted : str
        ``'kwok'`` (one current bin) or ``'kwok-current'``; ``'file'`` for a loaded estimate.
    i_ref_a, window_start_s, window_end_s, current_min_a, current_max_a : float
        Model constant and data coverage (stamps [s], currents [A]).
    rmse_n, nrmse_percent : float
        Fit quality on the fitted data (``nrmse_percent`` as the offline tool reports it:
        RMSE over the full force range).
    robust_nrmse_percent : float
        RMSE over the robust (0.5-99.5 percentile) force range of the fitted data [%]: the
        figure validity is judged on.
    seconds : float
        Compute time of the window [s].
    n_samples : int
        Samples fitted.
    bins_a : list of float
        Current levels of the bins fitted [A].
    result : object
        The :class:`~mr_damper_model.identify.IdentificationResult` (None for a loaded one).
    held : str
        '' for a set fitted on its window; for the set in use re-published because the
        window's set was refused by the acceptance review, the reason
        (:mod:`~mr_damper_model.acceptance`).

    """

    parameters: dict
    valid: bool
    reason: str = ''
    model_fitted: str = 'kwok-current'
    i_ref_a: float = 2.0
    window_start_s: float = math.nan
    window_end_s: float = math.nan
    current_min_a: float = math.nan
    current_max_a: float = math.nan
    rmse_n: float = math.nan
    nrmse_percent: float = math.nan
    robust_nrmse_percent: float = math.nan
    seconds: float = 0.0
    n_samples: int = 0
    bins_a: list = field(default_factory=list)
    result: object = None
    held: str = ''

    def message_values(self):
        """Return the values of the ``kwok_parameters`` message (see ``messages``)."""
        d = dict(self.parameters)
        d.update(i_ref_a=self.i_ref_a, window_start_s=self.window_start_s,
                 window_end_s=self.window_end_s, current_min_a=self.current_min_a,
                 current_max_a=self.current_max_a, rmse_n=self.rmse_n,
                 nrmse_percent=self.nrmse_percent, valid=self.valid, reason=self.reason)
        return d

    def params_file_dict(self, source=''):
        """Return the parameter-file dictionary (``params_file.save_params``)."""
        metrics = dict(self.result.metrics) if self.result is not None else {
            'rmse_n': self.rmse_n, 'nrmse_percent': self.nrmse_percent}
        return {'model': 'kwok-current',
                'parameters': {k: float(v) for k, v in self.parameters.items()},
                'model_options': {'i_ref_a': float(self.i_ref_a)},
                'current_min_a': float(self.current_min_a),
                'current_max_a': float(self.current_max_a),
                'metrics': metrics, 'valid': bool(self.valid),
                'seed': None if self.result is None else self.result.seed,
                'source': source or f'identifier window ending at {self.window_end_s:.3f} s'}


def kwok_to_kwok_current(p):
    """
    Write Kwok parameters as a current-independent kwok-current set.

    Parameters
    ----------
    p : dict
        Kwok parameters (c, k, alpha, beta, delta, f0).

    Returns
    -------
    dict
        kwok-current parameters with c1 = alpha1 = alpha2 = beta1 = 0.

    """
    return {'c0': p['c'], 'c1': 0.0, 'k': p['k'], 'alpha0': p['alpha'], 'alpha1': 0.0,
            'alpha2': 0.0, 'beta0': p['beta'], 'beta1': 0.0, 'delta': p['delta'], 'f0': p['f0']}


def kwok_current_at(p, current_a, i_ref_a=2.0):
    """
    Evaluate kwok-current parameters at one current as a Kwok set.

    Parameters
    ----------
    p : dict
        kwok-current parameters.
    current_a : float
        Coil current [A].
    i_ref_a : float
        Reference current [A].

    Returns
    -------
    dict
        Kwok parameters c(i), k, alpha(i), beta(i), delta, f0.

    """
    row = np.array([[p[n] for n in KWOK_CURRENT_NAMES]], dtype=float)
    c, alpha, beta = kwok_current_coefficients(row, np.array([current_a / i_ref_a]))
    return {'c': float(c[0, 0]), 'k': p['k'], 'alpha': float(alpha[0, 0]),
            'beta': float(beta[0, 0]), 'delta': p['delta'], 'f0': p['f0']}


def check_excitation(data, config):
    """
    Return why a window cannot be identified, or '' if it can.

    Parameters
    ----------
    data : DamperData
        Window samples.
    config : LiveConfig
        Thresholds.

    Returns
    -------
    str
        '' or one of ``'few_samples'``, ``'no_motion'``, ``'no_force'``, ``'one_direction'``.

    """
    if data.n < max(int(config.min_window_samples), 10):
        return 'few_samples'
    v = data.v
    if float(np.sqrt(np.mean(v * v))) < config.min_velocity_rms_m_s:
        return 'no_motion'
    if float(np.std(data.f)) < config.min_force_std_n:
        return 'no_force'
    # direction: only samples moving faster than a tenth of the RMS count
    vmin = 0.1 * float(np.sqrt(np.mean(v * v)))
    frac_up = np.count_nonzero(v > vmin) / data.n
    frac_down = np.count_nonzero(v < -vmin) / data.n
    if min(frac_up, frac_down) < config.min_direction_fraction:
        return 'one_direction'
    return ''


def robust_range(f):
    """
    Return the 0.5-99.5 percentile range of a force record [N] (0 for fewer than 2 samples).

    Single outliers cannot move it: the validity NRMSE is normalised by it.
    """
    f = np.asarray(f, dtype=float)
    if f.size < 2:
        return 0.0
    lo, hi = np.percentile(f, [0.5, 99.5])
    return float(hi - lo)


def pinned_parameters(names, values, lo, hi, fraction):
    """
    Return the names of parameters pinned at a bound of their box.

    A parameter is pinned when it lies within ``fraction`` of its bound span from a bound that
    is not zero.  Zero bounds (the lower bound of a non-negative coefficient: no viscous term,
    no hysteresis, no loop shift) are values a physical damper can take; a fit stopped at the
    end of the search box (e.g. ``f0`` at 500 N, ``beta0`` at 0.1 or 1000 s/m, ``beta1`` at
    +-3) is one the data pushed out of the physical range, typically by a sensor fault.

    Parameters
    ----------
    names : sequence of str
        Parameter names.
    values, lo, hi : array_like with shape (n,)
        Values and bounds (infinite bounds are never reached).
    fraction : float
        Fraction of ``hi - lo``.

    Returns
    -------
    list of str

    """
    x = np.asarray(values, dtype=float)
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    span = np.where(np.isfinite(hi - lo), hi - lo, np.inf)
    tol = fraction * span
    at_lo = np.isfinite(lo) & (lo != 0) & (x <= lo + tol)
    at_hi = np.isfinite(hi) & (hi != 0) & (x >= hi - tol)
    return [n for n, a, b in zip(names, at_lo, at_hi) if a or b]


def running_median(f, width=MEDIAN_WIDTH):
    """
    Return the centred running median of ``f`` (edges padded with the end values).

    Parameters
    ----------
    f : array_like with shape (n,)
        Signal.
    width : int
        Odd window length [samples].

    Returns
    -------
    numpy.ndarray with shape (n,)

    """
    f = np.asarray(f, dtype=float)
    h = width // 2
    if f.size == 0:
        return f.copy()
    padded = np.concatenate([np.full(h, f[0]), f, np.full(h, f[-1])])
    return np.median(np.lib.stride_tricks.sliding_window_view(padded, width), axis=1)


def constant_runs(f, t, min_s):
    """
    Return a mask of the samples in runs of exactly equal values lasting ``min_s`` or longer.

    Parameters
    ----------
    f : array_like with shape (n,)
        Signal.
    t : array_like with shape (n,)
        Stamps [s], increasing.
    min_s : float
        Shortest flagged run [s] (first to last stamp of the run).

    Returns
    -------
    numpy.ndarray of bool with shape (n,)

    """
    f = np.asarray(f, dtype=float)
    t = np.asarray(t, dtype=float)
    n = f.size
    mask = np.zeros(n, dtype=bool)
    if n < 2:
        return mask
    starts = np.flatnonzero(np.r_[True, f[1:] != f[:-1]])
    ends = np.r_[starts[1:], n] - 1
    long = (t[ends] - t[starts]) >= min_s - 1e-9     # stamps are floats: 0.2 s may be 0.1999..
    for a, b in zip(starts[long], ends[long]):
        mask[a:b + 1] = True
    return mask


def flag_samples(data, config):
    """
    Screen force samples for sensor faults; return a reason code per sample.

    Parameters
    ----------
    data : DamperData
        Consecutive samples (the more context around the samples of interest the better).
    config : LiveConfig
        ``outlier_mad_k``, ``outlier_floor_fraction``, ``stuck_s``.

    Returns
    -------
    numpy.ndarray of object with shape (n,)
        '' (clean), ``'outlier'`` (far from the running median of its neighbours),
        ``'stuck'`` (exactly constant for ``stuck_s`` or longer) or ``'dropout'`` (stuck at 0).

    """
    f = data.f
    out = np.full(data.n, '', dtype=object)
    if data.n == 0:
        return out
    resid = f - running_median(f)
    sigma = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    threshold = max(config.outlier_mad_k * sigma,
                    config.outlier_floor_fraction * robust_range(f))
    out[np.abs(resid) > threshold] = 'outlier'
    stuck = constant_runs(f, data.t, config.stuck_s)
    out[stuck] = 'stuck'
    out[stuck & (f == 0.0)] = 'dropout'
    return out


#: LiveConfig fields that may change while the identifier runs
#: (:meth:`LiveIdentifier.reconfigure`): sample rejection thresholds, window checks, fault
#: screening, validity and quality limits.
#: The rest (window and hop lengths, buffer size, current bins, model constant, the fit's swarm,
#: seed, budget and bounds, the backlog) is read at start-up.
DYNAMIC_FIELDS = (
    'force_limit_n', 'velocity_limit_m_s', 'displacement_limit_m', 'current_limit_min_a',
    'current_limit_max_a', 'restart_samples', 'max_gap_s', 'min_window_samples',
    'min_velocity_rms_m_s', 'min_force_std_n', 'min_direction_fraction', 'outlier_mad_k',
    'outlier_floor_fraction', 'stuck_s', 'max_nrmse_percent', 'max_error_ratio',
    'max_shift_ratio', 'error_floor_percent', 'pinned_fraction', 'inconsistent_reset_s',
    'min_bin_fraction', 'bin_max_age_s', 'acceptance_checks', 'min_amplitude_ratio',
    'velocity_bins', 'min_velocity_bin_share', 'max_condition_number', 'replace_margin',
    'holdout_s', 'offset_window_s', 'offset_ratio', 'drift_window_s')


def window_seed(seed, index):
    """
    Return the swarm seed of window ``index`` of a stream (in-order mode).

    Parameters
    ----------
    seed : int
        ``LiveConfig.seed``.
    index : int
        Window position ``m`` in its stream.

    Returns
    -------
    int
        A seed in ``[0, 2**32)`` that depends only on ``seed`` and ``index``
        (``numpy.random.SeedSequence``), so each window's swarm starts differently but the same
        window always starts the same way.

    """
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


def fit_kwargs(config):
    """
    Return the keyword arguments of the :func:`identify` call of one window.

    Parameters
    ----------
    config : LiveConfig
        Live settings.

    Returns
    -------
    dict
        ``method``, ``unbounded``, ``seed``, ``swarm_size``, ``maxiter``, ``budget_s``.

    """
    return {'method': 'separable', 'unbounded': bool(config.unbounded),
            'seed': int(config.seed), 'swarm_size': int(config.swarm_size),
            'maxiter': int(config.maxiter) or None,
            'budget_s': float(config.budget_s) or None}


def fit_data(data, model, config, x0=None):
    """
    Fit one window's data: the same :func:`identify` call the offline tool makes.

    Parameters
    ----------
    data : DamperData
        Samples to fit.
    model : {'kwok', 'kwok-current'}
        Model.
    config : LiveConfig
        Settings (see :func:`fit_kwargs`).
    x0 : dict, optional
        Warm start.

    Returns
    -------
    IdentificationResult
        Result of ``identify(data, model, x0=x0, **fit_kwargs(config))`` (kwok-current with
        ``model_options={'i_ref_a': config.i_ref_a}``).

    """
    from .identify import identify
    options = {'i_ref_a': float(config.i_ref_a)} if model == 'kwok-current' else None
    return identify(data, model, x0=x0, model_options=options, **fit_kwargs(config))


class FitProcess:
    """
    :func:`fit_data` in a child interpreter (callable with the same signature and result).

    A fit holds the GIL for most of its time; in a child process it cannot delay the thread that
    receives the 1 kHz measurements.  The child runs ``python -m mr_damper_model.live`` in its
    own session, so a Ctrl-C sent to the parent's process group does not reach it: the parent
    ends it with :meth:`close` (or the child ends when its stdin closes).  Requests and results
    travel pickled over the child's stdin / stdout; exceptions are re-raised in the parent.
    """

    def __init__(self):
        self._proc = None

    def _start(self):
        self._proc = subprocess.Popen([sys.executable, '-m', 'mr_damper_model.live'],
                                      stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                      start_new_session=True)

    def _call(self, request):
        if self._proc is None or self._proc.poll() is not None:
            self._start()
        proc = self._proc   # close() from another thread (shutdown) must not pull it away
        try:
            pickle.dump(request, proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            proc.stdin.flush()
            status, value = pickle.load(proc.stdout)
        except (EOFError, OSError, ValueError, pickle.UnpicklingError) as exc:
            self.close()
            raise RuntimeError(f'fit process failed ({type(exc).__name__}: {exc})') from None
        if status == 'error':
            raise value
        return value

    def alive(self):
        """Return True while the child runs (False before the first call or once it died)."""
        proc = self._proc
        return proc is not None and proc.poll() is None

    def warm_up(self):
        """Start the child and import the fitting code in it; return True."""
        return self._call('ping')

    def __call__(self, data, model, config, x0=None):
        """Run ``fit_data(data, model, config, x0=x0)`` in the child."""
        return self._call((data, model, config, x0))

    def close(self, wait_s=2.0):
        """End the child process (EOF on its stdin; killed if still there after ``wait_s``)."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            proc.stdin.close()
            proc.wait(timeout=wait_s)
        except (OSError, subprocess.TimeoutExpired):
            proc.kill()
            proc.wait()


def _malloc_trim():
    """
    Return a function that gives freed heap memory back to the OS (glibc), or a no-op.

    Fits allocate and free many temporaries of varying sizes; without trimming the child's
    heap keeps the high-water mark of its fragments (measured: +7 MB over the first 400 fits,
    then flat in-process, but still growing after 6 minutes in the live suite). After each
    fit ``malloc_trim(0)`` returns what is free, so the child's memory follows its use.
    """
    try:
        import ctypes
        trim = ctypes.CDLL('libc.so.6').malloc_trim
    except (OSError, AttributeError):
        return lambda: None
    return lambda: trim(0)


def _serve():
    """Child side of :class:`FitProcess`: answer pickled requests until stdin closes."""
    out = os.fdopen(os.dup(1), 'wb')
    os.dup2(2, 1)            # anything printed goes to stderr, stdout carries results only
    from . import identify   # noqa: F401  (load numpy, scipy and the models once)
    trim = _malloc_trim()
    src = sys.stdin.buffer
    while True:
        try:
            request = pickle.load(src)
        except EOFError:
            return
        try:
            reply = ('ok', True if request == 'ping' else fit_data(*request))
        except Exception as exc:  # returned to the parent, which raises it
            reply = ('error', exc)
        pickle.dump(reply, out, protocol=pickle.HIGHEST_PROTOCOL)
        out.flush()
        trim()


def _in_bounds(model, params, unbounded, i_ref_a):
    from .models import get_model
    mdl = get_model(model, **({'i_ref_a': i_ref_a} if model == 'kwok-current' else {}))
    lo, hi = mdl.default_bounds(unbounded=unbounded)
    x = np.array([params[n] for n in mdl.param_names], dtype=float)
    if not np.all(np.isfinite(x)):
        return 'nonfinite_parameters'
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    tol = 1e-9 * span
    if np.any(x < lo - tol) or np.any(x > hi + tol):
        bad = [n for n, a, b, c in zip(mdl.param_names, x, lo, hi)
               if a < b - 1e-9 * abs(c - b) or a > c + 1e-9 * abs(c - b)]
        return f'out_of_bounds:{",".join(bad)}'
    return ''


class _Bin:
    __slots__ = ('level', 'data', 'newest_s')

    def __init__(self, level, data):
        self.level = level
        self.data = data
        self.newest_s = float(data.t[-1])


class LiveIdentifier:
    """
    Sliding-window identifier of the current-dependent Kwok model (pure Python, no ROS).

    Parameters
    ----------
    config : LiveConfig, optional
        Settings.
    initial : dict or ParamsFile, optional
        Initial estimate (e.g. the parameter file of a previous run): a kwok-current or kwok
        parameter set; used as the first published estimate and as the warm start.
    fit : callable, optional
        Replacement of :func:`fit_data` with the same signature and result, e.g. one that runs
        :func:`fit_data` in a worker process.

    """

    def __init__(self, config=None, initial=None, fit=None):
        self.config = config if config is not None else LiveConfig()
        self._fit_window = fit_data if fit is None else fit
        self._seed = None          # in-order mode: the seed of the window being processed
        cfg = self.config
        # two windows and three hops: room for the samples of superseded windows
        self._cap = int(math.ceil((2 * cfg.window_s + (3 + int(cfg.backlog_windows)) * cfg.hop_s)
                                  * cfg.max_rate_hz)) + 16
        self._buf = np.empty((self._cap, 5))
        self._lock = threading.Lock()
        self._count = 0            # samples in the buffer (<= cap)
        self._head = 0             # next write position
        self._last_t = -math.inf
        self._t_origin = None      # first stamp of the current stream
        self._next_index = 0       # index m of the next due window end
        # stamp sanity (order, duplicates, future stamps, re-base after a clock jump)
        self._stamps = StampGuard(max_future_s=cfg.max_future_s or math.inf,
                                  rebase_after=cfg.restart_samples)
        self._seq = 0              # samples accepted into the buffer so far (all streams)
        self._handed = 0           # sequence number of the first sample not yet handed out
        self.counters = {'samples_received': 0, 'samples_accepted': 0,
                         'rejected': {r: 0 for r in REJECT_REASONS},
                         'out_of_range': {r: 0 for r in RANGE_CHANNELS},
                         'stream_restarts': 0, 'stamp_gaps': 0,
                         'windows_due': 0, 'windows_superseded': 0, 'windows_overflow': 0,
                         'windows_fitted': 0, 'windows_valid': 0,
                         'windows_skipped': {r: 0 for r in SKIP_REASONS},
                         'windows_refused': {},
                         'samples_binned': 0, 'samples_unbinned': 0, 'samples_lost': 0,
                         'samples_flagged': {r: 0 for r in FLAG_REASONS},
                         'reference_resets': 0, 'catch_up_fits': 0, 'fit_errors': 0}
        self._bins = {}
        self._ref = None           # last valid set of this stream, as a consistency reference
        self._inconsistent_since = None   # window end of the first of consecutive rejections
        self._last_solution = {}   # model name -> parameter dict (warm start)
        self.estimate = None
        self.last_good = None
        self.last_compute_s = math.nan
        self.compute_s_max = 0.0
        self._compute_sum = 0.0
        self.last_error = ''
        self.last_check = {}       # figures of the last consistency comparisons [N]
        self.processed_up_to_s = math.nan   # end of the last window processed (any outcome)
        self.last_skip = ''        # reason the last skipped window was skipped
        self.last_held = ''        # why the last fitted window's set was refused ('' taken)
        self._accept = Acceptance(lambda: self.config)
        self._restarts_seen = 0    # stream restarts the acceptance state has followed
        self._in_use = None        # the set the acceptance review compares with (taken last)
        if initial is not None:
            self.estimate = self._initial_estimate(initial)
            if self.estimate is not None:
                self._last_solution['kwok-current'] = dict(self.estimate.parameters)
                if self.estimate.valid:
                    self.last_good = self.estimate

    # ---------------------------------------------------------------- initial estimate
    def _initial_estimate(self, initial):
        d = initial.to_json_dict() if hasattr(initial, 'to_json_dict') else dict(initial)
        model = d.get('model', 'kwok-current')
        params = dict(d['parameters'])
        i_ref = float((d.get('model_options') or {}).get('i_ref_a', self.config.i_ref_a))
        if model == 'kwok':
            params = kwok_to_kwok_current(params)
        elif model != 'kwok-current':
            raise ValueError(f'`initial`: model {model!r} is not kwok or kwok-current')
        params = {n: float(params[n]) for n in KWOK_CURRENT_NAMES}
        metrics = d.get('metrics') or {}
        nrmse = float(metrics.get('nrmse_percent', math.nan) if metrics.get(
            'nrmse_percent') is not None else math.nan)
        rmse = float(metrics.get('rmse_n') if metrics.get('rmse_n') is not None else math.nan)
        reason = '' if d.get('valid', True) else 'stored_invalid'
        if not reason and i_ref != self.config.i_ref_a:
            reason = 'i_ref_mismatch'
        if not reason:
            reason = _in_bounds('kwok-current', params, self.config.unbounded, i_ref)
        if not reason and not (nrmse <= self.config.max_nrmse_percent):
            reason = 'nrmse_above_threshold'
        return LiveEstimate(parameters=params, valid=not reason, reason=reason,
                            model_fitted='file', i_ref_a=i_ref, window_end_s=0.0,
                            window_start_s=0.0,
                            current_min_a=float(d.get('current_min_a', math.nan)),
                            current_max_a=float(d.get('current_max_a', math.nan)),
                            rmse_n=rmse, nrmse_percent=nrmse)

    # ---------------------------------------------------------------- samples
    def count_rejected(self, reason):
        """Count a message rejected before it became a sample (e.g. ``'joint_names'``)."""
        with self._lock:
            self.counters['samples_received'] += 1
            rej = self.counters['rejected']
            rej[reason] = rej.get(reason, 0) + 1

    def add_sample(self, t, x, v, f, i, now=None):
        """
        Offer one sample.

        Parameters
        ----------
        t : float
            Stamp [s].
        x, v, f, i : float
            Displacement [m], velocity [m/s], force [N], current [A].
        now : float, optional
            Node clock at receipt [s] (``max_future_s``; None: no future check).

        Returns
        -------
        str
            '' if accepted, else the rejection reason (``'nonfinite'``, ``'out_of_order'``,
            ``'duplicate'``, ``'future_stamp'``, or ``'<channel>_range'`` with channel ``force``,
            ``velocity``,
            ``displacement`` or ``current``: counted in ``out_of_range[channel]``).

        """
        with self._lock:
            return self._add_one(float(t), float(x), float(v), float(f), float(i), now)

    def add_samples(self, t, x, v, f, i, now=None):
        """
        Offer a batch of consecutive samples (one measurement message), in order.

        The result is exactly that of :meth:`add_sample` called on each sample in turn; a batch
        that is clean (finite, in range, stamps increasing past the newest accepted one) is
        taken with array operations, others sample by sample.

        Parameters
        ----------
        t, x, v, f, i : array_like with shape (n,)
            Stamps [s], displacement [m], velocity [m/s], force [N], current [A].
        now : float, optional
            Node clock at receipt of the batch [s] (``max_future_s``).

        Returns
        -------
        list of (int, str)
            ``(index in the batch, reason)`` of every rejected sample (empty if all accepted).

        """
        t, x, v, f, i = (np.asarray(a, dtype=float) for a in (t, x, v, f, i))
        n = t.shape[0]
        cfg = self.config
        with self._lock:
            if n and self._clean_batch(t, x, v, f, i, cfg, now):
                self._append_batch(t, x, v, f, i, cfg)
                self._stamps.take_clean(t, now)
                return []
            rejected = []
            for k in range(n):
                reason = self._add_one(float(t[k]), float(x[k]), float(v[k]), float(f[k]),
                                       float(i[k]), now)
                if reason:
                    rejected.append((k, reason))
            return rejected

    def _clean_batch(self, t, x, v, f, i, cfg, now):
        """Tell whether every sample of the batch would be accepted as it is (lock held)."""
        if not t[0] > self._last_t or not self._stamps.clean(t, now):
            return False
        if t.shape[0] > 1 and not bool(np.all(np.diff(t) > 0.0)):
            return False
        with np.errstate(invalid='ignore'):
            return bool(np.all(np.abs(f) <= cfg.force_limit_n)
                        and np.all(np.abs(v) <= cfg.velocity_limit_m_s)
                        and np.all(np.abs(x) <= cfg.displacement_limit_m)
                        and np.all(i >= cfg.current_limit_min_a)
                        and np.all(i <= cfg.current_limit_max_a)
                        and np.all(np.isfinite(t)))

    def _append_batch(self, t, x, v, f, i, cfg):
        """Take a clean batch (see :meth:`_clean_batch`) into the buffer (lock held)."""
        c = self.counters
        n = t.shape[0]
        c['samples_received'] += n
        if self._t_origin is None:
            self._t_origin = float(t[0])
            steps = np.diff(t)
        else:
            steps = np.diff(t, prepend=self._last_t)
        c['stamp_gaps'] += int(np.count_nonzero(steps > cfg.max_gap_s))
        cap = self._cap
        if n > cap:   # only the newest cap samples can stay (older ones are lost below)
            keep = slice(n - cap, n)
            skipped = n - cap
        else:
            keep, skipped = slice(0, n), 0
        rows = np.column_stack((t[keep], x[keep], v[keep], f[keep], i[keep]))
        if skipped:
            self._seq += skipped   # passed through the buffer at once: never handed out
        m = rows.shape[0]
        first = min(m, cap - self._head)
        self._buf[self._head:self._head + first] = rows[:first]
        if m > first:
            self._buf[:m - first] = rows[first:]
        self._head = (self._head + m) % cap
        self._count = min(self._count + m, cap)
        self._last_t = float(t[-1])
        self._seq += m
        c['samples_accepted'] += n

    def _add_one(self, t, x, v, f, i, now=None):
        """:meth:`add_sample` with the lock held."""
        cfg = self.config
        c = self.counters
        c['samples_received'] += 1
        if not (math.isfinite(t) and math.isfinite(x) and math.isfinite(v)
                and math.isfinite(f) and math.isfinite(i)):
            c['rejected']['nonfinite'] += 1
            return 'nonfinite'
        verdict = self._stamps.check(t, now)   # order, duplicates, future, clock jumps
        if verdict == REBASED:
            self._restart_stream()
        elif verdict != ACCEPTED:
            c['rejected'][verdict] += 1
            return verdict
        # range checks after the stamp checks: a sample is late before it is implausible
        channel = ('force' if abs(f) > cfg.force_limit_n else
                   'velocity' if abs(v) > cfg.velocity_limit_m_s else
                   'displacement' if abs(x) > cfg.displacement_limit_m else
                   'current' if not (cfg.current_limit_min_a <= i
                                     <= cfg.current_limit_max_a) else '')
        if channel:
            c['out_of_range'][channel] += 1
            return channel + '_range'
        if self._t_origin is None:
            self._t_origin = t
        elif t - self._last_t > cfg.max_gap_s:
            # counted once per gap, here: the windows across it may all be superseded
            c['stamp_gaps'] += 1
        row = self._buf[self._head]
        row[0] = t
        row[1] = x
        row[2] = v
        row[3] = f
        row[4] = i
        self._head = (self._head + 1) % self._cap
        if self._count < self._cap:
            self._count += 1
        self._last_t = t
        self._stamps.commit(t, now)
        self._seq += 1
        c['samples_accepted'] += 1
        return ''

    def _restart_stream(self):
        self.counters['stream_restarts'] += 1
        self.counters['samples_lost'] += self._seq - self._handed
        self._handed = self._seq
        self._count = 0
        self._head = 0
        self._last_t = -math.inf
        self._t_origin = None
        self._next_index = 0
        self._bins.clear()
        self._ref = None

    # ---------------------------------------------------------------- windows
    def next_window(self):
        """
        Return the newest due window (older due windows are counted as superseded), or None.

        Window ends are ``t0 + window_s + m * hop_s`` in sample time, ``t0`` the first stamp.
        The window also hands out every sample up to its end that no earlier window handed out
        (:attr:`Window.new`); samples that left the buffer before that are counted in
        ``samples_lost`` (the buffer holds two windows and three hops).

        With ``backlog_windows`` > 0 the oldest due window is returned instead (every window in
        order, none superseded); only when the fitter fell so far behind that the oldest due
        windows' samples left the buffer (``backlog_windows`` more hops) are those windows
        passed over, counted in ``windows_overflow``.
        """
        cfg = self.config
        with self._lock:
            if self._t_origin is None:
                return None
            first_end = self._t_origin + cfg.window_s
            if self._last_t < first_end + self._next_index * cfg.hop_s:
                return None
            m = int(math.floor((self._last_t - first_end) / cfg.hop_s + 1e-9))
            m = max(m, self._next_index)
            n = self._count
            oldest = self._seq - n
            if cfg.backlog_windows:
                m = self._in_order_index(m, n)
            else:
                self.counters['windows_superseded'] += m - self._next_index
            self.counters['windows_due'] += 1
            self._next_index = m + 1
            end = first_end + m * cfg.hop_s
            if self._handed < oldest:
                self.counters['samples_lost'] += oldest - self._handed
                self._handed = oldest
            idx = (self._head - n + np.arange(n)) % self._cap
            t = self._buf[idx, 0]
            k_end = int(np.searchsorted(t, end + 1e-9, side='right'))
            k_win = int(np.searchsorted(t, end - cfg.window_s + 1e-9, side='right'))
            k_new = min(self._handed - oldest, k_end)
            rows = self._buf[idx[min(k_win, k_new):k_end]]
            n_new = k_end - k_new
            self._handed = oldest + k_end
        span = DamperData(*rows.T, source='window')
        window = span.select(slice(max(k_win - k_new, 0), None))
        return Window(window, end, span, n_new, oldest + k_new, m)

    def _in_order_index(self, newest, n):
        """Index of the oldest due window whose samples are all still buffered (lock held)."""
        m = self._next_index
        t_old = self._buf[(self._head - n) % self._cap, 0]
        start = self._t_origin + m * self.config.hop_s      # samples after it form window m
        if n == self._cap and t_old > start + 1e-9:
            m_kept = int(math.ceil((t_old - self._t_origin) / self.config.hop_s - 1e-9))
            m = min(max(m, m_kept), newest)
            self.counters['windows_overflow'] += m - self._next_index
        return m

    def _give_back(self, window, n):
        """Offer the last ``n`` new samples of ``window`` again with the next window."""
        with self._lock:
            self._handed = min(self._handed, window.first_new_seq + window.n_new - n)

    # ---------------------------------------------------------------- fitting
    def process(self, window):
        """
        Check, screen, bin and fit one window; return the new estimate (None if skipped).

        Parameters
        ----------
        window : Window
            From :meth:`next_window`.

        Returns
        -------
        LiveEstimate or None
            The estimate (also stored as :attr:`estimate`; :attr:`last_good` if valid).

        """
        self.last_skip = ''
        cfg = self.config
        self._seed = window_seed(cfg.seed, window.index) if cfg.backlog_windows else None
        try:
            return self._process(window)
        finally:
            self.processed_up_to_s = float(window.end_s)

    def _fit(self, data, model, config, x0=None):
        """Fit one window's data (in-order mode: stop on ``maxiter``, seeded per window)."""
        if self._seed is not None:
            config = replace(config, seed=self._seed, budget_s=0.0)
        return self._fit_window(data, model, config, x0=x0)

    def reconfigure(self, **changes):
        """
        Change settings of :data:`DYNAMIC_FIELDS` while running; return the new config.

        Parameters
        ----------
        **changes
            ``LiveConfig`` field -> new value.

        Returns
        -------
        LiveConfig
            The configuration now in use (validated as a whole, so an error names the field).

        Raises
        ------
        ValueError
            A field that is not dynamic or unknown (nothing changed), or a value the new
            configuration refuses (nothing changed).

        """
        names = {f.name for f in fields(LiveConfig)}
        for name in changes:
            if name not in names:
                raise ValueError(f'`{name}` is not a LiveConfig setting')
            if name not in DYNAMIC_FIELDS:
                raise ValueError(f'`{name}` is read at start-up and cannot change while running')
        config = replace(self.config, **changes)
        self.config = config
        self._stamps.rebase_after = int(config.restart_samples)
        return config

    def _process(self, window):
        t_start = time.perf_counter()
        cfg = self.config
        c = self.counters
        if c['stream_restarts'] != self._restarts_seen:     # a new stream: a new current set
            self._restarts_seen = c['stream_restarts']
            self._accept.reset()
        data = window.data
        new = window.new if window.span is not None else data
        span = window.span if window.span is not None else data
        reason = ''
        if data.n > 1 and float(np.max(np.diff(data.t))) > cfg.max_gap_s:
            reason = 'gap'
        reason = reason or check_excitation(data, cfg)
        if reason:
            c['windows_skipped'][reason] += 1
            self.last_skip = reason
            # the samples the next window holds get another chance with it (as when windows
            # were binned whole); the older ones stay out of the bins
            n_next = int(np.count_nonzero(new.t > window.end_s + cfg.hop_s - cfg.window_s
                                          + 1e-9))
            if window.span is not None and n_next:
                self._give_back(window, n_next)
            else:
                n_next = 0
            c['samples_unbinned'] += new.n - n_next
            return None
        flags = flag_samples(span, cfg)[span.n - new.n:]
        for name in ('outlier', 'stuck', 'dropout'):
            c['samples_flagged'][name] += int(np.count_nonzero(flags == name))
        clean = new.select(flags == '')
        # new samples older than this window (windows superseded while the fitter was busy)
        # are judged, binned and fitted one window length at a time, in time order
        parts = self._catch_up_parts(clean, window.end_s)
        for part_end, part in parts[:-1]:
            if self._admit(part, part_end, data.n) and part.n >= cfg.min_window_samples:
                t_catch = time.perf_counter()
                self._fit_bins(part, data.n, t_catch, catch_up=True)
                t_start += time.perf_counter() - t_catch    # the window's own time only
        if not self._admit(parts[-1][1], window.end_s, data.n):
            c['windows_skipped']['inconsistent'] += 1
            self.last_skip = 'inconsistent'
            return None
        return self._fit_bins(data, data.n, t_start)

    def _catch_up_parts(self, clean, end_s):
        """
        Split a window's screened new samples into consecutive ``window_s`` spans.

        Returns ``[(span_end_s, samples), ...]`` in time order; the last span is the window's
        own (after ``end_s - window_s``), the earlier ones end at ``end_s - j * window_s``.
        Only windows that follow superseded ones carry samples before their own span.  Judging
        those against the reference one span at a time, with a fit after each, bounds the age
        of the reference a sample is judged against by ``window_s`` whatever the fitter's
        delay: the damper's slow memory (e.g. the force shift of a Bouc-Wen damper back at 0 A
        after a 2 A dwell) is then judged against a set fitted on the levels in between, as a
        window of its own would have been, not against a set of the first level only.
        """
        ws = self.config.window_s
        lower = end_s - ws + 1e-9                  # the window's own samples: t > lower
        k_own = int(np.searchsorted(clean.t, lower, side='right'))
        parts = [(end_s, clean.select(slice(k_own, None)))]
        if k_own:
            span = np.floor((lower - clean.t[:k_own]) / ws).astype(np.int64) + 1
            for j in range(int(span[0]), 0, -1):   # oldest first (stamps increase)
                part = clean.select(np.flatnonzero(span == j))
                if part.n:
                    parts.insert(-1, (end_s - j * ws, part))
        return parts

    def _admit(self, clean, end_s, keep):
        """
        Judge screened new samples against the reference; bin them unless inconsistent.

        Returns False (samples counted as ``samples_flagged['inconsistent']``) when the last
        valid set explains them much worse than its own data (:meth:`_consistency`) and no
        reference reset is due (``inconsistent_reset_s``); True when they were binned.  Of
        consistent samples, those with a force offset against the set in use
        (``acceptance_checks``, :meth:`~mr_damper_model.acceptance.Acceptance.offset_flags`:
        the onset or end of a step inside the part) are counted as
        ``samples_flagged['offset']`` and left out of the bins.
        """
        cfg = self.config
        c = self.counters
        if self._consistency(clean):
            if self._inconsistent_since is None:
                self._inconsistent_since = end_s
            if not (0 < cfg.inconsistent_reset_s <= end_s - self._inconsistent_since):
                c['samples_flagged']['inconsistent'] += clean.n
                return False
            c['reference_resets'] += 1          # start afresh from these samples
            self._ref = None
            self._bins.clear()
            self._last_solution.clear()
            self._accept.reset()
        self._inconsistent_since = None
        if cfg.acceptance_checks and clean.n and self._ref is not None:
            # force offsets against the set in use (fitted on the part before this one) that
            # the part's overall consistency hides: a step that begins or ends in it
            offset = self._accept.offset_flags(clean, clean.n, self._ref['scale'], end_s)
            if offset.any():
                c['samples_flagged']['offset'] += int(np.count_nonzero(offset))
                clean = clean.select(~offset)
        self._update_bins(clean, keep, end_s)
        self._accept.remember(clean, end_s)
        c['samples_binned'] += clean.n
        return True

    def _fit_bins(self, data, keep, t_start, catch_up=False):
        """
        Fit the usable bins; return the estimate (None: no usable bin or a fit error).

        ``data``: the window (its first and last stamps are the estimate's); ``keep``: samples
        a window holds (a bin is usable with ``min_bin_fraction`` of them).  A catch-up fit
        (samples of superseded windows, see :meth:`_catch_up_parts`) is counted in
        ``catch_up_fits`` and, when valid, becomes the consistency reference and warm start;
        it is not published (:attr:`estimate` is the window's).
        """
        cfg = self.config
        c = self.counters
        usable = [b for b in sorted(self._bins.values(), key=lambda b: b.level)
                  if b.data.n >= max(cfg.min_bin_fraction * keep, 10)]
        if not usable:
            if not catch_up:
                c['windows_skipped']['no_bins'] += 1
                self.last_skip = 'no_bins'
            return None
        fit = DamperData.concatenate([b.data for b in usable])
        order = np.argsort(fit.t, kind='stable')
        fit = fit.select(order)
        if cfg.max_fit_samples and fit.n > cfg.max_fit_samples:
            step = int(math.ceil(fit.n / cfg.max_fit_samples))
            fit = fit.select(slice(None, None, step))
        levels = [b.level for b in usable]
        model = 'kwok' if len(usable) == 1 else 'kwok-current'
        x0 = self._warm_start(model, levels) if cfg.warm_start else None
        try:
            result = self._fit(fit, model, cfg, x0=x0)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
            c['fit_errors'] += 1
            self.last_error = f'{type(exc).__name__}: {exc}'
            return None
        self._last_solution[model] = dict(result.parameters)
        if model == 'kwok':
            params = kwok_to_kwok_current(result.parameters)
        else:
            params = dict(result.parameters)
            self._last_solution['kwok'] = kwok_current_at(params, levels[-1], cfg.i_ref_a)
        nrmse = float(result.metrics.get('nrmse_percent', math.nan))
        rmse = float(result.metrics.get('rmse_n', math.nan))
        scale = robust_range(fit.f)
        robust_nrmse = 100.0 * rmse / scale if scale > 0 else math.nan
        f_new = self._force(params, fit)
        reason = self._judge(model, result.parameters, robust_nrmse, fit, f_new, scale,
                             max(levels) - min(levels))
        held = ''
        if not reason and cfg.acceptance_checks:
            held = self._accept.review(params, fit, data)
            if held and self._accept.current is None:
                reason, held = held, ''      # nothing to hold: published as not valid
        seconds = time.perf_counter() - t_start
        est = LiveEstimate(
            parameters=params, valid=not (reason or held), reason=reason or held,
            model_fitted=model,
            i_ref_a=float(cfg.i_ref_a), window_start_s=float(data.t[0]),
            window_end_s=float(data.t[-1]), current_min_a=float(min(levels)),
            current_max_a=float(max(levels)), rmse_n=rmse, nrmse_percent=nrmse,
            robust_nrmse_percent=robust_nrmse, seconds=seconds, n_samples=fit.n, bins_a=levels,
            result=result)
        if est.valid and cfg.acceptance_checks:
            self._accept.take(params, fit, est.window_start_s, est.window_end_s, rmse)
            self._in_use = est
        if catch_up:
            c['catch_up_fits'] += 1
            if est.valid:
                self._set_reference(est, fit, f_new, scale)
            return est
        c['windows_fitted'] += 1
        self.last_compute_s = seconds
        self._compute_sum += seconds
        self.compute_s_max = max(self.compute_s_max, seconds)
        self.estimate = est
        self.last_held = held
        if est.valid:
            c['windows_valid'] += 1
            self.last_good = est
            self._set_reference(est, fit, f_new, scale)
        else:
            key = est.reason.split(':')[0]
            c['windows_refused'][key] = c['windows_refused'].get(key, 0) + 1
            if held:                         # the set in use stays: re-published, valid
                self.estimate = replace(self._in_use, held=held, seconds=seconds)
                return self.estimate
        return est

    # ---------------------------------------------------------------- validity
    def _force(self, params, data):
        """Kwok-current force [N] of a parameter dict on ``data``."""
        return kwok_current_force(dict(params, i_ref_a=self.config.i_ref_a), data.x, data.v,
                                  data.i)

    def _covered(self, ref, data):
        """Mask of the samples at current levels the reference set ``ref`` was fitted on."""
        tol = 0.5 * self.config.current_bin_a
        return (data.i >= ref['current_min_a'] - tol) & (data.i <= ref['current_max_a'] + tol)

    def _judge(self, model, fitted, robust_nrmse, fit, f_new, scale, span_a):
        """
        Return why a fitted set is not valid, or ''.

        ``beta1`` (the current slope of beta) may sit at its bound when the fitted current
        span is below half of ``i_ref_a``: over a narrow span a real damper's beta change
        extrapolates beyond the +-3 box (seen on the Spencer plant at 0 and 0.5 A); such sets
        are also too narrow for the quarter car, which refuses any pinned set.
        """
        cfg = self.config
        reason = _in_bounds(model, fitted, cfg.unbounded, cfg.i_ref_a)
        if reason:
            return reason
        from .models import get_model
        mdl = get_model(model, **({'i_ref_a': cfg.i_ref_a} if model == 'kwok-current' else {}))
        lo, hi = mdl.default_bounds(unbounded=cfg.unbounded)
        pinned = pinned_parameters(mdl.param_names, [fitted[n] for n in mdl.param_names],
                                   lo, hi, cfg.pinned_fraction)
        if span_a < 0.5 * cfg.i_ref_a:
            pinned = [n for n in pinned if n != 'beta1']
        if pinned:
            return 'pinned:' + ','.join(pinned)
        if not (robust_nrmse <= cfg.max_nrmse_percent):
            return 'nrmse_above_threshold'
        ref = self._ref
        if ref is not None:
            cov = self._covered(ref, fit)
            if np.count_nonzero(cov) >= MIN_CHECK_SAMPLES:
                e_new = float(np.sqrt(np.mean((fit.f[cov] - f_new[cov]) ** 2)))
                f_prev = self._force(ref['parameters'], fit.select(cov))
                e_prev = float(np.sqrt(np.mean((fit.f[cov] - f_prev) ** 2)))
                floor = 0.01 * cfg.error_floor_percent * scale
                self.last_check['new_vs_last_valid_rmse_n'] = (e_new, e_prev)
                if e_new > cfg.max_error_ratio * e_prev + floor:
                    return 'worse_than_last_valid'
        return ''

    def _cells(self, ref, data):
        """Return the cell codes (current, x, v cell) of samples in ``ref``; -1 off its grid."""
        xe, ve = ref['x_edges'], ref['v_edges']
        ix = np.searchsorted(xe, data.x, side='right') - 1
        iv = np.searchsorted(ve, data.v, side='right') - 1
        ix[data.x == xe[-1]] = STATE_CELLS - 1
        iv[data.v == ve[-1]] = STATE_CELLS - 1
        inside = (ix >= 0) & (ix < STATE_CELLS) & (iv >= 0) & (iv < STATE_CELLS)
        keys = np.round(data.i / self.config.current_bin_a).astype(np.int64)
        code = (keys * STATE_CELLS + ix) * STATE_CELLS + iv
        return np.where(inside, code, -1)

    def _set_reference(self, est, fit, f_new, scale):
        """
        Keep a valid set with its mean square error on its fit data per state cell.

        Cells: current bin x ``STATE_CELLS`` displacement cells x ``STATE_CELLS`` velocity
        cells over the fit data's range; the model error of a Kwok fit depends on the phase of
        the cycle (e.g. larger on one stroke of a real damper), so new samples are compared
        with the error the set made at the same current and state.
        """
        x_edges = np.linspace(float(fit.x.min()), float(fit.x.max()), STATE_CELLS + 1)
        v_edges = np.linspace(float(fit.v.min()), float(fit.v.max()), STATE_CELLS + 1)
        ref = {'parameters': dict(est.parameters), 'current_min_a': est.current_min_a,
               'current_max_a': est.current_max_a, 'x_edges': x_edges, 'v_edges': v_edges,
               'scale': scale, 'cell_ms': {}}
        codes = self._cells(ref, fit)
        sq = (fit.f - f_new) ** 2
        ok = codes >= 0
        uniq, inverse, counts = np.unique(codes[ok], return_inverse=True, return_counts=True)
        sums = np.bincount(inverse, weights=sq[ok], minlength=uniq.size)
        ref['cell_ms'] = {int(u): float(m) for u, m, n in zip(uniq, sums / counts, counts)
                          if n >= MIN_CELL_SAMPLES}
        self._ref = ref

    def _consistency(self, new):
        """
        Return 'inconsistent' if the last valid set explains ``new`` much worse than its data.

        Compares the RMSE of the last valid set of this stream on the new screened samples
        with its RMSE on the samples it was fitted on in the same state cells (current level,
        displacement and velocity, see :meth:`_set_reference`): ``max_shift_ratio`` times,
        plus ``error_floor_percent`` of its robust force range.  Samples in cells the set
        was not fitted on are not judged; fewer than ``MIN_CHECK_SAMPLES`` judged samples:
        no judgement ('').
        """
        ref = self._ref
        if ref is None or new.n < MIN_CHECK_SAMPLES:
            return ''
        cfg = self.config
        codes = self._cells(ref, new)
        cell_ms = ref['cell_ms']
        known = np.array([int(k) in cell_ms for k in codes], dtype=bool)
        if np.count_nonzero(known) < MIN_CHECK_SAMPLES:
            return ''
        part = new.select(known)
        r = part.f - self._force(ref['parameters'], part)
        expected = np.array([cell_ms[int(k)] for k in codes[known]])
        e_new = float(np.sqrt(np.mean(r * r)))
        limit = (cfg.max_shift_ratio * float(np.sqrt(np.mean(expected)))
                 + 0.01 * cfg.error_floor_percent * ref['scale'])
        self.last_check['new_samples_rmse_n'] = (e_new, limit)
        return 'inconsistent' if e_new > limit else ''

    def _warm_start(self, model, levels):
        if model in self._last_solution:
            return dict(self._last_solution[model])
        if model == 'kwok' and 'kwok-current' in self._last_solution:
            return kwok_current_at(self._last_solution['kwok-current'], levels[0],
                                   self.config.i_ref_a)
        if model == 'kwok-current' and 'kwok' in self._last_solution:
            return kwok_to_kwok_current(self._last_solution['kwok'])
        return None

    def _update_bins(self, new, keep, newest_s):
        """File ``new`` samples by current; each bin keeps its newest ``keep`` samples."""
        cfg = self.config
        if new.n:
            keys = np.round(new.i / cfg.current_bin_a).astype(int)
            for key in np.unique(keys):
                part = new.select(keys == key)
                old = self._bins.get(int(key))
                if old is not None:
                    part = DamperData.concatenate([old.data, part])
                if part.n > keep:
                    part = part.select(slice(part.n - keep, None))
                self._bins[int(key)] = _Bin(float(np.median(part.i)), part)
        if cfg.bin_max_age_s > 0:
            for key in [k for k, b in self._bins.items()
                        if b.newest_s < newest_s - cfg.bin_max_age_s]:
                del self._bins[key]

    def replay(self, data, every=1):
        """
        Feed a record sample by sample, processing the due window every ``every`` samples.

        The offline counterpart of the node (which asks for windows between callbacks):
        deterministic when the configuration has no wall-time budget.

        Parameters
        ----------
        data : DamperData
            Samples in stream order.
        every : int
            Samples between window requests.

        Returns
        -------
        list of LiveEstimate
            The estimates in order (skipped windows give none).

        """
        out = []
        for k, row in enumerate(zip(data.t, data.x, data.v, data.f, data.i)):
            self.add_sample(*row)
            if k % every == 0:
                window = self.next_window()
                if window is not None:
                    est = self.process(window)
                    if est is not None:
                        out.append(est)
        return out

    # ---------------------------------------------------------------- status
    def status(self):
        """
        Return the status counters and figures as a JSON-ready dict.

        Keys: ``samples_received``, ``samples_accepted``, ``rejected`` {reason: count},
        ``out_of_range`` {channel: count}, ``stream_restarts``, ``stamp_gaps``, ``windows_due``,
        ``windows_superseded``, ``windows_overflow`` (in-order mode: passed over, their samples
        left the buffer), ``windows_fitted``, ``windows_valid``, ``windows_skipped``
        {reason: count}, ``windows_refused`` {reason: count} (fitted, published not valid),
        ``samples_binned``, ``samples_unbinned`` (new samples of skipped windows),
        ``samples_lost`` (left the buffer before a window handed them out),
        ``samples_pending`` (accepted, not yet handed out: after the last due window end),
        ``samples_flagged`` {reason: count}, ``reference_resets``, ``catch_up_fits`` (fits of
        the samples of superseded windows, see :meth:`_catch_up_parts`), ``fit_errors``,
        ``last_window_start_s``,
        ``last_window_end_s`` (stamps of the first and last sample of the last fitted window
        [s]), ``processed_up_to_s`` (end of the last window processed, skipped or fitted: every
        sample up to it has been judged [s]), ``last_skip`` (why the last processed window was
        skipped, '' if it was not), ``last_valid``, ``last_reason``, ``last_model``,
        ``last_nrmse_percent``,
        ``last_robust_nrmse_percent``, ``last_check`` (last consistency figures [N]),
        ``compute_s_last``, ``compute_s_mean``, ``compute_s_max``, ``bins_a`` (current levels
        held), ``last_error``, ``last_held`` (why the last fitted window's set was refused and
        the set in use re-published, '' if taken), ``held_age_s`` (newest window end minus the
        set in use's [s]), ``last_condition_number``, ``offset`` and ``f0_trend``
        (:class:`~mr_damper_model.acceptance.Acceptance`).
        """
        with self._lock:
            c = {k: (dict(v) if isinstance(v, dict) else v) for k, v in self.counters.items()}
            c['samples_pending'] = self._seq - self._handed
        est = self.estimate
        fitted = c['windows_fitted']
        c.update(
            last_window_start_s=est.window_start_s if est else math.nan,
            last_window_end_s=est.window_end_s if est else math.nan,
            processed_up_to_s=self.processed_up_to_s, last_skip=self.last_skip,
            last_valid=bool(est.valid) if est else False,
            last_reason=est.reason if est else 'no_estimate',
            last_model=est.model_fitted if est else '',
            last_nrmse_percent=est.nrmse_percent if est else math.nan,
            last_robust_nrmse_percent=est.robust_nrmse_percent if est else math.nan,
            last_check={k: list(v) for k, v in self.last_check.items()},
            compute_s_last=self.last_compute_s,
            compute_s_mean=self._compute_sum / fitted if fitted else math.nan,
            compute_s_max=self.compute_s_max,
            bins_a=sorted(b.level for b in list(self._bins.values())),
            last_error=self.last_error, last_held=self.last_held,
            held_age_s=self._accept.age_s(self.processed_up_to_s),
            last_condition_number=self._accept.last_figures.get('condition', math.nan),
            offset=dict(self._accept.offset), f0_trend=self._accept.f0_trend())
        for name in ('window', 'heldback'):
            if name in self._accept.last_figures:
                c['last_check'][f'new_vs_current_{name}_rmse_n'] = list(
                    self._accept.last_figures[name])
        return c


if __name__ == '__main__':
    _serve()
