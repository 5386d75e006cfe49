"""
Live (sliding-window) identification of the current-dependent Kwok model; no ROS.

The identifier node feeds samples in as they arrive and asks for windows; this package does all
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
   ``stuck`` load cell (``dropout`` when the constant is zero), and so is a constant run of half
   ``stuck_s`` or longer that began among samples already kept out (the same fault going on,
   :func:`continued_runs`).  Flagged samples leave the fit
   and the bins and are counted by reason (``samples_flagged``).  Then the last valid model of
   this stream (if any) must explain the new samples of the current levels it covers about as
   well as it explained the data it was fitted on (:meth:`LiveIdentifier._consistency`):
   otherwise the data changed abruptly (force offset step, current sensor stuck, load cell sign
   flip, a dropout) and the window is skipped (``inconsistent``) without binning them.  When
   the part before was consistent as a whole and the new part, judged in blocks of 40 samples,
   is consistent up to one point and inconsistent after it (the onset of a fault inside the
   part), the blocks before the onset are binned and the window is fitted.
5. **Current bins**: the screened new samples are filed by coil current into bins of width
   ``current_bin_a``; each bin keeps its newest samples (as many as one window holds) and bins
   older than ``bin_max_age_s`` are dropped.  The Kwok model is algebraic (no internal state),
   so the union of the bins is a valid data set even though it joins different moments.
   When samples of the window were kept out (flagged or inconsistent), the levels the window
   holds are fitted on the window's own remaining samples, not on older ones filling the gap
   (a start from rest), unless fewer than ``min_bin_fraction`` of a window are left at that
   level (then its whole bin is used).
6. **Fit** (:func:`fit_data`, the same :func:`~mr_damper_model.identification.identify.identify`
   call as the
   offline tool): separable PSO warm-started from the last solution, within ``budget_s``.  One
   usable bin: plain Kwok (mapped to kwok-current with zero current slopes, the covered range
   being that single current); two or more bins: kwok-current on their union.
7. **Validity**: finite parameters within the model bounds; no parameter pinned at a bound
   (:mod:`mr_damper_model.models.validity`, the same rule as the car's supervisor); the fit
   RMSE divided by the robust force range of the fit data (0.5-99.5 percentile range, which
   single outliers cannot move) at most
   ``max_nrmse_percent``; and, on the fitted samples of the current levels covered by the last
   valid set of this stream, an RMSE at most ``max_error_ratio`` times that set's plus
   ``error_floor_percent`` of the robust force range (``worse_than_last_valid``).
8. **Acceptance** (``acceptance_checks``, :mod:`~mr_damper_model.identification.acceptance`): a
   valid set replaces the set in use only if its window excites what it claims (velocity amplitude,
   velocity bins, condition number) and it predicts at least as well on the newest window and
   on held-back recent data; otherwise the set in use is re-published (valid, ``held``) and the
   reason counted in ``windows_refused``.  Admitted samples with a force offset against the set
   in use are flagged ``offset``; the f0 trend of the sets taken is reported.

Threading: ``add_sample`` and ``next_window`` may be called from one thread and ``process``
(the fit) from another; the sample buffer is protected by a lock, the bins and the warm start
belong to the fitting thread.

Modules: ``config`` (:class:`LiveConfig`, counter names), ``window`` (:class:`Window`,
:class:`LiveEstimate`), ``screening`` (steps 3-4 and pinned parameters), ``conversions`` (plain
Kwok to kwok-current), ``fitting`` (step 6: the fit options, seeds and :class:`FitProcess`, the
child process a fit runs in), ``identifier`` (:class:`LiveIdentifier`: the state machine of
steps 1-8), ``worker`` (:class:`IdentifierRuntime`: what the node runs around it: health,
throttled saves, stamp ages). :class:`BatchIndex` (lost samples of a batched stream) moved to
:mod:`mr_damper_common.recording` (issue 33); ``sample_stream`` and ``BatchIndex`` still load
from here for one release, with a ``DeprecationWarning``.

Public API::

    from mr_damper_model.live import LiveConfig, LiveIdentifier, LiveEstimate, FitProcess
    from mr_damper_model.live import IdentifierRuntime
"""
from mr_damper_model.live.config import (DYNAMIC_FIELDS, FLAG_REASONS, LiveConfig,  # noqa: F401
                                         RANGE_CHANNELS, REJECT_REASONS, SKIP_REASONS)
from mr_damper_model.live.conversions import kwok_current_at, kwok_to_kwok_current  # noqa: F401
from mr_damper_model.live.fitting import (fit_data, fit_kwargs, FitProcess,  # noqa: F401
                                          window_seed)
from mr_damper_model.live.identifier import LiveIdentifier  # noqa: F401
from mr_damper_model.live.screening import (check_excitation, constant_runs,  # noqa: F401
                                            continued_runs, flag_samples, robust_range,
                                            running_median)
from mr_damper_model.live.window import LiveEstimate, Window  # noqa: F401

_LAZY = {'IdentifierRuntime': 'worker', 'BatchIndex': 'sample_stream'}


def __getattr__(name):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f'{__name__}.{_LAZY[name]}'), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
