"""The result table (CSV) of a batch, its journal of finished rows and the JSON summary."""
import csv
import json
import os
from pathlib import Path
import tempfile

from mr_damper_model.identification.batch.settings import METRIC_COLUMNS, TABLE_COLUMNS


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
