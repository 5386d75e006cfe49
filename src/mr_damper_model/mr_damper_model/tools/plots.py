"""
Plots of identification results (matplotlib, Agg backend; no display needed).

:func:`fit_figure` draws the thesis Figure 4.16 layout, one row per current level: (a) force vs
time, (b) force vs displacement, (c) force vs velocity, measured and model, and (d) force error
vs time. :func:`compare_figure` overlays several models on the same record (thesis Figure 4.14).
Computation stays outside: the functions take arrays and results, :func:`model_force` evaluates
an :class:`~mr_damper_model.identification.identify.IdentificationResult` on a record.
"""
import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from mr_damper_model.io.figures import save_figure  # noqa: E402,F401
from mr_damper_model.models import get_model  # noqa: E402

__all__ = ['model_force', 'fit_figure', 'compare_figure', 'save_figure']


def model_force(result, data):
    """
    Evaluate the force [N] of an identified model on a record.

    Parameters
    ----------
    result : IdentificationResult
        Model name, options and parameters (``x``) of the fit.
    data : DamperData
        Record whose displacement, velocity, current and time are used.

    Returns
    -------
    ndarray with shape (n,)

    """
    mdl = get_model(result.model, **(result.model_options or {}))
    return np.asarray(mdl.force(np.asarray(result.x, dtype=float), data.x, data.v, i=data.i,
                                t=data.t, starts=data.starts), dtype=float)


def fit_figure(groups, *, title=''):
    """
    Thesis Figure 4.16 layout, one row per group.

    Parameters
    ----------
    groups : sequence of (label, t, x, v, f_measured, f_model)
        Arrays with shape (n,) in s, m, m/s, N, N; ``label`` e.g. ``'0.50 A'``.
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure

    """
    groups = list(groups)
    rows = len(groups)
    fig, axes = plt.subplots(rows, 4, figsize=(16, 3.2 * rows), squeeze=False)
    for r, (label, t, x, v, f, fm) in enumerate(groups):
        a, b, c, d = axes[r]
        t0 = t - t[0]
        a.plot(t0, f, 'k-', lw=0.8, label='measured')
        a.plot(t0, fm, 'r--', lw=0.9, label='model')
        a.set_xlabel('time [s]')
        a.set_ylabel('force [N]')
        a.set_title(f'(a) {label} force vs time')
        a.legend(loc='best', fontsize=8)
        b.plot(x * 1e3, f, 'k-', lw=0.6)
        b.plot(x * 1e3, fm, 'r--', lw=0.8)
        b.set_xlabel('displacement [mm]')
        b.set_ylabel('force [N]')
        b.set_title('(b) force vs displacement')
        c.plot(v, f, 'k-', lw=0.6)
        c.plot(v, fm, 'r--', lw=0.8)
        c.set_xlabel('velocity [m/s]')
        c.set_ylabel('force [N]')
        c.set_title('(c) force vs velocity')
        d.plot(t0, f - fm, 'b-', lw=0.7)
        d.set_xlabel('time [s]')
        d.set_ylabel('force error [N]')
        d.set_title('(d) error (measured - model)')
        for ax in (a, b, c, d):
            ax.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig


def compare_figure(t, f_measured, model_forces, *, title=''):
    """
    Several models against the measured force (thesis Figure 4.14 style).

    Parameters
    ----------
    t : ndarray with shape (n,)
        Time [s].
    f_measured : ndarray with shape (n,)
        Measured force [N].
    model_forces : dict
        Model label -> force [N] with shape (n,).
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure

    """
    fig, (a, b) = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    t0 = t - t[0]
    a.plot(t0, f_measured, 'k-', lw=1.0, label='measured')
    for label, fm in model_forces.items():
        a.plot(t0, fm, lw=0.9, label=label)
        b.plot(t0, f_measured - fm, lw=0.7, label=label)
    a.set_ylabel('force [N]')
    a.legend(loc='best', fontsize=8)
    b.set_xlabel('time [s]')
    b.set_ylabel('force error [N]')
    for ax in (a, b):
        ax.grid(True, alpha=0.3)
    if title:
        a.set_title(title)
    fig.tight_layout()
    return fig
