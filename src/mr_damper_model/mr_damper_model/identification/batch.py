"""
Identification at scale: one model per damper of an archive, checked against a master model.

``mr-damper-identify --batch ROOT`` (see docs/batch.md) finds the dampers of an archive
(:func:`discover`), fits one model per damper (:func:`process_damper`, seeded by the damper's id),
computes its force envelope (:func:`force_envelope`), judges it against a master model within
stated tolerances, and writes one row per damper into a CSV table and a JSON summary
(:func:`run_batch`). The dampers run serially in this process or as tasks on a Dask cluster
(a loopback-only ``LocalCluster`` or an existing scheduler); a task gets everything it needs
in its arguments and its seed from the damper's id, so the table does not depend on the
number of workers or on the order in which they finish. A re-run skips the dampers whose row
is already in the table (same files, same settings) unless ``force``.
:func:`trend` reports each parameter and envelope force against the test time of the records
of one serial number (ageing, fluid loss) and :func:`trend_figure` plots it.

No ROS here: the module is imported by the command-line tool and the benchmark only.
"""
import csv
from dataclasses import asdict, dataclass, field
import datetime
import hashlib
import json
import math
import os
from pathlib import Path
import re
import sys
import tempfile
import time

__all__ = ['BatchSettings', 'DamperTask', 'discover', 'process_damper', 'process_dampers',
           'force_envelope', 'envelope_ratio', 'envelope_columns', 'run_batch', 'read_table',
           'trend',
           'write_trend', 'trend_figure', 'load_master', 'master_currents',
           'DEFAULT_VELOCITIES_MPS', 'DEFAULT_CURRENTS_A', 'DEFAULT_STROKE_M', 'DEFAULT_REL_TOL',
           'DEFAULT_ABS_TOL_N', 'DEFAULT_MAX_NRMSE_PERCENT', 'TABLE_COLUMNS']

#: Envelope defaults: peak piston velocities [m/s] of the reference sine strokes ...
DEFAULT_VELOCITIES_MPS = (0.025, 0.05, 0.1)
#: ... coil currents [A] when there is no master with a current range ...
DEFAULT_CURRENTS_A = (0.0, 1.0)
#: ... and the stroke amplitude [m] of the reference sine.
DEFAULT_STROKE_M = 0.01
#: Envelope tolerance: a point passes if abs(F - F_master) <= max(rel * abs(F_master), abs).
DEFAULT_REL_TOL = 0.10
DEFAULT_ABS_TOL_N = 20.0
#: A fit worse than this NRMSE [%] is not trusted: the damper fails ("fit").
DEFAULT_MAX_NRMSE_PERCENT = 10.0
#: Reference sine of the envelope: cycles simulated (the last one is measured), samples each.
ENVELOPE_CYCLES = 3
ENVELOPE_SAMPLES_PER_CYCLE = 400
#: Columns every row has, in this order; then the metrics, parameters (``p_<name>``) and
#: envelope forces (``env_...``).
TABLE_COLUMNS = ('record', 'serial', 'test_time', 'status', 'reason', 'error', 'files',
                 'samples', 'current_min_a', 'current_max_a', 'model', 'method', 'seed',
                 'envelope_worst_ratio', 'fingerprint', 'config')
METRIC_COLUMNS = ('rmse_n', 'nrmse_percent', 'mean_abs_error_n', 'mean_percent_error',
                  'max_percent_error')
RECORD_SUFFIXES = ('.csv', '.mcap', '.db3')
#: Seconds to wait for an existing Dask scheduler (``scheduler``) to answer.
SCHEDULER_TIMEOUT_S = 30
#: Dampers go to the cluster in about this many tasks per worker (a task costs the scheduler,
#: the worker and the client some milliseconds of CPU each; a damper of a short end-of-line
#: test takes tens of milliseconds to fit).
CHUNKS_PER_WORKER = 8
#: Default model for records at several current levels (as the single-record tool).
MULTI_CURRENT_MODEL = 'kwok-current-amp'


def _one_line(text):
    return ' '.join(str(text).split())


# ----------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class BatchSettings:
    """
    Everything a damper task needs besides its files (picklable, sent to the workers).

    Attributes
    ----------
    model : str or None
        Model fitted to every damper; None: the master's model, else ``kwok-current-amp`` for
        records at several current levels and ``kwok`` otherwise.
    method, unbounded, topic
        As ``mr-damper-identify`` (``--method``, ``--unbounded``, ``--topic``).
    seed : int
        Base seed; each damper's swarm seed is derived from it and the damper's id.
    master : dict or None
        ``{'model', 'parameters', 'model_options', 'source'}`` of the master model.
    velocities_mps, currents_a : tuple of float
        Envelope points: peak piston velocity [m/s] of the reference sine and coil current [A].
    stroke_m : float
        Amplitude of the reference sine [m].
    rel_tol, abs_tol_n : float
        Envelope tolerance: abs(F - F_master) <= max(rel_tol * abs(F_master), abs_tol_n).
    max_nrmse_percent : float
        Fits with a larger NRMSE fail.
    param_ranges : tuple of (name, lo, hi)
        Parameter ranges a passing damper's parameters must lie in.

    """

    model: object = None
    method: str = 'separable'
    unbounded: bool = False
    topic: object = None
    seed: int = 1
    master: object = None
    velocities_mps: tuple = DEFAULT_VELOCITIES_MPS
    currents_a: tuple = DEFAULT_CURRENTS_A
    stroke_m: float = DEFAULT_STROKE_M
    rel_tol: float = DEFAULT_REL_TOL
    abs_tol_n: float = DEFAULT_ABS_TOL_N
    max_nrmse_percent: float = DEFAULT_MAX_NRMSE_PERCENT
    param_ranges: tuple = ()
    master_envelope: tuple = field(default=None, compare=False)

    def __post_init__(self):
        for name in ('velocities_mps', 'currents_a'):
            vals = tuple(float(v) for v in getattr(self, name))
            if not vals or not all(math.isfinite(v) for v in vals):
                raise ValueError(f'`{name}` must be a non-empty list of finite numbers.')
            object.__setattr__(self, name, vals)
        if any(v <= 0 for v in self.velocities_mps):
            raise ValueError('`velocities_mps` must be positive.')
        for name in ('stroke_m', 'abs_tol_n', 'max_nrmse_percent'):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f'`{name}` must be a positive number, got {v}.')
        if not (math.isfinite(self.rel_tol) and self.rel_tol >= 0):
            raise ValueError(f'`rel_tol` must be >= 0, got {self.rel_tol}.')
        ranges = tuple((str(n), float(lo), float(hi)) for n, lo, hi in self.param_ranges)
        for n, lo, hi in ranges:
            if not lo <= hi:
                raise ValueError(f'parameter range of {n}: {lo} > {hi}')
        object.__setattr__(self, 'param_ranges', ranges)
        if self.master is not None and self.master_envelope is None:
            env = force_envelope(self.master['model'], self.master.get('model_options'),
                                 self.master['parameters'], self.currents_a,
                                 self.velocities_mps, self.stroke_m)
            object.__setattr__(self, 'master_envelope', tuple(map(tuple, env.tolist())))

    @property
    def judged(self):
        """True if the dampers get a pass / fail (a master or parameter ranges given)."""
        return self.master is not None or bool(self.param_ranges)

    def config_hash(self):
        """Return a short hash of the settings that change a row (other settings: redone)."""
        d = asdict(self)
        d.pop('master_envelope')
        if d['master'] is not None:         # the master's content, not where it was read from
            d['master'] = {k: d['master'].get(k) for k in ('model', 'parameters',
                                                           'model_options')}
        text = json.dumps(d, sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def load_master(path):
    """
    Read a master parameter file (``params_file.load_params``) as the settings' ``master``.

    Raises
    ------
    DataError
        Unreadable or invalid parameter file (the message names the file).

    """
    from mr_damper_model.io.params_file import load_params
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


# ----------------------------------------------------------------------------- envelope


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
    from mr_damper_model.models import get_model
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


# ----------------------------------------------------------------------------- discovery


@dataclass(frozen=True)
class DamperTask:
    """
    One damper test of the archive.

    Attributes
    ----------
    record : str
        Its id: the folder or file path relative to the archive root (posix). Unique.
    serial : str
        Serial number (the folder name, or the pattern's ``serial`` group).
    test_time : str
        Test time from the pattern's ``date`` group, ISO 8601 ('' if none).
    paths : tuple of str
        What to read (a folder: its records are fitted together; or one record file / bag).
    seed : int
        Swarm seed, from the base seed and ``record`` only.
    fingerprint : str
        Hash of the names, sizes and modification times of its files.
    time_error : str
        Why the ``date`` group could not be read ('' if it could).

    """

    record: str
    serial: str
    test_time: str
    paths: tuple
    seed: int
    fingerprint: str
    time_error: str = ''


def damper_seed(base_seed, record):
    """Seed of a damper's swarm: a hash of the base seed and its id (not of any order)."""
    digest = hashlib.sha256(f'{int(base_seed)}:{record}'.encode()).digest()
    return int.from_bytes(digest[:4], 'little') % (2 ** 31)


def _fingerprint(path):
    p = Path(path)
    files = sorted(q for q in p.rglob('*') if q.is_file()) if p.is_dir() else [p]
    h = hashlib.sha256()
    for q in files:
        st = q.stat()
        h.update(f'{q.relative_to(p) if p.is_dir() else q.name}\0{st.st_size}\0'
                 f'{st.st_mtime_ns}\n'.encode())
    return h.hexdigest()[:16]


def parse_test_time(text):
    """
    Read a test time (ISO 8601: 2026-03-01, 20260301, 2026-03-01T14:30) as ISO text.

    Raises
    ------
    ValueError
        Not an ISO 8601 date or date-time.

    """
    s = text.strip()
    if re.fullmatch(r'\d{4}-\d{2}-\d{2}[ _T]\d{2}-\d{2}(-\d{2})?', s):   # file-name safe
        s = s[:10] + 'T' + s[11:].replace('-', ':')
    try:
        return datetime.datetime.fromisoformat(s.replace('_', 'T')).isoformat()
    except ValueError:
        raise ValueError(f'test time {text!r} is not an ISO 8601 date or date-time '
                         '(e.g. 2026-03-01, 20260301, 2026-03-01T14:30)') from None


def _match(pattern, name):
    """Return ``(serial, date text or None)`` of a name, or None if it does not match."""
    m = pattern.search(name)
    if m is None:
        return None
    groups = m.groupdict()
    if groups.get('serial') is not None:
        serial = groups['serial']
    elif m.re.groups and 'serial' not in groups and m.group(1) is not None:
        serial = m.group(1)
    else:
        serial = m.group(0)
    return serial, groups.get('date')


def discover(root, *, per_file=False, pattern=None, seed=1, exclude=()):
    """
    Find the dampers of an archive.

    Parameters
    ----------
    root : str or Path
        Archive directory.
    per_file : bool
        False: one damper test per sub-directory of ``root`` (its CSV files and bags fitted
        together; serial = the directory name). True: one per record file (``.csv``,
        ``.mcap``, ``.db3``, rosbag2 directory) anywhere under ``root``.
    pattern : str or None
        Regular expression searched in the relative path (``per_file``) or the directory name;
        names it does not match are ignored (and listed). The group ``serial`` (or the first
        group, or the whole match) is the serial number, the optional group ``date`` the test
        time. Required with ``per_file``.
    seed : int
        Base seed (:func:`damper_seed`).
    exclude : sequence of path
        Files to leave out (the batch's own outputs). Hidden names (``.git``) are ignored.

    Returns
    -------
    tasks : list of DamperTask
        Sorted by ``record``.
    ignored : list of str
        Names (relative paths) not taken, sorted.

    Raises
    ------
    ValueError
        ``root`` is not a directory, or the pattern is not a regular expression.

    """
    from mr_damper_model.io.bag_io import is_bag
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f'{root}: not a directory')
    if per_file and pattern is None:
        raise ValueError('one damper per file needs a serial-number pattern')
    try:
        rx = re.compile(pattern) if pattern is not None else None
    except re.error as exc:
        raise ValueError(f'serial pattern {pattern!r} is not a regular expression ({exc})') \
            from None
    skip = {Path(e).resolve() for e in exclude}
    candidates, ignored = [], []
    if per_file:
        stack = [root]
        while stack:
            d = stack.pop()
            for c in sorted(d.iterdir()):
                if c.resolve() in skip:
                    continue
                if c.name.startswith('.'):
                    ignored.append(c.relative_to(root).as_posix())
                elif c.is_dir() and is_bag(c):
                    candidates.append(c)
                elif c.is_dir():
                    stack.append(c)
                elif c.suffix.lower() in RECORD_SUFFIXES:
                    candidates.append(c)
                else:
                    ignored.append(c.relative_to(root).as_posix())
    else:
        for c in sorted(root.iterdir()):
            if c.is_dir() and not c.name.startswith('.'):
                candidates.append(c)
            elif c.resolve() not in skip:
                ignored.append(c.name)
    tasks = []
    for c in candidates:
        rel = c.relative_to(root).as_posix()
        serial, date = rel if per_file else c.name, None
        if rx is not None:
            found = _match(rx, rel if per_file else c.name)
            if found is None:
                ignored.append(rel)
                continue
            serial, date = found
        test_time, time_error = '', ''
        if date is not None:
            try:
                test_time = parse_test_time(date)
            except ValueError as exc:
                time_error = str(exc)
        tasks.append(DamperTask(record=rel, serial=serial, test_time=test_time,
                                paths=(str(c),), seed=damper_seed(seed, rel),
                                fingerprint=_fingerprint(c), time_error=time_error))
    return sorted(tasks, key=lambda t: t.record), sorted(ignored)


# ----------------------------------------------------------------------------- one damper


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
        from mr_damper_model.io.data import DataError
        msg = str(exc) if isinstance(exc, (DataError, OSError, ValueError)) \
            else f'{type(exc).__name__}: {exc}'
        row.update(status='error', error=_one_line(msg) or type(exc).__name__)
    return row


def _identify_damper(task, settings):
    import numpy as np
    from mr_damper_model.tools.cli import _InputError, expand_inputs, read_record
    from mr_damper_model.io.data import DamperData
    from mr_damper_model.identification.identify import current_groups, identify

    if task.time_error:
        raise ValueError(task.time_error)
    try:
        names = expand_inputs(list(task.paths))
    except _InputError as exc:
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


# ----------------------------------------------------------------------------- table


def read_table(path):
    """
    Read a batch table.

    Returns
    -------
    list of dict
        One row per damper, values as text ('' = empty).

    Raises
    ------
    ValueError
        Not a batch table (no ``record`` column).

    """
    with open(path, newline='') as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames is None:
            return []
        if 'record' not in reader.fieldnames:
            raise ValueError(f'{path}: not a batch table (no "record" column)')
        return [dict(r) for r in reader]


def _journal_rows(path):
    """Rows of an interrupted run's journal (JSON lines); a cut last line is ignored."""
    rows = []
    try:
        with open(path) as fh:
            for line in fh:
                try:
                    rows.append(json.loads(line))
                except ValueError:
                    break
    except FileNotFoundError:
        pass
    return rows


def _write_table(path, rows):
    """Write rows sorted by record; columns: fixed, metrics, then in order of appearance."""
    rows = sorted(rows, key=lambda r: r['record'])
    cols = list(TABLE_COLUMNS) + list(METRIC_COLUMNS)
    seen = set(cols)
    for r in rows:
        for k in r:
            if k not in seen:
                seen.add(k)
                cols.append(k)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix='.tmp')
    try:
        with os.fdopen(fd, 'w', newline='') as fh:
            w = csv.DictWriter(fh, fieldnames=cols, restval='', lineterminator='\n')
            w.writeheader()
            w.writerows(rows)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _write_json(path, obj):
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix='.tmp')
    with os.fdopen(fd, 'w') as fh:
        json.dump(obj, fh, indent=2)
        fh.write('\n')
    os.replace(tmp, path)


# ----------------------------------------------------------------------------- progress


class Progress:
    """
    Progress bar of the batch on a text stream (stderr).

    On a terminal one line rewritten in place; otherwise a line at every tenth of the work.
    """

    def __init__(self, total, stream=None, width=30):
        self.total, self.done, self.errors = total, 0, 0
        self.stream = sys.stderr if stream is None else stream
        self.width = width
        self.t0 = time.perf_counter()
        self.tty = bool(getattr(self.stream, 'isatty', lambda: False)())
        self._next = 0

    def update(self, row):
        """Count one finished damper (its row)."""
        self.done += 1
        self.errors += row.get('status') == 'error'
        if self.tty or self.done >= self._next or self.done == self.total:
            self._next = self.done + max(1, self.total // 10)
            self._draw()

    def _draw(self):
        frac = self.done / self.total if self.total else 1.0
        el = time.perf_counter() - self.t0
        rate = self.done / el if el > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else math.nan
        bar = '#' * int(round(frac * self.width))
        text = (f'[{bar:<{self.width}}] {self.done}/{self.total} dampers, {self.errors} '
                f'error(s), {rate:.2f} /s' + (f', {eta:.0f} s left' if self.done < self.total
                                              and math.isfinite(eta) else ''))
        end = '' if self.tty and self.done < self.total else '\n'
        self.stream.write(('\r' if self.tty else '') + text + end)
        self.stream.flush()


# ----------------------------------------------------------------------------- the batch


def _run_serial(tasks, settings, on_row):
    for task in tasks:
        on_row(process_damper(task, settings))


def process_dampers(tasks, settings):
    """Run :func:`process_damper` on each task in turn; return the rows (one Dask task)."""
    return [process_damper(t, settings) for t in tasks]


def _chunks(tasks, n_workers):
    """Split the tasks into :data:`CHUNKS_PER_WORKER` contiguous groups per worker (sizes +-1)."""
    n = max(1, min(len(tasks), CHUNKS_PER_WORKER * max(1, n_workers)))
    base, extra = divmod(len(tasks), n)
    edges = [0]
    for k in range(n):
        edges.append(edges[-1] + base + (k < extra))
    return [tasks[a:b] for a, b in zip(edges[:-1], edges[1:])]


def _run_dask(tasks, settings, on_row, *, workers, scheduler):
    """Run the tasks on Dask in chunks; a chunk lost with its worker gives error rows."""
    import logging
    from dask.distributed import as_completed, Client, LocalCluster

    def drain(client, n_workers):
        futures = {client.submit(process_dampers, chunk, settings, pure=False,
                                 key=f'mr-damper-{chunk[0].seed}-{k}'): chunk
                   for k, chunk in enumerate(_chunks(tasks, n_workers))}
        for fut in as_completed(futures):
            try:
                rows = fut.result()
            except Exception as exc:
                rows = []
                for t in futures[fut]:
                    row = _base_row(t, settings)
                    row['error'] = _one_line(f'task failed on the cluster: '
                                             f'{type(exc).__name__}: {exc}')
                    rows.append(row)
            for row in rows:
                on_row(row)
            fut.release()

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=SCHEDULER_TIMEOUT_S)
        except (OSError, ValueError) as exc:
            raise ValueError(f'cannot reach the Dask scheduler {scheduler} '
                             f'({type(exc).__name__}: {exc})') from None
        with client:
            drain(client, len(client.scheduler_info().get('workers', {})))
        return
    with tempfile.TemporaryDirectory(prefix='mr_damper_dask_') as scratch:
        # loopback only, no dashboards: nothing of the cluster is reachable off this machine
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          host='127.0.0.1', dashboard_address=None,
                          worker_dashboard_address=None, silence_logs=logging.ERROR,
                          local_directory=scratch) as cluster, Client(cluster) as client:
            drain(client, workers)


def run_batch(root, settings, *, table, per_file=False, pattern=None, workers=0,
              scheduler=None, force=False, progress=None, summary=None, callback=None):
    """
    Identify every damper of an archive; write the table and the JSON summary.

    Parameters
    ----------
    root : str or Path
        Archive (see :func:`discover`).
    settings : BatchSettings
        Model, master and tolerances.
    table : str or Path
        CSV table; rows already in it (same record, files and settings) are kept and their
        dampers skipped unless ``force``.
    per_file, pattern
        See :func:`discover`.
    workers : int
        0: serially in this process; N: a local Dask cluster of N single-threaded worker
        processes on 127.0.0.1.
    scheduler : str, optional
        Address of an existing Dask scheduler (then ``workers`` is not used).
    force : bool
        Redo every damper.
    progress : text stream or False, optional
        Where the progress bar goes (default stderr; False: none).
    summary : str or Path, optional
        JSON summary (default: the table with the suffix ``.json``).
    callback : callable, optional
        ``callback(row)`` with each damper's row as it finishes (in finishing order).

    Returns
    -------
    dict
        The summary (see docs/batch.md).

    """
    table = Path(table)
    summary = Path(summary) if summary is not None else table.with_suffix('.json')
    journal = table.with_name(table.name + '.journal')
    tasks, ignored = discover(root, per_file=per_file, pattern=pattern, seed=settings.seed,
                              exclude=(table, summary, journal,
                                       table.with_name(f'{table.stem}_trend.csv')))
    config = settings.config_hash()
    old = read_table(table) if table.exists() else []
    old_by = {r['record']: r for r in old}
    for r in _journal_rows(journal):         # an interrupted run's finished dampers
        old_by[r['record']] = r
    todo, keep = [], []
    for t in tasks:
        prev = old_by.get(t.record)
        if (not force and prev is not None and prev.get('fingerprint') == t.fingerprint
                and prev.get('config') == config):
            keep.append(prev)
        else:
            todo.append(t)
    current = {t.record for t in tasks}
    history = [r for rec, r in old_by.items() if rec not in current]   # dampers since removed
    new_rows = []
    bar = None if progress is False else Progress(len(todo), progress)
    t0 = time.perf_counter()
    try:
        with open(journal, 'a') as jf:
            def on_row(row):
                new_rows.append(row)
                jf.write(json.dumps(row) + '\n')
                jf.flush()
                if bar is not None:
                    bar.update(row)
                if callback is not None:
                    callback(row)

            if todo and workers == 0 and scheduler is None:
                _run_serial(todo, settings, on_row)
            elif todo:
                _run_dask(todo, settings, on_row, workers=min(workers, len(todo)),
                          scheduler=scheduler)
    finally:
        if journal.exists() and journal.stat().st_size == 0:
            journal.unlink()
    wall = time.perf_counter() - t0
    rows = history + keep + new_rows
    _write_table(table, rows)
    journal.unlink(missing_ok=True)
    out = _summary(rows, settings, root=root, table=table, ignored=ignored,
                   processed=len(new_rows), skipped=len(keep), wall=wall,
                   workers=workers if scheduler is None else None, scheduler=scheduler)
    _write_json(summary, out)
    return out


def _summary(rows, settings, *, root, table, ignored, processed, skipped, wall, workers,
             scheduler):
    counts = {s: sum(r['status'] == s for r in rows)
              for s in ('pass', 'fail', 'error', 'fitted')}
    master = None
    if settings.master is not None:
        env = [{'current_a': i, 'velocity_mps': v, 'rebound_n': reb, 'compression_n': comp}
               for i, row in zip(settings.currents_a, settings.master_envelope)
               for v, (reb, comp) in zip(settings.velocities_mps, row)]
        master = {k: settings.master.get(k) for k in ('source', 'model', 'model_options')}
        master['envelope'] = env
    s = asdict(settings)
    s.pop('master_envelope')
    s.pop('master')
    return {
        'root': str(root), 'table': str(table), 'config': settings.config_hash(),
        'settings': s, 'master': master,
        'dampers': len(rows), 'processed': processed, 'skipped': skipped, 'counts': counts,
        'failed': [{'record': r['record'], 'reason': r['reason']}
                   for r in sorted(rows, key=lambda r: r['record']) if r['status'] == 'fail'],
        'errors': [{'record': r['record'], 'error': r['error']}
                   for r in sorted(rows, key=lambda r: r['record']) if r['status'] == 'error'],
        'ignored': ignored, 'wall_s': wall,
        'dampers_per_s': processed / wall if processed and wall > 0 else None,
        'workers': workers, 'scheduler': scheduler,
    }


# ----------------------------------------------------------------------------- trend


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
        from mr_damper_model.tools.plots import save_figure
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
            from mr_damper_model.models import get_model
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
