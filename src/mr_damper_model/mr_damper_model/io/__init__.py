"""
Reading and writing records: DAQ CSV files, rosbag2 bags, MCAP files, column logs, parameter files.

Public API::

    from mr_damper_model.io import DamperData, DataError, read_csv, write_csv, validate
    from mr_damper_model.io import read_bag, is_bag, load_params, save_params, load_plant
    from mr_damper_model.io import ColumnWriter, ColumnReader

Modules: ``data`` (the record type and CSV files), ``bag_io`` and ``bag_types`` (bags through
rosbags), ``mcap_scan`` (MCAP files read up to their last complete chunk), ``columnlog``
(append-only binary column logs of long runs), ``params_file`` (fitted parameter sets as JSON).
Names load on first use (a bag reader pulls in rosbags).
"""
_LAZY = {'DamperData': 'data', 'DataError': 'data', 'read_csv': 'data', 'write_csv': 'data',
         'validate': 'data', 'read_bag': 'bag_io', 'is_bag': 'bag_io',
         'load_params': 'params_file', 'save_params': 'params_file',
         'load_plant': 'params_file', 'ColumnWriter': 'columnlog', 'ColumnReader': 'columnlog'}

__all__ = list(_LAZY)


def __getattr__(name):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f'{__name__}.{_LAZY[name]}'), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
