"""One damper: its fit, its envelope and its table row (a Dask task runs this)."""
import math

from mr_damper_model.identification.batch.envelope import (envelope_columns, envelope_ratio,
                                                           force_envelope)
from mr_damper_model.identification.batch.settings import (_one_line, METRIC_COLUMNS,
                                                           MULTI_CURRENT_MODEL)
from mr_damper_model.identification.identify import current_groups, identify
from mr_damper_model.io.data import DamperData, DataError
from mr_damper_model.io.records import expand_inputs, InputError, read_record


def _fmt(value):
    """Table text of a value: floats as their shortest exact repr, None / NaN as ''."""
    if value is None:
        return ''
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float) or type(value).__module__ == 'numpy':
        v = float(value)
        return '' if math.isnan(v) else repr(v)
    return str(value)


def _base_row(task, settings):
    return {'record': task.record, 'serial': task.serial, 'test_time': task.test_time,
            'status': 'error', 'reason': '', 'error': '', 'files': '', 'samples': '',
            'current_min_a': '', 'current_max_a': '', 'model': '', 'method': '',
            'seed': str(task.seed), 'envelope_worst_ratio': '',
            'fingerprint': task.fingerprint, 'config': settings.config_hash()}


def process_damper(task, settings):
    """
    Identify one damper and judge it; never raises (a bad damper gives an ``error`` row).

    Parameters
    ----------
    task : DamperTask
        The damper: what to read, its id and seed.
    settings : BatchSettings
        Model, master and tolerances.

    Returns
    -------
    dict
        The table row, every value as text (see :data:`TABLE_COLUMNS`; then the metrics,
        ``p_<name>`` per parameter and the envelope columns).

    """
    row = _base_row(task, settings)
    try:
        row.update(_identify_damper(task, settings))
    except Exception as exc:     # one bad damper must not stop the batch: say what failed
        msg = str(exc) if isinstance(exc, (DataError, OSError, ValueError)) \
            else f'{type(exc).__name__}: {exc}'
        row.update(status='error', error=_one_line(msg) or type(exc).__name__)
    return row


def _identify_damper(task, settings):
    import numpy as np

    if task.time_error:
        raise ValueError(task.time_error)
    try:
        names = expand_inputs(list(task.paths))
    except InputError as exc:
        raise ValueError(': '.join(exc.args)) from None
    parts = [read_record(n, topic=settings.topic) for n in names]
    data = parts[0] if len(parts) == 1 else DamperData.concatenate(parts, restamp=True)
    master = settings.master
    if settings.model is not None:
        model = settings.model
    elif master is not None:
        model = master['model']
    else:
        levels = [lv for lv, _ in current_groups(data)] or list(data.current_levels())
        model = MULTI_CURRENT_MODEL if len(levels) > 1 else 'kwok'
    options = dict(master.get('model_options') or {}) \
        if master is not None and master['model'] == model else None
    res = identify(data, model, method=settings.method, unbounded=settings.unbounded,
                   seed=task.seed, model_options=options)
    out = {'files': str(len(parts)), 'samples': str(data.n),
           'current_min_a': _fmt(res.current_min_a), 'current_max_a': _fmt(res.current_max_a),
           'model': res.model, 'method': res.method}
    metrics = res.metrics      # of the joint fit on all samples
    out.update({k: _fmt(metrics.get(k)) for k in METRIC_COLUMNS})
    out.update({f'p_{k}': _fmt(v) for k, v in res.parameters.items()})
    env = force_envelope(res.model, res.model_options, res.x, settings.currents_a,
                         settings.velocities_mps, settings.stroke_m)
    cols = envelope_columns(settings.currents_a, settings.velocities_mps)
    out.update({c: _fmt(v) for c, v in zip(cols, env.ravel())})
    if not settings.judged:
        out.update(status='fitted')
        return out
    reasons = []
    nrmse = metrics.get('nrmse_percent', math.nan)
    if not (math.isfinite(nrmse) and nrmse <= settings.max_nrmse_percent):
        reasons.append(f'fit: NRMSE {nrmse:.3g} % > {settings.max_nrmse_percent:g} %')
    if settings.master_envelope is not None:
        ref = np.asarray(settings.master_envelope, dtype=float).ravel()
        ratio = envelope_ratio(env, ref, settings.rel_tol, settings.abs_tol_n)
        worst = int(np.argmax(ratio))
        out['envelope_worst_ratio'] = _fmt(float(ratio[worst]))
        if ratio[worst] > 1.0:
            bad = int(np.sum(ratio > 1.0))
            reasons.append(f'envelope: {bad} of {ratio.size} points out of tolerance, worst '
                           f'{cols[worst][4:-2]} {env.ravel()[worst]:.1f} N vs master '
                           f'{ref[worst]:.1f} N')
    for name, lo, hi in settings.param_ranges:
        value = res.parameters.get(name)
        if value is None:
            reasons.append(f'range: model {res.model} has no parameter {name}')
        elif not lo <= value <= hi:
            reasons.append(f'range: {name} = {value:.4g} outside [{lo:g}, {hi:g}]')
    out.update(status='fail' if reasons else 'pass', reason='; '.join(reasons))
    return out
