"""
Reading and writing records: DAQ CSV files, rosbag2 bags, parameter files.

Public API::

    from mr_damper_model.io import DamperData, DataError, read_csv, write_csv, validate
    from mr_damper_model.io import read_bag, is_bag, load_params, save_params, load_plant
Modules: ``data`` (the record type and CSV files), ``bag_io`` and ``bag_types`` (bags through
rosbags), ``params_file`` (fitted parameter sets as JSON). Names load on first use (a bag
reader pulls in rosbags). Column logs and MCAP scans moved to :mod:`mr_damper_common.recording`
(issue 33); ``columnlog``, ``mcap_scan``, ``ColumnWriter`` and ``ColumnReader`` still load from
here for one release, with a ``DeprecationWarning``.
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
