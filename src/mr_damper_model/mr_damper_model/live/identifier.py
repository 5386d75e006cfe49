"""
The sliding-window identifier of the current-dependent Kwok model (no ROS).

Steps 1-8 of the package docstring as one state machine, :class:`LiveIdentifier`, under one
lock discipline (samples in one thread, fits in another).  Its parts each have a module: the
sample buffer and the windows it hands out (``sample_ring.SampleRing``), the samples by current
(``current_bins.CurrentBins``), the set in use as a consistency reference
(``reference.ConsistencyReference``), the acceptance review
(``identification.acceptance.Acceptance``); what needs no state lives in ``config``,
``screening``, ``fitting``, ``conversions`` and ``window``.  What stays (about 630 lines, half
of them docstrings; over the project's ~600 lines on purpose) is the state machine itself:
the steps that read and write the shared counters and the gate's state under the one lock.
"""
from dataclasses import replace
import math
import threading
import time

import numpy as np

from mr_damper_common.stamps import ACCEPTED, REBASED
from mr_damper_model.identification.acceptance import Acceptance
from mr_damper_model.io.data import DamperData
from mr_damper_model.live.config import LiveConfig, new_counters
from mr_damper_model.live.conversions import (initial_estimate, kwok_current_at,
                                              kwok_to_kwok_current, warm_start)
from mr_damper_model.live.current_bins import CurrentBins, fit_samples
from mr_damper_model.live.fitting import fit_data, parameter_reason, window_seed
from mr_damper_model.live.reference import ConsistencyReference, model_force
from mr_damper_model.live.sample_ring import SampleRing
from mr_damper_model.live.screening import (check_excitation, continued_runs, flag_samples,
                                            force_step, robust_range)
from mr_damper_model.live.window import catch_up_parts, LiveEstimate, Window


def _ring(name):
    """Read-only view of a ``SampleRing`` attribute under the identifier's former name."""
    return property(lambda self: getattr(self._ring, name), doc=f'``SampleRing.{name}``')


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
        self._lock = threading.Lock()
        self.counters = new_counters()
        # the samples (stamp sanity, ring, windows handed out) and the bins by current
        self._ring = SampleRing(self.config, self.counters, self._restart_stream)
        self._bins = CurrentBins()
        self._ref = None           # last valid set of this stream, as a consistency reference
        self._refused_since = None  # newest stamp taken before a run of inconsistent batches
        self._inconsistent_since = None   # window end of the first of consecutive rejections
        self._excluded_s = -math.inf      # newest stamp of a sample kept out (flag, gate)
        self._prev_whole = True           # the last judged part was consistent as a whole
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
            self.estimate = initial_estimate(initial, self.config)
            if self.estimate is not None:
                self._last_solution['kwok-current'] = dict(self.estimate.parameters)
                if self.estimate.valid:
                    self.last_good = self.estimate

    _buf, _cap, _count, _head = _ring('buf'), _ring('cap'), _ring('count'), _ring('head')
    _last_t, _t_origin, _stamps = _ring('last_t'), _ring('t_origin'), _ring('stamps')
    _seq, _handed = _ring('seq'), _ring('handed')

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
            return self._ring.add_one(float(t), float(x), float(v), float(f), float(i),
                                      self.config, now)

    def add_samples(self, t, x, v, f, i, now=None):
        """
        Offer a batch of consecutive samples (one measurement message), in order.

        The batch is first judged as a whole against the stream's own clock
        (:meth:`~mr_damper_common.stamps.StampGuard.batch_verdict`): a batch reaching more than
        ``max_future_s`` ahead of it is refused whole (every sample ``future_stamp``), so one
        message cannot carry the stream ahead and displace it.  Otherwise the result is
        that of :meth:`add_sample` called on each sample in turn (without its own future
        check: the batch was judged); a batch that is clean (finite, in range, stamps
        increasing past the newest accepted one) is taken with array operations, others
        sample by sample.

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
            verdict = self._ring.stamps.batch_verdict(t, now) if n else ACCEPTED
            if verdict == 'future_stamp':
                self.counters['samples_received'] += n
                self.counters['rejected']['future_stamp'] += n
                return [(k, 'future_stamp') for k in range(n)]
            if verdict == REBASED:
                self._restart_stream()
            elif self._refuse_inconsistent(t, x, v, f, i, cfg):
                self.counters['samples_received'] += n
                self.counters['rejected']['inconsistent_batch'] += n
                return [(k, 'inconsistent_batch') for k in range(n)]
            if n and self._ring.clean_batch(t, x, v, f, i, cfg, now):
                self._ring.append_batch(t, x, v, f, i, cfg, now)
                return []
            rejected = []
            for k in range(n):
                reason = self._ring.add_one(float(t[k]), float(x[k]), float(v[k]), float(f[k]),
                                            float(i[k]), cfg, now, judged=True)
                if reason:
                    rejected.append((k, reason))
            return rejected

    def _refuse_inconsistent(self, t, x, v, f, i, cfg):
        """
        Tell whether to refuse a batch the set in use cannot explain (lock held).

        :meth:`~mr_damper_model.live.reference.ConsistencyReference.judge_batch` against the
        consistency reference.  The first inconsistent batch after a consistent one is refused
        whatever its length (one message that would carry the stream's stamps); the ones after
        it only while the stamps they would leave out stay within ``max_gap_s`` of the newest
        sample taken before them: a lasting change goes on to the window's gate (which keeps it
        out of the bins and may reset the reference) without a stamp gap that skips windows.
        """
        verdict = None if self._ref is None else self._ref.judge_batch(t, x, v, f, i, cfg)
        if not verdict:
            if verdict is not None:         # consistent (not merely unjudged)
                self._refused_since = None
            return False
        if self._refused_since is None:
            self._refused_since = self._ring.last_t
            return True
        finite = t[np.isfinite(t)]
        step = float(np.median(np.diff(finite))) if finite.size > 1 else 0.0
        return float(finite.max()) + step - self._refused_since <= cfg.max_gap_s

    def _restart_stream(self):
        """Start a new stream (lock held): restart the ring, drop the bins and the reference."""
        self._ring.restart()
        self._bins.clear()
        self._ref = None
        self._excluded_s = -math.inf
        self._prev_whole = True

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
        with self._lock:
            taken = self._ring.next_window(self.config)
        if taken is None:
            return None
        rows, k_window, end, n_new, first_new_seq, m = taken
        span = DamperData(*rows.T, source='window')
        return Window(span.select(slice(k_window, None)), end, span, n_new, first_new_seq, m)

    def _give_back(self, window, n):
        """Offer the last ``n`` new samples of ``window`` again with the next window."""
        with self._lock:
            self._ring.give_back(window.first_new_seq, window.n_new, n)

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
        config = self.config.with_dynamic(**changes)
        self.config = config
        self._ring.stamps.rebase_after = int(config.restart_samples)
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
        flags = flag_samples(span, cfg)
        # a constant run that began among samples already kept out is that fault going on
        more = (flags == '') & continued_runs(span.f, span.t, 0.5 * cfg.stuck_s,
                                              self._excluded_s)
        flags[more] = np.where(span.f[more] == 0.0, 'dropout', 'stuck')
        flags = flags[span.n - new.n:]
        for name in ('outlier', 'stuck', 'dropout'):
            c['samples_flagged'][name] += int(np.count_nonzero(flags == name))
        self._exclude(new.t[flags != ''])
        clean = new.select(flags == '')
        # new samples older than this window (windows superseded while the fitter was busy)
        # are judged, binned and fitted one window length at a time, in time order
        parts = catch_up_parts(clean, window.end_s, cfg.window_s)
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

    def _admit(self, clean, end_s, keep):
        """
        Judge screened new samples against the reference; bin them unless inconsistent.

        Returns False (samples counted as ``samples_flagged['inconsistent']``) when the last
        valid set explains them much worse than its own data (:meth:`_consistency`) and no
        reference reset is due (``inconsistent_reset_s``); True when they were binned.  Of
        consistent samples, those with a force offset against the set in use
        (``acceptance_checks``,
        :meth:`~mr_damper_model.identification.acceptance.Acceptance.offset_flags`:
        the onset or end of a step inside the part) are counted as
        ``samples_flagged['offset']`` and left out of the bins.
        """
        cfg = self.config
        c = self.counters
        inconsistent = self._consistency(clean)
        prev_whole, self._prev_whole = self._prev_whole, not inconsistent
        if inconsistent and prev_whole:
            # the onset of a fault inside the part: the blocks before it still count
            fine = self._ref.consistent_blocks(clean, cfg)
            if fine.any():
                c['samples_flagged']['inconsistent'] += int(np.count_nonzero(~fine))
                self._exclude(clean.t[~fine])
                clean = clean.select(fine)
                inconsistent = ''
        if inconsistent:
            if self._inconsistent_since is None:
                self._inconsistent_since = end_s
            if not (0 < cfg.inconsistent_reset_s <= end_s - self._inconsistent_since):
                c['samples_flagged']['inconsistent'] += clean.n
                self._exclude(clean.t)
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
            offset = self._accept.offset_flags(clean, clean.n, self._ref.scale, end_s)
            if offset.any():
                c['samples_flagged']['offset'] += int(np.count_nonzero(offset))
                clean = clean.select(~offset)
        self._bins.update(clean, keep, end_s, cfg.current_bin_a, cfg.bin_max_age_s)
        self._accept.remember(clean, end_s)
        c['samples_binned'] += clean.n
        return True

    def _fit_bins(self, data, keep, t_start, catch_up=False):
        """
        Fit the usable bins; return the estimate (None: no usable bin or a fit error).

        ``data``: the window (its first and last stamps are the estimate's); ``keep``: samples
        a window holds (a bin is usable with ``min_bin_fraction`` of them).  A catch-up fit
        (samples of superseded windows, see :func:`~mr_damper_model.live.window.catch_up_parts`)
        is counted in ``catch_up_fits`` and, when valid, becomes the consistency reference and
        warm start; it is not published (:attr:`estimate` is the window's).
        """
        cfg = self.config
        c = self.counters
        start = float(data.t[0])
        # samples of the window kept out: each level on the window's remaining samples
        trim = not catch_up and self._excluded_s >= start
        usable = self._bins.usable(max(cfg.min_bin_fraction * keep, 10),
                                   start if trim else None)
        if not usable:
            if not catch_up:
                c['windows_skipped']['no_bins'] += 1
                self.last_skip = 'no_bins'
            return None
        fit = fit_samples(usable, cfg.max_fit_samples)
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
        # a force step in the set's own data (an offset no earlier set could catch): its
        # samples are no evidence for the held-back comparisons either
        step = '' if reason else force_step(fit, fit.f - f_new, cfg)
        if step:
            self._accept.forget(float(fit.t[0]), float(fit.t[-1]))
        held = ''
        if not reason and cfg.acceptance_checks:
            held = step or self._accept.review(params, fit, data)
            if held and self._accept.current is None:
                reason, held = held, ''      # nothing to hold: published as not valid
        elif not reason:
            reason = step
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
        return model_force(params, data, self.config.i_ref_a)

    def _judge(self, model, fitted, robust_nrmse, fit, f_new, scale, span_a):
        """
        Return why a fitted set is not valid, or ''.

        ``beta1`` (the current slope of beta) may sit at its bound when the fitted current
        span is below half of ``i_ref_a``: over a narrow span a real damper's beta change
        extrapolates beyond the +-3 box (seen on the Spencer plant at 0 and 0.5 A); such sets
        are also too narrow for the quarter car, which refuses any pinned set.
        """
        cfg = self.config
        reason = parameter_reason(model, fitted, cfg.unbounded, cfg.i_ref_a, cfg.pinned_fraction,
                                  ('beta1',) if span_a < 0.5 * cfg.i_ref_a else ())
        if reason:
            return reason
        if not (robust_nrmse <= cfg.max_nrmse_percent):
            return 'nrmse_above_threshold'
        figures = None if self._ref is None else self._ref.rmse_on(fit, f_new, cfg.i_ref_a,
                                                                   cfg.current_bin_a)
        if figures is not None:
            self.last_check['new_vs_last_valid_rmse_n'] = figures
            e_new, e_prev = figures
            if e_new > cfg.max_error_ratio * e_prev + 0.01 * cfg.error_floor_percent * scale:
                return 'worse_than_last_valid'
        return ''

    def _set_reference(self, est, fit, f_new, scale):
        """Keep a valid set as the consistency reference (``ConsistencyReference.from_fit``)."""
        self._ref = ConsistencyReference.from_fit(est, fit, f_new, scale,
                                                  self.config.current_bin_a)

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
        figures = None if self._ref is None else self._ref.figures(new, self.config)
        if figures is None:
            return ''
        self.last_check['new_samples_rmse_n'] = figures
        return 'inconsistent' if figures[0] > figures[1] else ''

    def _warm_start(self, model, levels):
        return warm_start(self._last_solution, model, levels, self.config.i_ref_a)

    def _exclude(self, t):
        """Note the stamps of samples kept out of the bins (flagged or inconsistent)."""
        if len(t):
            self._excluded_s = max(self._excluded_s, float(np.max(t)))

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
        the samples of superseded windows, see
        :func:`~mr_damper_model.live.window.catch_up_parts`), ``fit_errors``,
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
        (:class:`~mr_damper_model.identification.acceptance.Acceptance`).
        """
        with self._lock:
            c = {k: (dict(v) if isinstance(v, dict) else v) for k, v in self.counters.items()}
            c['samples_pending'] = self._ring.seq - self._ring.handed
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
            bins_a=self._bins.levels(),
            last_error=self.last_error, last_held=self.last_held,
            held_age_s=self._accept.age_s(self.processed_up_to_s),
            last_condition_number=self._accept.last_figures.get('condition', math.nan),
            offset=dict(self._accept.offset), f0_trend=self._accept.f0_trend())
        for name in ('window', 'heldback'):
            if name in self._accept.last_figures:
                c['last_check'][f'new_vs_current_{name}_rmse_n'] = list(
                    self._accept.last_figures[name])
        return c
