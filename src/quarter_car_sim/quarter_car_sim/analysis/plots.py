"""
Plots of quarter-car results (matplotlib, Agg backend; compute elsewhere, plot here).

All functions take precomputed results and write a PNG when ``path`` is given; they return the
matplotlib Figure.
"""
import numpy as np


def _plt():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def plot_transmissibility(trans, f_hz, ax=None, *, quantity='a_s'):
    """
    Bode-style magnitude of road displacement -> ``quantity`` for linear damper settings.

    Parameters
    ----------
    trans : dict
        Output of :func:`semi_active_control.car.quarter_car_linear.transmissibility`.
    f_hz : array_like
        Frequencies [Hz] used for ``trans``.
    ax : matplotlib Axes, optional
        Axes to draw on (a new figure when None).
    quantity : str
        'a_s' [1/s^2], 'travel' or 'tyre_deflection' [-].

    """
    plt = _plt()
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    for c, d in trans.items():
        ax.loglog(f_hz, d[quantity], label=f'c = {c:g} N s/m')
    ax.set_xlabel('frequency [Hz]')
    unit = '[1/s$^2$]' if quantity == 'a_s' else '[-]'
    ax.set_ylabel(f'|{quantity} / z_r| {unit}')
    ax.set_title('road -> ' + quantity + ' (linear model)')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=7)
    return ax.figure


def plot_results(results, path=None, *, params=None, c_values=(300.0, 1000.0, 3000.0),
                 window_s=3.0, names=None):
    """
    Four panels: body acceleration traces, body-acceleration PSD, transmissibility, current.

    Parameters
    ----------
    results : dict
        name -> SimResult.
    path : str or Path, optional
        PNG output.
    params : QuarterCarParams, optional
        For the transmissibility panel (default parameters if None).
    c_values : sequence of float
        Linear damping values for the transmissibility panel [N s/m].
    window_s : float
        Length of the time-trace window [s] (the last ``window_s`` seconds).
    names : sequence of str, optional
        Results to draw (default: all; with more than five, the softest passive setting,
        skyhook, skyhook-ideal and lqr-active when present).

    Returns
    -------
    matplotlib Figure

    """
    from scipy import signal

    from semi_active_control.car.quarter_car_linear import transmissibility
    from semi_active_control.car.quarter_car import QuarterCarParams
    plt = _plt()
    fig, axs = plt.subplots(2, 2, figsize=(12, 8))
    if names is None:
        names = list(results)
        if len(names) > 5:
            passive = [n for n in names if n.startswith('passive@')]
            keep = passive[:1] + ['skyhook', 'skyhook-ideal', 'lqr-active']
            names = [n for n in names if n in keep] or names
    for name in names:
        r = results[name]
        m = r.t >= r.t[-1] - window_s
        axs[0, 0].plot(r.t[m], r.a_s[m], lw=0.7, label=name)
        fs = 1.0 / (r.t[1] - r.t[0])
        f, p = signal.welch(r.a_s, fs=fs, nperseg=min(r.t.size, 4096))
        axs[0, 1].loglog(f[1:], p[1:], lw=0.8, label=name)
        if np.any(np.isfinite(r.current_cmd)):
            axs[1, 1].plot(r.t[m], r.current_cmd[m], lw=0.7, label=name)
    axs[0, 0].set(xlabel='t [s]', ylabel='body acceleration [m/s$^2$]', title='time traces')
    axs[0, 1].set(xlabel='frequency [Hz]', ylabel='PSD [(m/s$^2$)$^2$/Hz]',
                  title='body acceleration PSD', xlim=(0.3, 100))
    lo, hi = axs[0, 1].get_ylim()
    axs[0, 1].set_ylim(max(lo, hi * 1e-7), hi)
    axs[1, 1].set(xlabel='t [s]', ylabel='current command [A]', title='coil current command')
    f = np.logspace(-1, 2, 300)
    plot_transmissibility(transmissibility(params or QuarterCarParams(), c_values, f), f,
                          ax=axs[1, 0])
    for ax in axs.flat:
        ax.grid(True, alpha=0.3)
    axs[0, 0].legend(fontsize=7)
    axs[0, 1].legend(fontsize=7)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig


def plot_tradeoff(curves, path=None, *, points=None):
    """
    Comfort vs road holding: Wk RMS body acceleration against RMS dynamic tyre load ratio.

    Parameters
    ----------
    curves : dict
        label -> list of (rms_tyre_load_ratio, rms_body_accel_wk, point_label).
    path : str or Path, optional
        PNG output.
    points : dict, optional
        label -> (rms_tyre_load_ratio, rms_body_accel_wk) single controllers.

    Returns
    -------
    matplotlib Figure

    """
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 5))
    for label, pts in curves.items():
        x = [p[0] for p in pts]
        y = [p[1] for p in pts]
        ax.plot(x, y, 'o-', label=label)
        for p in pts:
            ax.annotate(str(p[2]), (p[0], p[1]), fontsize=7, xytext=(3, 3),
                        textcoords='offset points')
    for label, (x, y) in (points or {}).items():
        ax.plot([x], [y], 's', label=label)
    ax.set_xlabel('RMS dynamic tyre load / static load [-]  (road holding: lower is better)')
    ax.set_ylabel('Wk-weighted RMS body acceleration [m/s$^2$]  (comfort)')
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig
