"""
Damper measurement records: the ``t,x,v,f,i`` DAQ format, reading, writing and validation.

A record holds one damper test as equal-length arrays in SI units:

====  ==========================  =====
name  quantity                    unit
====  ==========================  =====
t     sample time                 s
x     piston displacement         m
v     piston velocity             m/s
f     damper force                N
i     coil current                A
====  ==========================  =====

CSV files have the header ``t,x,v,f,i`` (any column order; extra columns are ignored). The ``v``
column may be left empty: it is then derived from ``x`` (see :func:`derive_velocity`). A gzip
compressed CSV (``.csv.gz``, recognised by its content) reads the same as the plain file.
Every problem found in a file raises :class:`DataError` with one line naming the file and the
problem, so command-line tools can print it and exit with status 2.
"""
import csv
from dataclasses import dataclass
import gzip
import math
from pathlib import Path
import zlib

import numpy as np

from mr_damper_model.models.base import ModelError, segment_starts

COLUMNS = ('t', 'x', 'v', 'f', 'i')
#: File name endings of DAQ CSV files (plain, gzip-compressed).
CSV_SUFFIXES = ('.csv', '.csv.gz')
_GZIP_MAGIC = b'\x1f\x8b'


class DataError(ValueError):
    """A measurement record or file is unusable; the message is one line naming the problem."""


def _label(name):
    return f'{name}: ' if name else ''


@dataclass(frozen=True)
class DamperData:
    """
    One damper test record: equal-length 1-D float arrays ``t, x, v, f, i`` (SI units).

    Parameters
    ----------
    t : array_like with shape (n,)
        Sample time [s].
    x : array_like with shape (n,)
        Piston displacement [m].
    v : array_like with shape (n,)
        Piston velocity [m/s].
    f : array_like with shape (n,)
        Damper force [N].
    i : array_like with shape (n,)
        Coil current [A].
    source : str, optional
        Where the record came from (file name), used in error messages.
    starts : array_like of int, optional
        Segments: sorted sample indices where an independent test begins (0 is always one;
        default: just 0). A record joined from several tests (:meth:`concatenate`) has one per
        part; stateful models (Bouc-Wen, Spencer) restart from rest at each and need ``t``
        increasing only within a segment. Memoryless models ignore them.

    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    f: np.ndarray
    i: np.ndarray
    source: str = ''
    starts: np.ndarray = None

    def __post_init__(self):
        arrays = {}
        for name in COLUMNS:
            a = np.atleast_1d(np.asarray(getattr(self, name), dtype=float))
            if a.ndim != 1:
                raise DataError(f'{_label(self.source)}column `{name}` must be 1-D, '
                                f'got shape {a.shape}')
            arrays[name] = a
        n = {len(a) for a in arrays.values()}
        if len(n) != 1:
            lengths = ', '.join(f'{k}={len(a)}' for k, a in arrays.items())
            raise DataError(f'{_label(self.source)}columns have different lengths ({lengths})')
        for name, a in arrays.items():
            object.__setattr__(self, name, a)
        object.__setattr__(self, 'starts', self._check_starts(self.starts, n.pop()))

    def _check_starts(self, starts, n):
        try:
            return segment_starts(starts, n)
        except ModelError as exc:
            raise DataError(f'{_label(self.source)}{exc}') from None

    @property
    def n(self):
        """Number of samples."""
        return len(self.t)

    @property
    def duration(self):
        """Time spanned by the record [s] (0 for fewer than two samples)."""
        return float(self.t[-1] - self.t[0]) if self.n > 1 else 0.0

    @property
    def sample_rate_hz(self):
        """Sample rate from the median sample interval [Hz] (nan for fewer than two samples)."""
        if self.n < 2:
            return math.nan
        dt = float(np.median(np.diff(self.t)))
        return 1.0 / dt if dt > 0 else math.nan

    @property
    def n_segments(self):
        """Number of independent segments (tests) in the record."""
        return len(self.starts)

    def segments(self):
        """Return the segments as records of their own, in order (each with starts [0])."""
        edges = np.append(self.starts, self.n)
        return [self.select(slice(a, b)) for a, b in zip(edges[:-1], edges[1:])]

    def select(self, index, *, split_gaps=False):
        """
        Return the samples picked by a boolean mask, an index array or a slice.

        Segment starts follow the samples: a picked sample begins a segment if it is the first,
        if it lies in another segment than the sample picked before it, or if it comes before
        that sample in the record (a reordering index).

        Parameters
        ----------
        index : slice, array_like of bool with shape (n,) or array_like of int
            Samples to keep.
        split_gaps : bool
            Also begin a segment wherever picked samples are not neighbours in the record
            (a gap: the samples left out lie between them). A stepping slice never splits.

        """
        orig = np.arange(self.n)[index]
        out = DamperData(self.t[index], self.x[index], self.v[index], self.f[index],
                         self.i[index], source=self.source)
        if orig.size > 1 and (self.starts.size > 1 or split_gaps
                              or not isinstance(index, slice)):
            seg = np.searchsorted(self.starts, orig, side='right')
            step = np.diff(orig)
            new = (np.diff(seg) != 0) | (step <= 0)
            if split_gaps and not isinstance(index, slice):
                new |= step > 1
            if new.any():
                object.__setattr__(out, 'starts',
                                   np.concatenate([[0], np.flatnonzero(new) + 1]).astype(np.int64))
        return out

    def current_levels(self, tol_a=0.05):
        """
        Return the distinct coil-current levels of the record [A].

        Currents are sorted and split wherever two neighbouring values differ by more than
        ``tol_a``; each cluster's median is its level.
        """
        return [level for level, _ in self._clusters(tol_a)]

    def split_by_current(self, tol_a=0.05):
        """
        Split the record into one record per coil-current level.

        Parameters
        ----------
        tol_a : float
            Currents closer than this [A] belong to the same level.

        Returns
        -------
        list of (float, DamperData)
            ``(level_a, record)`` sorted by level; each record keeps its samples in time order.
            Every run of a level (the record was at another level between two runs) begins a
            segment, as do the segment starts of this record.

        """
        return [(level, self.select(mask, split_gaps=True))
                for level, mask in self._clusters(tol_a)]

    def _clusters(self, tol_a):
        if self.n == 0:
            return []
        order = np.argsort(self.i, kind='stable')
        sorted_i = self.i[order]
        breaks = np.flatnonzero(np.diff(sorted_i) > tol_a) + 1
        out = []
        for members in np.split(order, breaks):
            mask = np.zeros(self.n, dtype=bool)
            mask[members] = True
            out.append((float(np.median(self.i[members])), mask))
        return out

    @classmethod
    def concatenate(cls, parts, *, restamp=False, release=False):
        """
        Join records end to end.

        Parameters
        ----------
        parts : sequence of DamperData
            Records to join, in order.
        restamp : bool
            If True, rewrite the time stamps so the result has a continuous, increasing time
            base (each segment of each part keeps its own sample intervals).
        release : bool
            If True (``parts`` must be a list), each entry of ``parts`` is set to None once it
            is copied, so a part nothing else refers to is freed before the next is copied:
            joining long records then takes about one copy of the data plus one record, not
            two copies (``mr-damper-identify FILE...``).

        Returns
        -------
        DamperData
            Every part's first sample begins a segment (``starts``), as do the parts' own
            segment starts: models with internal state (Bouc-Wen, Spencer) restart from rest at
            each, so the joined record is a valid data set for them too (with or without
            ``restamp``); algebraic models (Kwok, Bingham) ignore the segments. Empty parts
            add nothing.

        """
        src = parts if release else list(parts)
        if not src:
            raise DataError('nothing to concatenate')
        if release and not isinstance(src, list):
            raise TypeError('`release` needs `parts` as a list')
        n = sum(p.n for p in src)
        out = {c: np.empty(n) for c in COLUMNS}       # pages are touched as they are filled
        starts = []
        source = src[0].source
        offset = None
        a = 0
        for k in range(len(src)):
            p = src[k]
            if release:
                src[k] = None
            b = a + p.n
            if p.n:
                starts.append(p.starts + a)
            for c in COLUMNS[1:]:
                out[c][a:b] = getattr(p, c)
            t_out = out['t'][a:b]
            t_out[:] = p.t
            if restamp:
                for s0, s1 in zip(p.starts, np.append(p.starts[1:], p.n)):
                    t = t_out[s0:s1]
                    if t.size:
                        dt = float(np.median(np.diff(t))) if t.size > 1 else 1e-3
                        start = 0.0 if offset is None else offset + dt
                        t -= t[0]
                        t += start
                        offset = float(t[-1])
            a = b
            del p
        return cls(*(out[c] for c in COLUMNS), source=source,
                   starts=np.concatenate(starts) if starts else None)


def derive_velocity(t, x):
    """
    Derive piston velocity [m/s] from displacement samples.

    Uniformly sampled records (sample intervals within 1 % of their median) use a cubic
    Savitzky-Golay derivative over about 20 ms (at least 5 samples), which suppresses the
    displacement sensor's quantisation noise the way the shared Quiroz files were prepared;
    otherwise a second-order central difference on the sample times (``numpy.gradient``).
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if len(t) < 3:
        raise DataError('too few samples to derive velocity from displacement')
    dt = np.diff(t)
    med = float(np.median(dt))
    if med > 0 and np.all(np.abs(dt - med) <= 0.01 * med):
        from scipy.signal import savgol_filter
        window = max(5, int(round(0.02 / med)) | 1)
        if window > len(x):
            window = len(x) if len(x) % 2 else len(x) - 1
        if window >= 5:
            return savgol_filter(x, window, 3, deriv=1, delta=med, mode='interp')
    return np.gradient(x, t)


def is_csv(path):
    """Tell whether ``path`` names a DAQ CSV file by its ending (``.csv`` or ``.csv.gz``)."""
    return str(path).lower().endswith(CSV_SUFFIXES)


def _open_text(path):
    """Open a CSV for reading as text, decompressing it when it starts like a gzip file."""
    with open(path, 'rb') as fh:
        gz = fh.read(2) == _GZIP_MAGIC
    # utf-8-sig: a spreadsheet's "CSV UTF-8" starts with a byte-order mark
    if gz:
        return gzip.open(path, 'rt', newline='', encoding='utf-8-sig')
    return open(path, newline='', encoding='utf-8-sig')


def read_csv(path):
    """
    Read a DAQ CSV file with header ``t,x,v,f,i`` into a :class:`DamperData`.

    Parameters
    ----------
    path : str or Path
        CSV file; columns in any order, extra columns ignored, ``v`` may be empty. A gzip
        compressed file (``.csv.gz``; recognised by its first bytes) is decompressed while read.

    Returns
    -------
    DamperData

    Raises
    ------
    DataError
        Unreadable file, truncated or corrupt gzip stream, missing column, truncated or
        non-numeric row, NaN/inf values. Use :func:`validate` for the checks that need the
        whole record (time order, motion).

    """
    path = Path(path)
    name = str(path)
    try:
        with _open_text(path) as fh:
            values, v_empty, first_line = _parse_rows(csv.reader(fh), name)
    except (EOFError, gzip.BadGzipFile, zlib.error) as exc:
        raise DataError(f'{name}: truncated or corrupt gzip file ({exc})') from None
    except OSError as exc:
        raise DataError(f'{name}: cannot read file ({exc.strerror or exc})') from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f'{name}: not a text CSV file ({exc})') from None
    for k, c in enumerate(COLUMNS):
        bad = ~np.isfinite(values[:, k])
        if c == 'v':
            bad &= ~v_empty
        if bad.any():
            line = int(np.flatnonzero(bad)[0]) + first_line
            raise DataError(f'{name}: column {c} has {int(bad.sum())} NaN/inf value(s), '
                            f'first at line {line}')
    t, x, v, f, i = values.T
    if v_empty.all():
        if np.any(np.diff(t) <= 0):
            raise DataError(f'{name}: time is not strictly increasing, cannot derive v from x')
        v = derive_velocity(t, x)
    elif v_empty.any():
        line = int(np.flatnonzero(v_empty)[0]) + first_line
        raise DataError(f'{name}: column v is empty on some rows only (first at line {line}); '
                        'leave it empty everywhere to derive it from x')
    return DamperData(t, x, v, f, i, source=name)


#: Rows parsed into one block of :func:`_parse_rows` (bounded memory for any file size).
_CSV_BLOCK_ROWS = 65536


def _parse_rows(rows, name):
    """
    Parse the header and the numeric rows of a ``t,x,v,f,i`` CSV as they are read.

    Values go into float blocks of ``_CSV_BLOCK_ROWS`` rows, moved into the final array at the
    end one block at a time, each freed once copied: the peak memory is about the final arrays
    plus one block, whatever the file size (joining all blocks at once took twice the arrays; a
    list of the file's rows as strings about 8x the file). Trailing blank lines are ignored.

    Returns
    -------
    values : ndarray with shape (n, 5)
        Columns in the order of ``COLUMNS`` (NaN where ``v`` is empty).
    v_empty : ndarray of bool with shape (n,)
    first_line : int
        Line number of the first data row.

    """
    header_row = None
    line = 0
    for row in rows:
        line += 1
        if any(cell.strip() for cell in row):
            header_row = row
            break
    if header_row is None:
        raise DataError(f'{name}: file is empty (expected header t,x,v,f,i)')
    header = [h.strip().lower() for h in header_row]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise DataError(f"{name}: missing column(s) {', '.join(missing)} "
                        f"(header is '{','.join(header_row)}', expected t,x,v,f,i)")
    cols = [header.index(c) for c in COLUMNS]
    iv = COLUMNS.index('v')
    n_fields = len(header)
    blocks, empties = [], []
    block = np.empty((_CSV_BLOCK_ROWS, len(COLUMNS)))
    empty = np.zeros(_CSV_BLOCK_ROWS, dtype=bool)
    k = 0
    blank_line = 0          # first of a run of blank lines (an error unless trailing)
    first_line = line + 1   # of the data rows (for the NaN check's line numbers)
    for row in rows:
        line += 1
        if not any(cell.strip() for cell in row):
            blank_line = blank_line or line
            continue
        if blank_line:
            raise DataError(f'{name}: line {blank_line} has 0 fields, expected {n_fields} '
                            '(truncated file?)')
        if len(row) < n_fields:
            raise DataError(f'{name}: line {line} has {len(row)} fields, expected '
                            f'{n_fields} (truncated file?)')
        out = block[k]
        for j, c in enumerate(cols):
            cell = row[c].strip()
            if cell == '' and j == iv:
                empty[k] = True
                out[j] = math.nan
                continue
            try:
                out[j] = float(cell)
            except ValueError:
                raise DataError(f"{name}: line {line} column {COLUMNS[j]}: '{cell}' is not a "
                                'number') from None
        k += 1
        if k == _CSV_BLOCK_ROWS:
            blocks.append(block)
            empties.append(empty)
            block = np.empty((_CSV_BLOCK_ROWS, len(COLUMNS)))
            empty = np.zeros(_CSV_BLOCK_ROWS, dtype=bool)
            k = 0
    blocks.append(block[:k])
    empties.append(empty[:k])
    if sum(len(b) for b in blocks) == 0:
        raise DataError(f'{name}: no data rows after the header')
    values = blocks[0] if len(blocks) == 1 else _join_freeing(blocks)
    return values, np.concatenate(empties), first_line


def _join_freeing(blocks):
    """Concatenate 2-D ``blocks`` along rows, emptying the list (each freed once copied)."""
    out = np.empty((sum(len(b) for b in blocks), blocks[0].shape[1]))
    pos = 0
    blocks.reverse()
    while blocks:
        block = blocks.pop()
        out[pos:pos + len(block)] = block
        pos += len(block)
        del block
    return out


def write_csv(path, data):
    """Write a :class:`DamperData` as a ``t,x,v,f,i`` CSV file (SI units; gzip for ``.gz``)."""
    arr = np.column_stack([getattr(data, c) for c in COLUMNS])
    np.savetxt(path, arr, delimiter=',', header=','.join(COLUMNS), comments='', fmt='%.10g')


def check_samples(data, *, min_samples=2, name=''):
    """
    Check the samples of a record are usable at all; return it unchanged.

    Parameters
    ----------
    data : DamperData
        Record to check.
    min_samples : int
        Fewer samples than this is an error.
    name : str
        Label for messages (defaults to ``data.source``).

    Raises
    ------
    DataError
        Too few samples, NaN/inf values, non-increasing time.

    """
    label = _label(name or data.source)
    if data.n < min_samples:
        raise DataError(f'{label}too few samples ({data.n}, need at least {min_samples})')
    for c in COLUMNS:
        bad = ~np.isfinite(getattr(data, c))
        if bad.any():
            raise DataError(f'{label}column {c} has {int(bad.sum())} NaN/inf value(s), '
                            f'first at sample {int(np.flatnonzero(bad)[0])}')
    dt = np.diff(data.t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0]) + 1
        raise DataError(f'{label}time is not strictly increasing at sample {k} '
                        f'(t={data.t[k]:.6f} s after {data.t[k - 1]:.6f} s)')
    return data


def validate(data, *, min_samples=50, min_stroke_m=1e-4, name=''):
    """
    Check that a record can be identified; return it unchanged.

    Parameters
    ----------
    data : DamperData
        Record to check.
    min_samples : int
        Fewer samples than this is an error.
    min_stroke_m : float
        Peak-to-peak displacement below this [m] counts as "no motion".
    name : str
        Label for messages (defaults to ``data.source``).

    Raises
    ------
    DataError
        The errors of :func:`check_samples`, and no motion or constant force.

    """
    check_samples(data, min_samples=min_samples, name=name)
    label = _label(name or data.source)
    stroke = float(np.ptp(data.x))
    if stroke < min_stroke_m or not np.any(data.v != 0):
        raise DataError(f'{label}no motion: displacement spans {stroke * 1e3:.3g} mm '
                        f'(need at least {min_stroke_m * 1e3:.3g} mm)')
    if float(np.ptp(data.f)) == 0.0:
        raise DataError(f'{label}force is constant ({data.f[0]:.6g} N): no damper response')
    return data
