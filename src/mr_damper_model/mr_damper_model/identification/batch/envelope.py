"""The master model and the force envelope a damper is judged by."""
import math

from mr_damper_model.identification.batch.settings import (DEFAULT_CURRENTS_A, ENVELOPE_CYCLES,
                                                           ENVELOPE_SAMPLES_PER_CYCLE)
from mr_damper_model.io.params_file import load_params
from mr_damper_model.models import get_model


def load_master(path):
    """
    Read a master parameter file (``params_file.load_params``) as the settings' ``master``.

    Raises
    ------
    DataError
        Unreadable or invalid parameter file (the message names the file).

    """
    pf = load_params(path)
    return {'model': pf.model, 'parameters': dict(pf.parameters),
            'model_options': dict(pf.model_options or {}), 'source': str(path),
            'current_min_a': pf.current_min_a, 'current_max_a': pf.current_max_a}


def master_currents(master):
    """Return a master's default envelope currents [A]: min, middle, max of its fit range."""
    lo, hi = master.get('current_min_a', math.nan), master.get('current_max_a', math.nan)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return DEFAULT_CURRENTS_A
    if hi - lo < 1e-9:
        return (float(lo),)
    return (float(lo), 0.5 * (lo + hi), float(hi))


def force_envelope(model, model_options, params, currents_a, velocities_mps, stroke_m):
    """
    Peak forces of a model on reference sine strokes (the damper's force-velocity envelope).

    For each coil current and peak velocity V, the piston follows x = A sin(w t) with
    w = V / A (A = ``stroke_m``) at constant current for :data:`ENVELOPE_CYCLES` cycles from
    rest; the rebound force is the largest and the compression force the smallest force of the
    last cycle (a damper dynamometer's peak-force / peak-velocity points).

    Parameters
    ----------
    model : str
        Model name (``models.get_model``).
    model_options : dict or None
        Model constants (e.g. ``{'i_ref_a': 1.0}``).
    params : dict or array_like with shape (n_params,)
        Parameter set.
    currents_a : sequence of float
        Coil currents [A].
    velocities_mps : sequence of float
        Peak piston velocities [m/s], positive.
    stroke_m : float
        Sine amplitude [m].

    Returns
    -------
    ndarray with shape (n_currents, n_velocities, 2)
        Rebound (max) and compression (min) force [N]; NaN where the model is not finite.

    """
    import numpy as np
    mdl = get_model(model, **(model_options or {}))
    x0 = mdl.from_dict(params) if isinstance(params, dict) else np.asarray(params, float)
    n = ENVELOPE_CYCLES * ENVELOPE_SAMPLES_PER_CYCLE
    phase = 2.0 * np.pi * np.arange(n) / ENVELOPE_SAMPLES_PER_CYCLE
    pairs = [(float(i), float(v)) for i in currents_a for v in velocities_mps]
    t, x, v, cur = [], [], [], []
    for i_a, vel in pairs:
        w = vel / stroke_m
        t.append(phase / w)
        x.append(stroke_m * np.sin(phase))
        v.append(vel * np.cos(phase))
        cur.append(np.full(n, i_a))
    starts = np.arange(len(pairs)) * n
    with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
        f = np.asarray(mdl.force(x0, np.concatenate(x), np.concatenate(v),
                                 i=np.concatenate(cur), t=np.concatenate(t), starts=starts),
                       dtype=float).reshape(len(pairs), n)
    last = f[:, n - ENVELOPE_SAMPLES_PER_CYCLE:]
    out = np.stack([last.max(axis=1), last.min(axis=1)], axis=1)
    out[~np.all(np.isfinite(last), axis=1)] = np.nan
    return out.reshape(len(currents_a), len(velocities_mps), 2)


def envelope_ratio(env, ref, rel_tol, abs_tol_n):
    """
    Deviation of envelope forces from the master's, in units of the tolerance.

    Parameters
    ----------
    env, ref : array_like
        Envelope forces of the damper and of the master [N] (same shape).
    rel_tol, abs_tol_n : float
        A point passes if abs(F - F_master) <= max(rel_tol * abs(F_master), abs_tol_n).

    Returns
    -------
    ndarray with shape (n_points,)
        abs(F - F_master) / allowed, flattened; a point passes if <= 1 (inf if not finite).

    """
    import numpy as np
    env = np.ravel(np.asarray(env, dtype=float))
    ref = np.ravel(np.asarray(ref, dtype=float))
    allowed = np.maximum(rel_tol * np.abs(ref), abs_tol_n)
    with np.errstate(invalid='ignore'):
        ratio = np.abs(env - ref) / allowed
    return np.where(np.isfinite(ratio), ratio, np.inf)


def envelope_columns(currents_a, velocities_mps):
    """Table column names of the envelope, in :func:`force_envelope` order (flattened)."""
    return [f'env_{i:g}A_{v:g}mps_{side}_n' for i in currents_a for v in velocities_mps
            for side in ('rebound', 'compression')]
