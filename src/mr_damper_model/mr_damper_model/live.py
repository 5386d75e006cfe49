"""
Live (sliding-window) identification of the current-dependent Kwok model; no ROS.

The identifier node feeds samples in as they arrive and asks for windows; this module does all
the work, so it can be tested and benchmarked without ROS:

1. **Sample validation** (:meth:`LiveIdentifier.add_sample`): NaN/inf values and out-of-order or
   duplicate stamps are rejected and counted by reason; bad samples never reach the buffer.
   A stream that restarts from an earlier time (a replay started again) is detected by a run
   of ``restart_samples`` consecutive, increasing, out-of-order samples: the buffer restarts.
2. **Sliding window** (:meth:`LiveIdentifier.next_window`): a window of ``window_s`` seconds of
   *sample* time becomes due every ``hop_s``; when the fitter is slower than the hop, only the
   newest due window is fitted and the others are counted as superseded.
3. **Excitation check**: windows with too few samples, no motion (velocity RMS), no force
   variation or motion in one direction only are skipped and counted by reason.
4. **Current bins**: each window's samples are filed by coil current into bins of width
   ``current_bin_a``; each bin keeps its newest samples (as many as one window holds) and bins
   older than ``bin_max_age_s`` are dropped.  The Kwok model is algebraic (no internal state),
   so the union of the bins is a valid data set even though it joins different moments.
5. **Fit** (:func:`fit_data`, the same :func:`~mr_damper_model.identify.identify` call as the
   offline tool): separable PSO warm-started from the last solution, within ``budget_s``.  One
   usable bin: plain Kwok (mapped to kwok-current with zero current slopes, the covered range
   being that single current); two or more bins: kwok-current on their union.
6. **Validity**: finite parameters within the model bounds and ``nrmse_percent <=
   max_nrmse_percent``.

Threading: ``add_sample`` and ``next_window`` may be called from one thread and ``process``
(the fit) from another; the sample buffer is protected by a lock, the bins and the warm start
belong to the fitting thread.
"""
from dataclasses import dataclass, field
import math
import os
import pickle
import subprocess
import sys
import threading
import time

import numpy as np

from .data import DamperData
from .kwok_current import KwokCurrent, kwok_current_coefficients

KWOK_CURRENT_NAMES = KwokCurrent.param_names

#: Keys of the sample rejection counters.
REJECT_REASONS = ('nonfinite', 'out_of_order', 'duplicate', 'joint_names', 'layout')
#: Keys of the skipped-window counters.
SKIP_REASONS = ('few_samples', 'no_motion', 'no_force', 'one_direction', 'no_bins')


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

    def __post_init__(self):
        positive = ('window_s', 'hop_s', 'i_ref_a', 'max_nrmse_percent', 'current_bin_a',
                    'max_rate_hz')
        for name in positive:
            value = float(getattr(self, name))
            if not math.isfinite(value) or value <= 0:
                raise ValueError(f'`{name}` must be a positive finite number, got {value!r}')
        for name in ('budget_s', 'bin_max_age_s', 'min_velocity_rms_m_s', 'min_force_std_n',
                     'min_bin_fraction', 'min_direction_fraction'):
            value = float(getattr(self, name))
            if not math.isfinite(value) or value < 0:
                raise ValueError(f'`{name}` must be >= 0, got {value!r}')
        for name in ('maxiter', 'max_fit_samples', 'min_window_samples'):
            if int(getattr(self, name)) < 0:
                raise ValueError(f'`{name}` must be >= 0')
        if int(self.swarm_size) < 2:
            raise ValueError('`swarm_size` must be >= 2')
        if int(self.restart_samples) < 1:
            raise ValueError('`restart_samples` must be >= 1')
        if self.hop_s > self.window_s:
            raise ValueError(f'`hop_s` ({self.hop_s}) must not exceed `window_s` '
                             f'({self.window_s})')


@dataclass
class Window:
    """Samples of one due window (copies) and its scheduled end [s]."""

    data: DamperData
    end_s: float


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
        Fit quality on the fitted data.
    seconds : float
        Compute time of the window [s].
    n_samples : int
        Samples fitted.
    bins_a : list of float
        Current levels of the bins fitted [A].
    result : object
        The :class:`~mr_damper_model.identify.IdentificationResult` (None for a loaded one).

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
    seconds: float = 0.0
    n_samples: int = 0
    bins_a: list = field(default_factory=list)
    result: object = None

    def message_values(self):
        """Return the values of the ``kwok_parameters`` message (see ``messages``)."""
        d = dict(self.parameters)
        d.update(i_ref_a=self.i_ref_a, window_end_s=self.window_end_s,
                 current_min_a=self.current_min_a, current_max_a=self.current_max_a,
                 rmse_n=self.rmse_n, nrmse_percent=self.nrmse_percent, valid=self.valid)
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
        try:
            pickle.dump(request, self._proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self._proc.stdin.flush()
            status, value = pickle.load(self._proc.stdout)
        except (EOFError, OSError, pickle.UnpicklingError) as exc:
            self.close()
            raise RuntimeError(f'fit process failed ({type(exc).__name__}: {exc})') from None
        if status == 'error':
            raise value
        return value

    def warm_up(self):
        """Start the child and import the fitting code in it; return True."""
        return self._call('ping')

    def __call__(self, data, model, config, x0=None):
        """Run ``fit_data(data, model, config, x0=x0)`` in the child."""
        return self._call((data, model, config, x0))

    def close(self):
        """End the child process."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            proc.stdin.close()
            proc.wait(timeout=2.0)
        except (OSError, subprocess.TimeoutExpired):
            proc.kill()
            proc.wait()


def _serve():
    """Child side of :class:`FitProcess`: answer pickled requests until stdin closes."""
    out = os.fdopen(os.dup(1), 'wb')
    os.dup2(2, 1)            # anything printed goes to stderr, stdout carries results only
    from . import identify   # noqa: F401  (load numpy, scipy and the models once)
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
        self._fit = fit_data if fit is None else fit
        cfg = self.config
        self._cap = int(math.ceil((cfg.window_s + 3 * cfg.hop_s) * cfg.max_rate_hz)) + 16
        self._buf = np.empty((self._cap, 5))
        self._lock = threading.Lock()
        self._count = 0            # samples in the buffer (<= cap)
        self._head = 0             # next write position
        self._last_t = -math.inf
        self._t_origin = None      # first stamp of the current stream
        self._next_index = 0       # index m of the next due window end
        self._ooo_run = 0
        self._ooo_last = -math.inf
        self.counters = {'samples_received': 0, 'samples_accepted': 0,
                         'rejected': {r: 0 for r in REJECT_REASONS},
                         'stream_restarts': 0, 'windows_due': 0, 'windows_superseded': 0,
                         'windows_fitted': 0, 'windows_valid': 0,
                         'windows_skipped': {r: 0 for r in SKIP_REASONS},
                         'fit_errors': 0}
        self._bins = {}
        self._last_solution = {}   # model name -> parameter dict (warm start)
        self.estimate = None
        self.last_good = None
        self.last_compute_s = math.nan
        self.compute_s_max = 0.0
        self._compute_sum = 0.0
        self.last_error = ''
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

    def add_sample(self, t, x, v, f, i):
        """
        Offer one sample.

        Parameters
        ----------
        t : float
            Stamp [s].
        x, v, f, i : float
            Displacement [m], velocity [m/s], force [N], current [A].

        Returns
        -------
        str
            '' if accepted, else the rejection reason (``'nonfinite'``, ``'out_of_order'``,
            ``'duplicate'``).

        """
        with self._lock:
            c = self.counters
            c['samples_received'] += 1
            if not (math.isfinite(t) and math.isfinite(x) and math.isfinite(v)
                    and math.isfinite(f) and math.isfinite(i)):
                c['rejected']['nonfinite'] += 1
                return 'nonfinite'
            if t <= self._last_t:
                reason = 'duplicate' if t == self._last_t else 'out_of_order'
                if reason == 'out_of_order' and t > self._ooo_last:
                    self._ooo_run += 1
                else:
                    self._ooo_run = 1 if reason == 'out_of_order' else 0
                self._ooo_last = t
                if self._ooo_run < self.config.restart_samples:
                    c['rejected'][reason] += 1
                    return reason
                self._restart_stream()
            self._ooo_run = 0
            self._ooo_last = -math.inf
            if self._t_origin is None:
                self._t_origin = t
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
            c['samples_accepted'] += 1
            return ''

    def _restart_stream(self):
        self.counters['stream_restarts'] += 1
        self._count = 0
        self._head = 0
        self._last_t = -math.inf
        self._t_origin = None
        self._next_index = 0
        self._bins.clear()

    # ---------------------------------------------------------------- windows
    def next_window(self):
        """
        Return the newest due window (older due windows are counted as superseded), or None.

        Window ends are ``t0 + window_s + m * hop_s`` in sample time, ``t0`` the first stamp.
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
            self.counters['windows_due'] += 1
            self.counters['windows_superseded'] += m - self._next_index
            self._next_index = m + 1
            end = first_end + m * cfg.hop_s
            n = self._count
            idx = (self._head - n + np.arange(n)) % self._cap
            rows = self._buf[idx]
        keep = (rows[:, 0] > end - cfg.window_s + 1e-9) & (rows[:, 0] <= end + 1e-9)
        rows = rows[keep]
        return Window(DamperData(*rows.T, source='window'), end)

    # ---------------------------------------------------------------- fitting
    def process(self, window):
        """
        Check, bin and fit one window; return the new estimate (None if skipped).

        Parameters
        ----------
        window : Window
            From :meth:`next_window`.

        Returns
        -------
        LiveEstimate or None
            The estimate (also stored as :attr:`estimate`; :attr:`last_good` if valid).

        """
        t_start = time.perf_counter()
        cfg = self.config
        c = self.counters
        data = window.data
        reason = check_excitation(data, cfg)
        if reason:
            c['windows_skipped'][reason] += 1
            return None
        self._update_bins(data)
        usable = [b for b in sorted(self._bins.values(), key=lambda b: b.level)
                  if b.data.n >= max(cfg.min_bin_fraction * data.n, 10)]
        if not usable:
            c['windows_skipped']['no_bins'] += 1
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
        reason = _in_bounds(model, result.parameters, cfg.unbounded, cfg.i_ref_a)
        if not reason and not (nrmse <= cfg.max_nrmse_percent):
            reason = 'nrmse_above_threshold'
        seconds = time.perf_counter() - t_start
        est = LiveEstimate(
            parameters=params, valid=not reason, reason=reason, model_fitted=model,
            i_ref_a=float(cfg.i_ref_a), window_start_s=float(data.t[0]),
            window_end_s=float(data.t[-1]), current_min_a=float(min(levels)),
            current_max_a=float(max(levels)),
            rmse_n=float(result.metrics.get('rmse_n', math.nan)), nrmse_percent=nrmse,
            seconds=seconds, n_samples=fit.n, bins_a=levels, result=result)
        c['windows_fitted'] += 1
        self.last_compute_s = seconds
        self._compute_sum += seconds
        self.compute_s_max = max(self.compute_s_max, seconds)
        self.estimate = est
        if est.valid:
            c['windows_valid'] += 1
            self.last_good = est
        return est

    def _warm_start(self, model, levels):
        if model in self._last_solution:
            return dict(self._last_solution[model])
        if model == 'kwok' and 'kwok-current' in self._last_solution:
            return kwok_current_at(self._last_solution['kwok-current'], levels[0],
                                   self.config.i_ref_a)
        if model == 'kwok-current' and 'kwok' in self._last_solution:
            return kwok_to_kwok_current(self._last_solution['kwok'])
        return None

    def _update_bins(self, data):
        cfg = self.config
        keys = np.round(data.i / cfg.current_bin_a).astype(int)
        t_start = float(data.t[0])
        for key in np.unique(keys):
            part = data.select(keys == key)
            old = self._bins.get(int(key))
            if old is not None:
                older = old.data.select(old.data.t < t_start)
                if older.n:
                    part = DamperData.concatenate([older, part])
            if part.n > data.n:
                part = part.select(slice(part.n - data.n, None))
            self._bins[int(key)] = _Bin(float(np.median(part.i)), part)
        if cfg.bin_max_age_s > 0:
            newest = float(data.t[-1])
            for key in [k for k, b in self._bins.items()
                        if b.newest_s < newest - cfg.bin_max_age_s]:
                del self._bins[key]

    # ---------------------------------------------------------------- status
    def status(self):
        """
        Return the status counters and figures as a JSON-ready dict.

        Keys: ``samples_received``, ``samples_accepted``, ``rejected`` {reason: count},
        ``stream_restarts``, ``windows_due``, ``windows_superseded``, ``windows_fitted``,
        ``windows_valid``, ``windows_skipped`` {reason: count}, ``fit_errors``,
        ``last_window_start_s``, ``last_window_end_s`` (stamps of the first and last sample
        of the last fitted window [s]), ``last_valid``, ``last_reason``, ``last_model``,
        ``last_nrmse_percent``, ``compute_s_last``, ``compute_s_mean``, ``compute_s_max``,
        ``bins_a`` (current levels held), ``last_error``.
        """
        with self._lock:
            c = {k: (dict(v) if isinstance(v, dict) else v) for k, v in self.counters.items()}
        est = self.estimate
        fitted = c['windows_fitted']
        c.update(
            last_window_start_s=est.window_start_s if est else math.nan,
            last_window_end_s=est.window_end_s if est else math.nan,
            last_valid=bool(est.valid) if est else False,
            last_reason=est.reason if est else 'no_estimate',
            last_model=est.model_fitted if est else '',
            last_nrmse_percent=est.nrmse_percent if est else math.nan,
            compute_s_last=self.last_compute_s,
            compute_s_mean=self._compute_sum / fitted if fitted else math.nan,
            compute_s_max=self.compute_s_max,
            bins_a=sorted(b.level for b in list(self._bins.values())),
            last_error=self.last_error)
        return c


if __name__ == '__main__':
    _serve()
