"""
Identification: fitting a model to a record, judging a fit, and fitting many dampers.

Public API::

    from mr_damper_model.identification.identify import identify   # the function
    from mr_damper_model.identification import IdentificationResult, compare_models
    from mr_damper_model.identification import current_groups, fit_metrics
    from mr_damper_model.identification import Acceptance, run_batch, BatchSettings

(``identify`` and ``pso`` are the names of modules of this package: import the functions from
them, ``identification.identify.identify`` and ``identification.pso.pso``.)

Modules: ``pso`` (the particle swarm), ``lsq`` (bounded linear least squares of the separable
parts), ``identify`` (the fitting methods; their costs and solvers in ``separable``),
``metrics`` (fit quality), ``acceptance`` (whether a new live set may replace the one in use),
``presets`` (parameter sets of the thesis and the rig), ``batch`` (one fit per damper of an
archive, on Dask). Names load on first use.
"""
_LAZY = {'IdentificationResult': 'identify',
         'compare_models': 'identify', 'current_groups': 'identify',
         'current_group_levels': 'identify', 'identify_per_current': 'identify',
         'fit_metrics': 'metrics', 'METRIC_KEYS': 'metrics',
         'Acceptance': 'acceptance', 'run_batch': 'batch', 'BatchSettings': 'batch'}

__all__ = list(_LAZY)


def __getattr__(name):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f'{__name__}.{_LAZY[name]}'), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
