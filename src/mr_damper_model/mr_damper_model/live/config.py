"""Settings of the live identifier and the names of its counters (no ROS)."""
from dataclasses import dataclass, fields, replace
import math

from mr_damper_model.models.validity import PINNED_FRACTION

#: Keys of the sample rejection counters.
REJECT_REASONS = ('nonfinite', 'out_of_order', 'duplicate', 'future_stamp', 'joint_names',
                  'layout', 'inconsistent_batch')
#: Keys of the out-of-range sample counters (the channel whose range check failed).
RANGE_CHANNELS = ('force', 'velocity', 'displacement', 'current')
#: Keys of the skipped-window counters.
SKIP_REASONS = ('gap', 'few_samples', 'no_motion', 'no_force', 'one_direction', 'inconsistent',
                'no_bins')
#: Keys of the flagged-sample counters (samples kept out of the fit and the bins).
FLAG_REASONS = ('outlier', 'stuck', 'dropout', 'offset', 'inconsistent')


def new_counters():
    """Return the live identifier's counters, all zero (``LiveIdentifier.status`` lists them)."""
    return {'samples_received': 0, 'samples_accepted': 0,
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
        Horizon [s] on the stream's own clock: a batch (or a single sample) stamped more than
        this ahead of where the stream's clock says the stream is (its newest stamp advanced at
        the stream's recent rate against the node clock,
        :class:`~mr_damper_common.stamps.StampGuard` with ``stream_clock``) is refused whole
        (``rejected['future_stamp']``, every sample) and never becomes the reference; a
        stream that really jumped ahead is followed after ``restart_samples`` such samples in
        consecutive batches that follow each other. The stream's rate is measured, so this
        holds at any ``rate_factor`` (a replay at 4x on wall time, as fast as the reader takes
        it, under ``use_sim_time``); before the stream's first sample nothing is in the
        future. 0: no such check.
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
        (:mod:`~mr_damper_model.identification.acceptance`): excitation, comparison with the set
        in use on
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
        Held-back part: the admitted samples of this long [s] before a window's own samples,
        reaching back further to the second most recent velocity reversal (both ends of the
        stroke) up to ``holdout_max_s``.
    holdout_max_s : float
        Longest held-back part [s] (a slow excitation: 0.1 Hz needs 10-15 s).
    offset_window_s : float
        Running-median length of the force-offset screen [s].
    offset_ratio : float
        A force offset: the smoothed residual of the set in use (less its mean in the state
        cell) beyond this times its RMS error, plus the error floor.
    drift_window_s : float
        The f0 trend is the slope over the accepted sets of this long [s].
    force_step_percent : float
        A set whose own fit data holds a force step is refused (``force_step``; published not
        valid when no set is in use, else the set in use re-published): comparable whole cycles
        whose mean forces differ, or a persistent mid-stroke jump of its residual, beyond this
        [% of the level's robust force range] (:func:`~mr_damper_model.live.screening.
        force_step`).  Needs no earlier set: a sensor offset that begins or ends inside the
        first windows of a stream, before any set can be compared with, is refused; 0: no
        such check.

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
    max_future_s: float = 1.0
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
    pinned_fraction: float = PINNED_FRACTION
    inconsistent_reset_s: float = 0.0
    backlog_windows: int = 0
    acceptance_checks: bool = True
    min_amplitude_ratio: float = 0.7
    velocity_bins: int = 6
    min_velocity_bin_share: float = 0.03
    max_condition_number: float = 100.0
    replace_margin: float = 0.0
    holdout_s: float = 2.0
    holdout_max_s: float = 20.0
    offset_window_s: float = 0.2
    offset_ratio: float = 3.0
    drift_window_s: float = 300.0
    force_step_percent: float = 6.0

    def __post_init__(self):
        positive = ('window_s', 'hop_s', 'i_ref_a', 'max_nrmse_percent', 'current_bin_a',
                    'max_rate_hz', 'force_limit_n', 'velocity_limit_m_s',
                    'displacement_limit_m', 'max_gap_s', 'outlier_mad_k', 'stuck_s',
                    'max_error_ratio', 'max_shift_ratio', 'max_condition_number',
                    'holdout_s', 'holdout_max_s', 'offset_window_s', 'offset_ratio',
                    'drift_window_s')
        for name in positive:
            value = float(getattr(self, name))
            if not math.isfinite(value) or value <= 0:
                raise ValueError(f'`{name}` must be a positive finite number, got {value!r}')
        for name in ('budget_s', 'bin_max_age_s', 'min_velocity_rms_m_s', 'min_force_std_n',
                     'min_bin_fraction', 'min_direction_fraction', 'outlier_floor_fraction',
                     'error_floor_percent', 'pinned_fraction', 'inconsistent_reset_s',
                     'max_future_s', 'min_amplitude_ratio', 'min_velocity_bin_share',
                     'replace_margin', 'force_step_percent'):
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

    def with_dynamic(self, **changes):
        """
        Return a copy with fields of :data:`DYNAMIC_FIELDS` changed (validated as a whole).

        Raises
        ------
        ValueError
            A field that is not dynamic or unknown, or a value the new configuration refuses.

        """
        names = {f.name for f in fields(self)}
        for name in changes:
            if name not in names:
                raise ValueError(f'`{name}` is not a LiveConfig setting')
            if name not in DYNAMIC_FIELDS:
                raise ValueError(f'`{name}` is read at start-up and cannot change while running')
        return replace(self, **changes)


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
    'holdout_s', 'holdout_max_s', 'offset_window_s', 'offset_ratio',
    'drift_window_s', 'force_step_percent')
