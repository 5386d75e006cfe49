"""
Robust signal filters shared by the acceptance of live sets and the live sensor-fault screen.

No ROS; numpy only. ``mr_damper_model.live`` re-exports :func:`running_median`.
"""
import numpy as np

#: Width of the running median of the outlier screen [samples] (isolates bursts of <= 2).
MEDIAN_WIDTH = 5


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
