"""
Recording helpers every part of the suite shares: column logs, MCAP scans, batch continuity.

Public API::

    from mr_damper_common.recording import ColumnWriter, ColumnReader, ArrayLog, open_log
    from mr_damper_common.recording import JsonLines, read_json_lines, McapScan, BatchIndex

Modules: ``columnlog`` (append-only binary column logs of long runs, JSON-lines files),
``mcap_scan`` (MCAP files read up to their last complete chunk; loads ``mcap`` and ``rosbags``
when a file is read), ``batch_index`` (samples lost between measurement batches, counted from
their stream index). Used by the identifier, the rig, the cars and the bring-up's recorder and
reports. Names load on first use, so importing the package loads neither numpy nor rosbags.
"""
_LAZY = {'ColumnWriter': 'columnlog', 'ColumnReader': 'columnlog', 'ArrayLog': 'columnlog',
         'open_log': 'columnlog', 'JsonLines': 'columnlog', 'read_json_lines': 'columnlog',
         'McapScan': 'mcap_scan', 'BatchIndex': 'batch_index'}

__all__ = list(_LAZY)


def __getattr__(name):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f'{__name__}.{_LAZY[name]}'), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
