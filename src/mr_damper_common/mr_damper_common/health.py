"""
Health of a node as a level, a one-line message and flat key-values (ROS-free).

The nodes publish this on ``/diagnostics`` (``diagnostic_msgs/DiagnosticStatus``, converted in
:mod:`mr_damper_common.messages`); this module holds the levels, the flattening of nested status
dicts into text key-values and back, so the conversion is testable without ROS.

Levels are those of ``diagnostic_msgs/DiagnosticStatus``: ``OK`` (0), ``WARN`` (1), ``ERROR``
(2), ``STALE`` (3).

Key-values: nested dicts become dotted keys (``windows_skipped.gap``); values are JSON text
(``12000``, ``0.83``, ``true``, ``null``, ``[0.0, 2.0]``) except strings, which stay as they
are, and non-finite floats, which are written ``nan``, ``inf`` and ``-inf``.
"""
from dataclasses import dataclass, field
import json
import math

import numpy as np


OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR', STALE: 'STALE'}

_NON_FINITE = {'nan': math.nan, 'inf': math.inf, '-inf': -math.inf}


def finite_or_none(value):
    """
    Return ``value`` as plain JSON values: non-finite floats become None (the one sanitiser).

    dicts (keys as str), lists and tuples are walked; numpy scalars become Python ones;
    None and str stay; anything else becomes its ``str``.
    """
    if isinstance(value, dict):
        return {str(k): finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return str(value)


@dataclass
class Health:
    """
    One node's health: level, message and status values.

    Attributes
    ----------
    level : int
        :data:`OK`, :data:`WARN`, :data:`ERROR` or :data:`STALE`.
    message : str
        One line for a human: what is wrong (or ``'ok'``) and why.
    values : dict
        Status values (nested dicts allowed), published as key-values.

    """

    level: int = OK
    message: str = 'ok'
    values: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.level not in LEVEL_NAMES:
            raise ValueError(f'`level` must be one of {sorted(LEVEL_NAMES)}, got {self.level!r}')


def worst(problems, values=None):
    """
    Combine ``(level, message)`` findings into one :class:`Health`.

    Parameters
    ----------
    problems : iterable of (int, str)
        Findings; those at ``OK`` are ignored.
    values : dict, optional
        Status values of the result.

    Returns
    -------
    Health
        The highest level; the message joins the findings at that level with ``'; '``
        (``'ok'`` when there are none).

    """
    problems = [(int(level), str(msg)) for level, msg in problems if level != OK]
    if not problems:
        return Health(OK, 'ok', dict(values or {}))
    top = max(level for level, _ in problems)
    return Health(top, '; '.join(msg for level, msg in problems if level == top),
                  dict(values or {}))


class Rising:
    """Counters seen at the previous check: how much each rose since (status rules)."""

    def __init__(self):
        self._last = {}

    def rise(self, key, value):
        """Return how much counter ``key`` rose since the last call (0 if it fell: a restart)."""
        value = int(value or 0)
        before = self._last.get(key, 0)
        self._last[key] = value
        return max(value - before, 0)


def dropped_since(rising, dropped, label='dropped since the last check'):
    """
    Return the WARN finding of the drop counts that rose since the last check, or None.

    Parameters
    ----------
    rising : Rising
        The rule's counter memory.
    dropped : dict or None
        ``{reason: count}`` of a node's :class:`~mr_damper_common.node_utils.DropCounter`.
    label : str
        Start of the message.

    """
    n = {reason: rising.rise(f'dropped.{reason}', count)
         for reason, count in sorted((dropped or {}).items())}
    n = {k: v for k, v in n.items() if v}
    if not n:
        return None
    return (WARN, f'{label}: ' + ', '.join(f'{v} {k}' for k, v in n.items()))


def value_text(value):
    """
    Write one status value as key-value text.

    Parameters
    ----------
    value : object
        bool, int, float, str, None, or a list/tuple of those.

    Returns
    -------
    str
        Strings unchanged, non-finite floats as ``nan``/``inf``/``-inf``, the rest as JSON.

    """
    kind = type(value)          # the plain types first, as JSON writes them (a 1 Hz status of
    if kind is str:             # hundreds of values shares the GIL with a node's hot thread)
        return value
    if kind is int:
        return int.__repr__(value)
    if kind is float:
        return float.__repr__(value) if math.isfinite(value) else non_finite_text(value)
    if kind is bool:
        return 'true' if value else 'false'
    if value is None:
        return 'null'
    if isinstance(value, str):
        return value
    if hasattr(value, 'tolist'):
        value = value.tolist()              # numpy scalars and arrays
    if isinstance(value, float) and not math.isfinite(value):
        return non_finite_text(value)
    return json.dumps(finite_or_none(value))     # nested non-finite values: null


def non_finite_text(value):
    """Return the text of a non-finite float: ``nan``, ``inf`` or ``-inf``."""
    return 'nan' if math.isnan(value) else ('inf' if value > 0 else '-inf')


def text_value(text):
    """
    Read key-value text back (the inverse of :func:`value_text` up to strings).

    Parameters
    ----------
    text : str
        Value text.

    Returns
    -------
    object
        The JSON value, a non-finite float, or the text itself when it is not JSON.

    """
    if text in _NON_FINITE:
        return _NON_FINITE[text]
    try:
        return json.loads(text)
    except ValueError:
        return text


def flatten(values, prefix=''):
    """
    Flatten nested status dicts into ``[(dotted_key, text)]`` (keys sorted per level).

    Parameters
    ----------
    values : dict
        Status values; keys must not contain ``'.'``.
    prefix : str
        Key prefix (used in the recursion).

    Returns
    -------
    list of (str, str)
        Key-values in a stable order.

    """
    out = []
    keys = list(values)
    keys.sort(key=None if all(type(k) is str for k in keys) else str)     # ordered by text
    for key in keys:
        key_s = key if type(key) is str else str(key)
        if '.' in key_s:
            raise ValueError(f'status key {key_s!r} contains a dot')
        value = values[key]
        if isinstance(value, dict):
            out.extend(flatten(value, f'{prefix}{key_s}.'))
        else:
            out.append((f'{prefix}{key_s}', value_text(value)))
    return out


def unflatten(pairs):
    """
    Rebuild nested status values from ``(dotted_key, text)`` pairs.

    Parameters
    ----------
    pairs : iterable of (str, str)
        Key-values as written by :func:`flatten`.

    Returns
    -------
    dict
        Nested dicts of values read by :func:`text_value`.

    """
    out = {}
    for key, text in pairs:
        parts = key.split('.')
        node = out
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ValueError(f'status key {key!r} nests under a value')
        node[parts[-1]] = text_value(text)
    return out
