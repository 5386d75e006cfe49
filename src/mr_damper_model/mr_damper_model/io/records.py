"""
Rig test records named on a command line: expand files, directories and globs, read each one.

A record is a ``t,x,v,f,i`` CSV (plain or ``.csv.gz``), a rosbag2 directory or a ``.mcap`` /
``.db3`` bag (see :mod:`~mr_damper_model.io.bag_io`). Users: ``mr-damper-identify`` (its FILE
arguments) and the batch identification (the files of one damper).
"""
import glob
from pathlib import Path
import sys

from mr_damper_model.io.bag_io import is_bag, read_bag
from mr_damper_model.io.data import read_csv, validate

#: File suffixes of records inside a directory (a rosbag2 directory counts as well).
RECORD_SUFFIXES = ('.csv', '.csv.gz', '.mcap', '.db3')


class InputError(ValueError):
    """An input argument names nothing readable: ``(argument, problem)``."""


def _directory_records(path):
    return sorted(str(c) for c in path.iterdir()
                  if (c.is_dir() and is_bag(c))
                  or (c.is_file() and c.name.lower().endswith(RECORD_SUFFIXES)))


def expand_inputs(args):
    """
    Expand FILE arguments into the list of records to read.

    Parameters
    ----------
    args : sequence of str
        CSV files, bags (rosbag2 directory, ``.mcap``, ``.db3``), directories and globs.

    Returns
    -------
    list of str
        Record paths in argument order; a directory and a glob give their matches sorted by
        name; a path named twice is kept once.

    Raises
    ------
    InputError
        A glob matching nothing or a directory holding no record.

    """
    out = []
    for arg in args:
        p = Path(arg)
        if not p.exists() and any(ch in arg for ch in '*?['):
            matches = sorted(glob.glob(arg))
            if not matches:
                raise InputError(arg, 'no file matches this pattern')
            found = []
            for m in matches:
                mp = Path(m)
                found.extend(_directory_records(mp) if mp.is_dir() and not is_bag(mp)
                             else [m])
            if not found:
                raise InputError(arg, 'the matching directories hold no .csv(.gz), .mcap or '
                                 '.db3 file or rosbag2 directory')
        elif p.is_dir() and not is_bag(p):
            found = _directory_records(p)
            if not found:
                raise InputError(arg, 'directory holds no .csv(.gz), .mcap or .db3 file or '
                                 'rosbag2 directory')
        else:
            found = [arg]
        out.extend(found)
    seen = set()
    return [n for n in out if not (Path(n).resolve() in seen or seen.add(Path(n).resolve()))]


def _warn_stderr(text):
    print(f'warning: {text}', file=sys.stderr)


def read_record(path, *, topic=None, truncated=None, warn=_warn_stderr):
    """
    Read and check one record for identification (CSV or bag, by its form).

    Parameters
    ----------
    path : str
        CSV file, rosbag2 directory, ``.mcap`` or ``.db3`` bag.
    topic : str, optional
        Measurement topic of a bag (see ``bag_io.read_bag``).
    truncated : list, optional
        A truncated ``.mcap`` file read up to its last complete chunk is appended to it
        (``file``, ``messages``, ``samples``, first and last log time, ``error``).
    warn : callable, optional
        Called with one line (where the file ends, how many samples are used) when a truncated
        ``.mcap`` file is read; by default the line goes to stderr after ``warning:``.

    Returns
    -------
    DamperData

    Raises
    ------
    DataError
        Unreadable or malformed record (the message names the file).

    """
    recovery = {}
    data = read_bag(path, topic, recovery=recovery) if is_bag(path) else read_csv(path)
    if recovery:        # a recording whose writer was killed: say what is used of it
        warn(f'{recovery["note"]}; {data.n} samples used')
        if truncated is not None:
            truncated.append({'file': str(path), 'messages': recovery.get('messages'),
                              'samples': int(data.n),
                              'first_log_time_s': recovery.get('first_log_time_s'),
                              'last_log_time_s': recovery.get('last_log_time_s'),
                              'error': recovery.get('error')})
    return validate(data, name=path)
