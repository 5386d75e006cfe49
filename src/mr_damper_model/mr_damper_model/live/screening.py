"""
Screening before and after a fit (no ROS).

A window's excitation, the running median and the stuck runs of the sensor-fault screen, and
force steps inside a set's own fit data (:func:`force_step`: a sensor offset that begins or ends
inside the window, seen without an earlier set).
"""
import math

import numpy as np

from mr_damper_model.identification.acceptance import reversal_indices, velocity_amplitude
from mr_damper_model.identification.signals import MEDIAN_WIDTH, running_median  # noqa: F401


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


def continued_runs(f, t, min_s, since_s):
    """
    Mask of the samples in constant runs of ``min_s`` or longer that began by ``since_s``.

    A run that began among samples already kept out of the fit (a stuck load cell or a dropout
    judged inconsistent before it lasted ``stuck_s``) and goes on into new samples is the same
    fault: its new samples are flagged even when the run falls just short of ``stuck_s``.

    Parameters
    ----------
    f, t : array_like with shape (n,)
        Signal and its stamps [s], increasing.
    min_s : float
        Shortest run [s] (first to last stamp).
    since_s : float
        Latest start of a run [s].

    Returns
    -------
    numpy.ndarray of bool with shape (n,)

    """
    f = np.asarray(f, dtype=float)
    t = np.asarray(t, dtype=float)
    mask = constant_runs(f, t, min_s)
    if mask.any():
        starts = np.flatnonzero(np.r_[True, f[1:] != f[:-1]])
        first = starts[np.searchsorted(starts, np.arange(f.size), side='right') - 1]
        mask &= t[first] <= since_s
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


#: Force steps inside a window (:func:`force_step`): whole cycles are comparable when their
#: velocity amplitude and stroke are within this fraction of the run's median cycle ...
CYCLE_TOLERANCE = 0.05
#: ... and their displacement centres within this fraction of that stroke.
CENTRE_TOLERANCE = 0.02
#: Mid-stroke: samples where ``|v|`` is at least this fraction of the velocity amplitude.
MID_STROKE = 0.5
#: Jumps are judged in runs holding at least this many samples per cycle (per stroke pair).
MIN_CYCLE_SAMPLES = 100
#: A jump persists when the residual's medians over this span [s] on either side differ by as
#: much, in the same direction.
STEP_SPAN_S = 0.05


def level_runs(data, bin_a, max_gap_s):
    """
    Return the index arrays of the time-contiguous runs of each current level of ``data``.

    A fit's data joins bins of several levels from different moments; a force step is judged
    within one run (same level, no stamp step above ``max_gap_s``), in time order.
    """
    keys = np.round(np.asarray(data.i, dtype=float) / bin_a).astype(np.int64)
    out = []
    for key in np.unique(keys):
        idx = np.flatnonzero(keys == key)
        idx = idx[np.argsort(data.t[idx], kind='stable')]
        cut = np.flatnonzero(np.diff(data.t[idx]) > max_gap_s) + 1
        out.extend(np.split(idx, cut))
    return out


def cycle_mean_spread(x, v, f):
    """
    Spread [N] of the mean forces of the comparable whole cycles of one run (nan: < 2 of them).

    A whole cycle runs from one velocity reversal to the second next (both stroke ends).  Over
    whole cycles of the same motion a damper's mean force is the same (``f0`` plus ``k`` times
    the displacement centre; the velocity terms average out): a force offset that begins or
    ends among them moves the mean of the cycles it covers, and needs no set to be seen.
    Cycles of another amplitude, stroke or centre (a start from rest, a change of excitation)
    are not compared: there the damper's asymmetry moves the mean too.
    """
    rev = reversal_indices(v)
    if rev.size < 4:
        return math.nan
    a, b = rev[:-2], rev[2:]
    cf = np.concatenate(([0.0], np.cumsum(f)))
    cx = np.concatenate(([0.0], np.cumsum(x)))
    mean_f = (cf[b] - cf[a]) / (b - a)
    centre = (cx[b] - cx[a]) / (b - a)
    peak = np.maximum.reduceat(np.abs(v), rev)[:-1]        # per half cycle (between reversals)
    top = np.maximum.reduceat(x, rev)[:-1]
    bottom = np.minimum.reduceat(x, rev)[:-1]
    amp = np.maximum(peak[:-1], peak[1:])
    stroke = np.maximum(top[:-1], top[1:]) - np.minimum(bottom[:-1], bottom[1:])
    ma, ms, mc = np.median(amp), np.median(stroke), np.median(centre)
    same = ((np.abs(amp - ma) <= CYCLE_TOLERANCE * ma)
            & (np.abs(stroke - ms) <= CYCLE_TOLERANCE * ms)
            & (np.abs(centre - mc) <= CENTRE_TOLERANCE * ms))
    if np.count_nonzero(same) < 2:
        return math.nan
    return float(np.ptp(mean_f[same]))


def mid_stroke_jump(t, v, resid):
    """
    Largest persistent one-sample jump [N] of a set's residual in mid-stroke (0: none judged).

    A load cell's offset step moves the force from one sample to the next while the motion
    goes on smoothly: the residual of a set fitted on the samples jumps, and stays (its medians
    over :data:`STEP_SPAN_S` before and after differ by as much, same sign).  Judged where the
    damper's own force changes slowly, in mid-stroke (``|v|`` at least :data:`MID_STROKE` of the
    velocity amplitude, on both samples; the force rises fast after a reversal) and in runs
    sampled finely for their motion (:data:`MIN_CYCLE_SAMPLES` per cycle or more).
    """
    n = resid.size
    dt = float(np.median(np.diff(t))) if n > 1 else 0.0
    if not dt > 0:
        return 0.0
    span = max(2, int(round(STEP_SPAN_S / dt)))
    if n < 2 * span + 2:
        return 0.0
    rev = reversal_indices(v)
    if rev.size >= 3 and 2.0 * float(np.median(np.diff(rev))) < MIN_CYCLE_SAMPLES:
        return 0.0
    amp = velocity_amplitude(v)
    k = np.arange(span, n - span + 1)
    fast = np.abs(v) >= MID_STROKE * amp
    k = k[fast[k] & fast[k - 1]]
    if not k.size:
        return 0.0
    medians = np.median(np.lib.stride_tricks.sliding_window_view(resid, span), axis=1)
    lasting = medians[k] - medians[k - span]              # after minus before sample k
    jump = resid[k] - resid[k - 1]
    size = np.where(np.sign(lasting) == np.sign(jump),
                    np.minimum(np.abs(lasting), np.abs(jump)), 0.0)
    return float(size.max())


def force_step(data, resid, config):
    """
    Return why a set's own fit data holds a force step, or '' (needs no earlier set).

    Per level run (:func:`level_runs`): the spread of the mean forces of comparable whole
    cycles (:func:`cycle_mean_spread`) and the largest persistent mid-stroke jump of the set's
    residual (:func:`mid_stroke_jump`), each against ``force_step_percent`` of the run's robust
    force range.  Fast cycles are judged by the first, slow strokes by the second.

    Parameters
    ----------
    data : DamperData
        The samples the set was fitted on.
    resid : numpy.ndarray
        Their force less the set's force [N].
    config : LiveConfig
        ``force_step_percent`` (0: no check), ``current_bin_a``, ``max_gap_s``.

    Returns
    -------
    str
        '' or ``'force_step:<A>'`` (``<A>`` the level's current [A]).

    """
    if not config.force_step_percent > 0:
        return ''
    for idx in level_runs(data, config.current_bin_a, config.max_gap_s):
        if idx.size < 10:
            continue
        limit = 0.01 * config.force_step_percent * robust_range(data.f[idx])
        spread = cycle_mean_spread(data.x[idx], data.v[idx], data.f[idx])
        if spread > limit or mid_stroke_jump(data.t[idx], data.v[idx], resid[idx]) > limit:
            return f'force_step:{float(np.median(data.i[idx])):.3g}'
    return ''
