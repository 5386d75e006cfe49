"""Finding the dampers of an archive: one per folder, or per file by serial pattern."""
from dataclasses import dataclass
import datetime
import hashlib
from pathlib import Path
import re

from mr_damper_model.identification.batch.settings import RECORD_SUFFIXES
from mr_damper_model.io.bag_io import is_bag


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
