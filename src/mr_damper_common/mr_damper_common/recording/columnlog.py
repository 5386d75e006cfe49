"""
Column logs: numeric records streamed to disk as they are made, read back in bounded chunks.

A long run (an 8-hour drive at 1 kHz is 29 M control steps) must not keep its log in memory.
A column log is two files next to each other:

- ``NAME.f64``: the rows, float64 little-endian, row-major (one row = one value per column),
  appended in chunks of ``chunk_rows`` rows as the run goes;
- ``NAME.json``: the header: ``columns``, ``dtype``, ``rows`` and free ``meta`` (JSON values),
  written when the log is opened and again when it is closed.

A log cut short by a crash is still readable: the reader trusts the data file's size (whole rows
only), not the header's row count. Memory is bounded by the chunk (writer) or by the chunk a
reader asks for; :meth:`ColumnReader.strided` returns at most ``max_rows`` evenly spaced rows
(for plots and quick fits) through a memory map.

``NAME`` is given with or without a suffix; ``log.f64``, ``log.json`` and ``log`` name the same
log.
"""
import json
import math
import os
from pathlib import Path

import numpy as np

from mr_damper_common.health import finite_or_none

DTYPE = '<f8'


def log_paths(path):
    """Return ``(data_path, header_path)`` of the column log named ``path``."""
    p = Path(path)
    if p.suffix in ('.f64', '.json'):
        p = p.with_suffix('')
    return p.with_name(p.name + '.f64'), p.with_name(p.name + '.json')


def exists(path):
    """Return True when the column log ``path`` has a header and a data file."""
    data, head = log_paths(path)
    return data.exists() and head.exists()


class ColumnWriter:
    """
    Append rows of floats to a column log, in chunks.

    Parameters
    ----------
    path : path
        Log name (see :func:`log_paths`); existing files are replaced.
    columns : sequence of str
        Column names (one float per column and row).
    chunk_rows : int
        Rows buffered in memory before they are written (and flushed to the OS).
    meta : dict, optional
        JSON values stored in the header (updated by :meth:`close`).

    """

    def __init__(self, path, columns, *, chunk_rows=4096, meta=None):
        self.columns = tuple(str(c) for c in columns)
        if not self.columns or len(set(self.columns)) != len(self.columns):
            raise ValueError(f'column names must be unique and not empty, got {columns!r}')
        if int(chunk_rows) < 1:
            raise ValueError(f'`chunk_rows` must be >= 1, got {chunk_rows}')
        self.data_path, self.header_path = log_paths(path)
        self.data_path.parent.mkdir(parents=True, exist_ok=True)
        self.meta = dict(meta or {})
        self._buf = np.empty((int(chunk_rows), len(self.columns)), dtype=DTYPE)
        self._k = 0
        self.rows = 0
        self._file = open(self.data_path, 'wb')
        self._write_header()

    def _write_header(self):
        head = {'columns': list(self.columns), 'dtype': DTYPE, 'rows': self.rows,
                'meta': finite_or_none(self.meta)}
        tmp = self.header_path.with_name(self.header_path.name + '.tmp')
        tmp.write_text(json.dumps(head, allow_nan=False))
        os.replace(tmp, self.header_path)

    def append(self, row):
        """Append one row (a sequence of ``len(columns)`` floats)."""
        if self._file is None:
            raise ValueError(f'column log {self.data_path} is closed')
        self._buf[self._k] = row
        self._k += 1
        self.rows += 1
        if self._k == self._buf.shape[0]:
            self.flush()

    def append_block(self, block):
        """Append rows given as an array with shape ``(n, len(columns))``."""
        block = np.asarray(block, dtype=DTYPE)
        if block.ndim != 2 or block.shape[1] != len(self.columns):
            raise ValueError(f'block must have shape (n, {len(self.columns)}), got {block.shape}')
        self.flush()
        self._file.write(np.ascontiguousarray(block).tobytes())
        self.rows += block.shape[0]

    def flush(self):
        """Write the buffered rows to the file."""
        if self._file is None or self._k == 0:
            return
        self._file.write(self._buf[:self._k].tobytes())
        self._file.flush()
        self._k = 0

    def __len__(self):
        return self.rows

    def close(self, **meta):
        """Write what is buffered, update the header (``meta`` added) and close the file."""
        if self._file is None:
            return
        self.flush()
        self._file.close()
        self._file = None
        self.meta.update(meta)
        self._write_header()

    @property
    def closed(self):
        """True once :meth:`close` ran."""
        return self._file is None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class ColumnReader:
    """
    Read a column log in bounded chunks.

    Parameters
    ----------
    path : path
        Log name (see :func:`log_paths`).

    Raises
    ------
    FileNotFoundError
        No header or data file.
    ValueError
        A header that is not a column log.

    """

    def __init__(self, path):
        self.data_path, self.header_path = log_paths(path)
        if not self.header_path.exists() or not self.data_path.exists():
            raise FileNotFoundError(f'no column log {self.data_path} (+ .json header)')
        try:
            head = json.loads(self.header_path.read_text())
            self.columns = tuple(head['columns'])
            dtype = head.get('dtype', DTYPE)
        except (ValueError, KeyError, TypeError) as exc:
            raise ValueError(f'{self.header_path}: not a column log header ({exc})') from exc
        if dtype != DTYPE:
            raise ValueError(f'{self.header_path}: dtype {dtype!r}, expected {DTYPE!r}')
        self.meta = dict(head.get('meta') or {})
        self._width = len(self.columns)
        # whole rows in the file: a log cut short by a crash is read up to its last full row
        self.rows = os.path.getsize(self.data_path) // (8 * self._width)

    def __len__(self):
        return self.rows

    def _index(self, columns):
        names = self.columns if columns is None else tuple(columns)
        missing = [c for c in names if c not in self.columns]
        if missing:
            raise KeyError(f'{self.data_path}: no column(s) {missing}; has {list(self.columns)}')
        return names, [self.columns.index(c) for c in names]

    def _map(self):
        if self.rows == 0:
            return np.zeros((0, self._width))
        return np.memmap(self.data_path, dtype=DTYPE, mode='r',
                         shape=(self.rows, self._width))

    def chunks(self, rows=65536, columns=None, *, overlap=0):
        """
        Yield the log as dicts of column arrays of at most ``rows`` rows each.

        Parameters
        ----------
        rows : int
            Rows per chunk.
        columns : sequence of str, optional
            Columns to read (default all).
        overlap : int
            Each chunk after the first starts with the last ``overlap`` rows of the previous
            one (for differences across chunk boundaries).

        """
        names, idx = self._index(columns)
        rows = max(int(rows), int(overlap) + 1)
        m = self._map()
        start = 0
        while start < self.rows:
            lo = max(0, start - overlap) if start else 0
            stop = min(self.rows, start + rows)
            block = np.array(m[lo:stop])
            yield {n: block[:, j] for n, j in zip(names, idx)}
            start = stop
        del m

    def strided(self, max_rows=200000, columns=None):
        """
        Return at most ``max_rows`` evenly spaced rows (every row if the log is that short).

        The last row is always included. Returns a dict of arrays and adds ``'stride'``.

        """
        names, idx = self._index(columns)
        step = max(1, int(math.ceil(self.rows / max(1, int(max_rows)))))
        m = self._map()
        sel = np.arange(0, self.rows, step)
        if self.rows and sel[-1] != self.rows - 1:
            sel = np.append(sel, self.rows - 1)
        block = np.array(m[sel]) if self.rows else np.zeros((0, self._width))
        del m
        out = {n: block[:, j] for n, j in zip(names, idx)}
        out['stride'] = step
        return out

    def read(self, columns=None, *, max_rows=None):
        """
        Return whole columns (for short logs: tests and small tools).

        Raises
        ------
        MemoryError
            The log has more than ``max_rows`` rows (use :meth:`chunks` or :meth:`strided`).

        """
        if max_rows is not None and self.rows > max_rows:
            raise MemoryError(f'{self.data_path}: {self.rows} rows > {max_rows}; read it in '
                              'chunks')
        names, idx = self._index(columns)
        m = self._map()
        block = np.array(m[:])
        del m
        return {n: block[:, j] for n, j in zip(names, idx)}


class JsonLines:
    """
    Append JSON records to a file, one per line, as they come (bounded memory).

    ``JsonLines.read(path)`` yields the records back; a line cut short by a crash is skipped
    and counted in ``skipped`` of the iterator's owner (see :func:`read_json_lines`).
    """

    def __init__(self, path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, 'w', encoding='utf-8')
        self.count = 0

    def append(self, record):
        """Write one record (non-finite floats become null)."""
        self._file.write(json.dumps(finite_or_none(record), allow_nan=False))
        self._file.write('\n')
        self._file.flush()
        self.count += 1

    def close(self):
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None


def read_json_lines(path, bad=None):
    """
    Yield the records of a JSON-lines file.

    Parameters
    ----------
    path : path
        File written by :class:`JsonLines`.
    bad : list, optional
        Line numbers that are not valid JSON (e.g. the last line of a crashed run) are appended
        here instead of raising.

    """
    with open(path, encoding='utf-8') as fh:
        for n, line in enumerate(fh, 1):
            line = line.strip()
            if not line:
                continue
            try:
                yield json.loads(line)
            except ValueError:
                if bad is None:
                    raise ValueError(f'{path}:{n}: not a JSON record') from None
                bad.append(n)


class ArrayLog:
    """
    Arrays in memory with the reading interface of :class:`ColumnReader` (tests, short runs).

    Parameters
    ----------
    arrays : dict of str -> array_like
        Columns of equal length (scalar entries go to ``meta``).

    """

    def __init__(self, arrays):
        cols, meta = {}, {}
        for k, v in dict(arrays).items():
            a = np.asarray(v)
            if a.ndim == 1:
                cols[k] = a.astype(float) if a.dtype != float else a
            else:
                meta[k] = a.item() if a.ndim == 0 else v
        lengths = {a.size for a in cols.values()}
        if len(lengths) > 1:
            raise ValueError(f'columns of different lengths: {sorted(lengths)}')
        self._cols = cols
        self.columns = tuple(cols)
        self.meta = meta
        self.rows = lengths.pop() if lengths else 0

    def __len__(self):
        return self.rows

    def _names(self, columns):
        names = self.columns if columns is None else tuple(columns)
        missing = [c for c in names if c not in self._cols]
        if missing:
            raise KeyError(f'no column(s) {missing}; has {list(self.columns)}')
        return names

    def chunks(self, rows=65536, columns=None, *, overlap=0):
        """As :meth:`ColumnReader.chunks`."""
        names = self._names(columns)
        rows = max(int(rows), int(overlap) + 1)
        start = 0
        while start < self.rows:
            lo = max(0, start - overlap) if start else 0
            stop = min(self.rows, start + rows)
            yield {n: self._cols[n][lo:stop] for n in names}
            start = stop

    def strided(self, max_rows=200000, columns=None):
        """As :meth:`ColumnReader.strided`."""
        names = self._names(columns)
        step = max(1, int(math.ceil(self.rows / max(1, int(max_rows)))))
        sel = np.arange(0, self.rows, step)
        if self.rows and sel[-1] != self.rows - 1:
            sel = np.append(sel, self.rows - 1)
        out = {n: self._cols[n][sel] for n in names}
        out['stride'] = step
        return out

    def read(self, columns=None, *, max_rows=None):
        """As :meth:`ColumnReader.read`."""
        return {n: self._cols[n] for n in self._names(columns)}


def open_log(source):
    """Return a reader for ``source``: a column log path, a reader, or a dict of arrays."""
    if isinstance(source, (ColumnReader, ArrayLog)):
        return source
    if isinstance(source, dict):
        return ArrayLog(source)
    return ColumnReader(source)
