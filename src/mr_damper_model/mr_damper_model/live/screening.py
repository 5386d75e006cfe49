"""
Screening before and after a fit (no ROS).

A window's excitation, the running median and the stuck runs of the sensor-fault screen, and
parameters pinned at a bound.
"""
import numpy as np

#: Width of the running median of the outlier screen [samples] (isolates bursts of <= 2).
MEDIAN_WIDTH = 5


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
