"""Drift of the records of one serial number over time (ageing, fluid loss)."""
import csv
import datetime
import math
import os
from pathlib import Path
import tempfile

from mr_damper_model.identification.batch.damper import _fmt
from mr_damper_model.io.figures import save_figure
from mr_damper_model.models import get_model


def _num(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def trend(rows):
    """
    Drift of each parameter and envelope force over the records of each serial number.

    For every serial with at least two dated records (status ``pass``, ``fail`` or
    ``fitted``), a least-squares line of each quantity (``p_*`` and ``env_*`` columns) against
    the test time.

    Parameters
    ----------
    rows : list of dict
        Table rows (:func:`read_table`).

    Returns
    -------
    list of dict
        Sorted by serial, then quantity: ``serial``, ``quantity``, ``records``,
        ``first_time``, ``last_time``, ``span_days``, ``first_value``, ``last_value``,
        ``slope_per_day`` (of the line), ``change`` (slope x span) and ``change_percent``
        (of the line's value at the first time; NaN if that is 0).

    """
    import numpy as np
    by = {}
    for r in rows:
        if r.get('status') in ('pass', 'fail', 'fitted') and r.get('test_time'):
            by.setdefault(r['serial'], []).append(r)
    out = []
    for serial in sorted(by):
        recs = sorted(by[serial], key=lambda r: r['test_time'])
        if len(recs) < 2:
            continue
        times = [datetime.datetime.fromisoformat(r['test_time']) for r in recs]
        days = np.array([(t - times[0]).total_seconds() / 86400.0 for t in times])
        if days[-1] <= 0:
            continue
        qs = [k for k in recs[0] if k.startswith(('p_', 'env_'))]
        for q in qs:
            y = np.array([_num(r.get(q)) for r in recs])
            ok = np.isfinite(y)
            if ok.sum() < 2 or np.ptp(days[ok]) <= 0:
                continue
            slope, icpt = np.polyfit(days[ok], y[ok], 1)
            span = float(days[-1])
            base = icpt
            out.append({'serial': serial, 'quantity': q, 'records': int(ok.sum()),
                        'first_time': recs[0]['test_time'], 'last_time': recs[-1]['test_time'],
                        'span_days': span, 'first_value': float(y[ok][0]),
                        'last_value': float(y[ok][-1]), 'slope_per_day': float(slope),
                        'change': float(slope * span),
                        'change_percent': float(100.0 * slope * span / abs(base))
                        if base != 0 else math.nan})
    return out


def write_trend(rows, csv_path, png_path=None, *, max_serials=6):
    """
    Write :func:`trend` as a CSV table and optionally its plot; return the trend rows.

    The plot shows the serials whose envelope forces changed most (at most ``max_serials``).
    """
    tr = trend(rows)
    cols = ['serial', 'quantity', 'records', 'first_time', 'last_time', 'span_days',
            'first_value', 'last_value', 'slope_per_day', 'change', 'change_percent']
    fd, tmp = tempfile.mkstemp(dir=Path(csv_path).parent, prefix=Path(csv_path).name,
                               suffix='.tmp')
    with os.fdopen(fd, 'w', newline='') as fh:
        w = csv.DictWriter(fh, fieldnames=cols, lineterminator='\n')
        w.writeheader()
        w.writerows([{k: _fmt(v) if isinstance(v, float) else v for k, v in r.items()}
                     for r in tr])
    os.replace(tmp, csv_path)
    if png_path is not None and tr:
        worst = {}
        for r in tr:
            if r['quantity'].startswith('env_') and math.isfinite(r['change_percent']):
                worst[r['serial']] = max(worst.get(r['serial'], 0.0), abs(r['change_percent']))
        serials = sorted(worst, key=lambda s: (-worst[s], s))[:max_serials] or \
            sorted({r['serial'] for r in tr})[:max_serials]
        save_figure(trend_figure(rows, serials), png_path)
    return tr


def trend_figure(rows, serials):
    """
    Plot each parameter and the envelope forces of some serials against test time.

    One panel per parameter and one per envelope current (every velocity and side in it);
    one colour per serial. Returns the matplotlib figure.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    recs = {s: sorted((r for r in rows if r.get('serial') == s and r.get('test_time')
                       and r.get('status') in ('pass', 'fail', 'fitted')),
                      key=lambda r: r['test_time']) for s in serials}
    keys = []
    for s in serials:
        for k in (recs[s][0] if recs[s] else {}):
            if k.startswith('p_') and k not in keys:
                keys.append(k)
    env_groups = {}
    for s in serials:
        for k in (recs[s][0] if recs[s] else {}):
            if k.startswith('env_'):
                env_groups.setdefault(k.split('_')[1], []).append(k)
    units = {}
    for s in serials:
        if recs[s] and recs[s][0].get('model'):
            try:
                units.update(get_model(recs[s][0]['model']).param_units)
            except (KeyError, ValueError):
                pass
    panels = [(f'{k[2:]} [{units.get(k[2:], "-")}]', [k]) for k in keys] + \
        [(f'envelope at {cur} [N]', sorted(set(ks), key=ks.index))
         for cur, ks in env_groups.items()]
    ncol = 4
    nrow = max(1, math.ceil(len(panels) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4 * ncol, 2.8 * nrow), squeeze=False)
    colors = plt.rcParams['axes.prop_cycle'].by_key()['color']
    for ax, (title, ks) in zip(axes.ravel(), panels):
        for j, s in enumerate(serials):
            if not recs[s]:
                continue
            t0 = datetime.datetime.fromisoformat(recs[s][0]['test_time'])
            d = [(datetime.datetime.fromisoformat(r['test_time']) - t0).total_seconds()
                 / 86400.0 for r in recs[s]]
            for k in ks:
                ax.plot(d, [_num(r.get(k)) for r in recs[s]], 'o-', ms=3, lw=1,
                        color=colors[j % len(colors)], label=s if k == ks[0] else None)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel('days since first test', fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[len(panels):]:
        ax.set_visible(False)
    if panels:
        axes.ravel()[0].legend(fontsize=7)
    fig.suptitle('parameter and force-envelope trend per serial number')
    fig.tight_layout()
    return fig
