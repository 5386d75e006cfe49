"""The result table (CSV) of a batch, its journal of finished rows and the JSON summary."""
import csv
import json
import os
from pathlib import Path
import tempfile

from mr_damper_model.identification.batch.settings import METRIC_COLUMNS, TABLE_COLUMNS
from mr_damper_model.io.params_file import save_params
from mr_damper_model.models import get_model


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


#: Row status -> ``valid`` of the damper's parameter file (a failed damper's model is written
#: but marked invalid: a vehicle controller refuses it, ``invalid_flag``).
PARAMS_VALID = {'pass': True, 'fitted': True, 'fail': False}


def row_params(row, master=None):
    """
    One damper's end-of-line record as a parameter file (``io.params_file`` format).

    Parameters
    ----------
    row : dict
        A table row (:func:`read_table` or the batch's own rows), status ``pass``, ``fail``
        or ``fitted``.
    master : dict, optional
        The batch's master (its ``model_options`` were the fit's when its model is the
        damper's); otherwise the model's default options were.

    Returns
    -------
    dict
        ``model``, ``parameters`` (the ``p_<name>`` columns), ``model_options``,
        ``current_min_a``, ``current_max_a``, ``metrics``, ``valid`` (False for a failed
        damper), ``seed``, ``source`` (the record, serial, test time, status and reason).

    Raises
    ------
    ValueError
        A row without a model (status ``error``).

    """
    status = row.get('status')
    if status not in PARAMS_VALID:
        raise ValueError(f'{row.get("record")}: status {status!r} has no model')
    model = row['model']
    if master is not None and master.get('model') == model:
        options = dict(master.get('model_options') or {})
    else:
        options = dict(get_model(model).options)

    def num(key):
        text = row.get(key, '')
        return float(text) if text not in ('', None) else float('nan')

    params = {k[2:]: float(v) for k, v in row.items() if k.startswith('p_') and v != ''}
    source = (f'mr-damper-identify --batch: record {row["record"]}, serial '
              f'{row.get("serial") or "-"}, tested {row.get("test_time") or "-"}: {status}'
              + (f' ({row["reason"]})' if row.get('reason') else ''))
    return {'model': model, 'parameters': params, 'model_options': options,
            'current_min_a': num('current_min_a'), 'current_max_a': num('current_max_a'),
            'metrics': {k: num(k) for k in METRIC_COLUMNS if row.get(k, '') != ''},
            'valid': PARAMS_VALID[status], 'seed': row.get('seed'), 'source': source}


def write_params_files(rows, folder, master=None):
    """
    Write each damper's parameter file, ``<folder>/<serial>.json`` (``io.save_params``).

    Rows with status ``error`` have no model and are left out; a serial tested several
    times keeps its newest record (by test time, then record id).

    Returns
    -------
    dict
        ``{serial: path}`` of the files written.

    """
    newest = {}
    for row in sorted(rows, key=lambda r: (r.get('test_time') or '', r['record'])):
        if row.get('status') in PARAMS_VALID:
            newest[row.get('serial') or row['record']] = row
    out = {}
    for serial, row in sorted(newest.items()):
        name = ''.join(ch if ch.isalnum() or ch in '-_.' else '_' for ch in serial)
        path = Path(folder) / f'{name}.json'
        save_params(path, row_params(row, master))
        out[serial] = str(path)
    return out
