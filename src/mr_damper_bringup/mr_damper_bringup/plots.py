"""
Plots of one suite run (matplotlib, Agg backend); called by :mod:`mr_damper_bringup.report`.

- ``hysteresis.png``: measured force against velocity and against displacement for the last
  cycles at each current level, with the final identified model on the same samples;
- ``convergence.png``: identified parameters (relative to the truth when the truth is
  kwok-current, else to their final value) and the fit error over wall time;
- ``ride.png``: body acceleration of the live controller and the passive reference on the same
  road, the coil current command, fail-safe periods shaded.
"""
from pathlib import Path

import numpy as np

from mr_damper_common.contract import KWOK_CURRENT_NAMES
from mr_damper_model.models.kwok_current import kwok_current_force


def _plt():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def _save(plt, fig, axes, path):
    """Grid every axis, write ``fig`` to ``path`` (110 dpi) and close it; return ``path``."""
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_hysteresis(path, meas, params, *, per_level_s=2.0, max_levels=6):
    """Measured vs identified force loops per current level; return the path or None."""
    t = np.asarray(meas.get('t', []), dtype=float)
    if t.size < 10:
        return None
    x, v, f, i = (np.asarray(meas[k], dtype=float) for k in 'xvfi')
    rounded = np.round(i / 0.05) * 0.05
    levels, counts = np.unique(rounded, return_counts=True)
    levels = levels[counts >= 0.4 * per_level_s * max(1.0, t.size / max(np.ptp(t), 1e-9))]
    if levels.size > max_levels:
        levels = levels[np.linspace(0, levels.size - 1, max_levels).round().astype(int)]
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    colors = plt.cm.viridis(np.linspace(0, 0.9, max(1, levels.size)))
    for lev, col in zip(levels, colors):
        idx = np.flatnonzero(np.abs(i - lev) < 0.025)
        if idx.size < 10:
            continue
        idx = idx[t[idx] >= t[idx[-1]] - per_level_s]
        axes[0].plot(v[idx], f[idx], '.', ms=1.5, color=col, label=f'{lev:.2f} A measured')
        axes[1].plot(x[idx] * 1e3, f[idx], '.', ms=1.5, color=col)
        if params:
            fm = kwok_current_force(params, x[idx], v[idx], i[idx])
            order = np.argsort(t[idx])
            axes[0].plot(v[idx][order], fm[order], '-', lw=1.0, color='k', alpha=0.7)
            axes[1].plot(x[idx][order] * 1e3, fm[order], '-', lw=1.0, color='k', alpha=0.7)
    axes[0].set_xlabel('piston velocity [m/s]')
    axes[0].set_ylabel('force [N]')
    axes[1].set_xlabel('displacement [mm]')
    axes[0].set_title('measured (dots) vs identified kwok-current (black)')
    axes[1].set_title('force - displacement')
    if axes[0].get_legend_handles_labels()[1]:
        axes[0].legend(fontsize=7, markerscale=5)
    return _save(plt, fig, axes, path)


def plot_convergence(path, params_log, truth=None, history=None):
    """Parameter and error histories over wall time; return the path or None."""
    if not params_log:
        return None
    plt = _plt()
    t = np.array([p[0] for p in params_log])
    valid = np.array([p[1].get('valid') == 1.0 for p in params_log])
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    for n in KWOK_CURRENT_NAMES:
        vals = np.array([p[1].get(n, np.nan) for p in params_log], dtype=float)
        if truth and truth.get(n):
            ref = abs(truth[n])
        else:
            ref = np.nanmax(np.abs(vals)) if np.any(np.isfinite(vals)) else np.nan
        if not (np.isfinite(ref) and ref > 0):
            continue
        axes[0].plot(t, vals / ref, '-', lw=1.0, label=n)
    if truth:
        axes[0].axhline(1.0, color='k', lw=0.8)
        axes[0].set_ylabel('parameter / |truth|')
    else:
        axes[0].set_ylabel('parameter / its largest |value|')
    axes[0].set_ylim(-1.2, 1.2 if not truth else 3.0)
    axes[0].legend(ncol=5, fontsize=7)
    nrmse = np.array([p[1].get('nrmse_percent', np.nan) for p in params_log], dtype=float)
    axes[1].plot(t, nrmse, '.-', lw=0.8, ms=3, label='identifier window NRMSE')
    axes[1].plot(t[~valid], nrmse[~valid], 'rx', ms=4, label='not valid')
    hist = [h for h in (history or []) if h.get('record_nrmse_percent') is not None]
    if hist:
        axes[1].plot([h['t_s'] for h in hist], [h['record_nrmse_percent'] for h in hist], 's-',
                     ms=3, lw=1.0, label='NRMSE on the whole record (all currents)')
        axes[1].set_yscale('log')
    axes[1].set_ylabel('NRMSE [%]')
    axes[1].set_xlabel('wall time since start [s]')
    axes[1].legend(fontsize=8)
    return _save(plt, fig, axes, path)


def plot_ride(path, log, passive_trace=None, controller='skyhook'):
    """Body acceleration and current command over simulated time; return the path or None."""
    if log is None or len(log['t']) < 10:
        return None
    plt = _plt()
    t = np.asarray(log['t'])
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    if passive_trace is not None:
        axes[0].plot(passive_trace['t'], passive_trace['a_s'], lw=0.6, color='0.6',
                     label='passive (safe current), same road')
    axes[0].plot(t, log['a_s'], lw=0.6, color='C0', label=f'live {controller}')
    axes[0].set_ylabel('body acceleration [m/s^2]')
    axes[0].legend(fontsize=8)
    axes[1].plot(t, log['i_cmd'], lw=0.6, color='C1', label='current command')
    axes[1].plot(t, log['coil_current'], lw=0.6, color='C2', label='coil current')
    axes[1].set_ylabel('current [A]')
    axes[1].set_xlabel('simulated time [s]')
    fs = np.asarray(log['mode']) < 0.5
    if fs.any():
        for ax in axes:
            ax.fill_between(t, 0, 1, where=fs, transform=ax.get_xaxis_transform(),
                            color='red', alpha=0.08, lw=0, label='fail-safe')
    axes[1].legend(fontsize=8)
    return _save(plt, fig, axes, path)


def plot_all(out, meas, params_log, summary, log, passive_trace):
    """Write every plot of a run into ``out``; return the written paths."""
    out = Path(out)
    ident = summary.get('identification') or {}
    paths = [plot_hysteresis(out / 'hysteresis.png', meas, ident.get('parameters')),
             plot_convergence(out / 'convergence.png', params_log, ident.get('truth'),
                              ident.get('history')),
             plot_ride(out / 'ride.png', log, passive_trace,
                       (summary.get('ride') or {}).get('controller', 'skyhook'))]
    return [p for p in paths if p is not None]


def plot_body_modes(path, t, acc, t_passive, acc_passive, controller, t_normal=0.0):
    """
    Full car: body heave, pitch and roll accelerations, live against passive; return the path.

    ``acc`` and ``acc_passive`` have columns heave [m/s^2], pitch and roll [rad/s^2]; the time
    before every corner was first on its model (``t < t_normal``) is shaded.
    """
    plt = _plt()
    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True)
    units = ('heave [m/s^2]', 'pitch [rad/s^2]', 'roll [rad/s^2]')
    for k, ax in enumerate(axes):
        ax.plot(t_passive, acc_passive[:, k], lw=0.6, color='0.6',
                label='passive (safe current), same road')
        ax.plot(t, acc[:, k], lw=0.6, color='C0', label=f'live {controller}')
        ax.set_ylabel(units[k])
        if t_normal > 0:
            ax.axvspan(0.0, t_normal, color='red', alpha=0.08, lw=0,
                       label='a corner in fail-safe')
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel('simulated time [s]')
    return _save(plt, fig, axes, path)
