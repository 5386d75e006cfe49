"""
Fit-quality metrics between measured and model force (seed thesis eq. 4.1-4.3).

Keys of the dictionary returned by :func:`fit_metrics`:

``mean_abs_error_n``
    mean |F_exp - F_sim| [N] (thesis eq. 4.1, read as the mean absolute error).
``rmse_n``
    sqrt(mean (F_exp - F_sim)^2) [N] (thesis eq. 4.3).
``mean_percent_error``, ``max_percent_error``
    mean / max of 100 |F_exp - F_sim| / |F_exp| [%] (thesis eq. 4.2) over the samples with
    |F_exp| >= 10 % of max |F_exp|. Eq. 4.2 divides by the measured force, so near the force
    zero-crossings (twice per cycle) it grows without bound whatever the model; the 10 % floor
    keeps the figure about the loop, not about the division.
``nrmse_percent``
    100 rmse_n / (max F_exp - min F_exp) [%].
"""
import numpy as np

METRIC_KEYS = ('mean_abs_error_n', 'rmse_n', 'mean_percent_error', 'max_percent_error',
               'nrmse_percent')
PERCENT_FLOOR = 0.10


def fit_metrics(f_exp, f_sim):
    """
    Compare measured and model force.

    Parameters
    ----------
    f_exp : array_like with shape (n,)
        Measured force [N].
    f_sim : array_like with shape (n,)
        Model force [N].

    Returns
    -------
    dict
        The keys listed in the module docstring, as floats.

    Raises
    ------
    ValueError
        Empty or mismatched inputs, or non-finite values.

    """
    f_exp = np.asarray(f_exp, dtype=float).ravel()
    f_sim = np.asarray(f_sim, dtype=float).ravel()
    if f_exp.size == 0:
        raise ValueError('`f_exp` is empty.')
    if f_exp.shape != f_sim.shape:
        raise ValueError(f'`f_exp` and `f_sim` differ in length ({f_exp.size} vs {f_sim.size}).')
    if not (np.all(np.isfinite(f_exp)) and np.all(np.isfinite(f_sim))):
        raise ValueError('`f_exp` or `f_sim` has NaN/inf values.')
    # two sample-length temporaries (error, |F_exp|), worked in place: a fit of a
    # 3-million-sample record stays within its memory budget (bench/bench_csv_memory.py)
    err = f_exp - f_sim
    rmse = float(np.sqrt((err @ err) / err.size))
    np.abs(err, out=err)
    mean_abs = float(err.mean())
    mag = np.abs(f_exp)
    peak = float(mag.max())
    if peak > 0:
        keep = mag >= PERCENT_FLOOR * peak
        np.divide(err, mag, out=err, where=keep)
        mean_pct = 100.0 * float(np.sum(err, where=keep)) / int(np.count_nonzero(keep))
        max_pct = 100.0 * float(np.max(err, where=keep, initial=0.0))
    else:
        mean_pct = max_pct = float('nan')
    span = float(f_exp.max() - f_exp.min())
    return {
        'mean_abs_error_n': mean_abs,
        'rmse_n': rmse,
        'mean_percent_error': mean_pct,
        'max_percent_error': max_pct,
        'nrmse_percent': 100.0 * rmse / span if span > 0 else float('nan'),
    }
