"""
MR damper models: the force laws, their plants for simulation and the inverse (current for force).

Public API::

    from mr_damper_model.models import get_model, MODEL_NAMES, ModelError, HysteresisModel
    from mr_damper_model.models import KwokCurrent, kwok_current_force, KwokCurrentInverse
    from mr_damper_model.models import make_plant, PLANT_NAMES

Modules: ``base`` (the model interface and the registry behind :func:`get_model`), ``kwok``,
``kwok_current``, ``kwok_current_lag``, ``kwok_current_amp``, ``bingham``, ``bouc_wen``,
``spencer`` (one model family each), ``compiled`` (numba kernels), ``presets`` (parameter sets
of the thesis and the rig), ``plant`` (a damper with state for the simulators), ``inverse`` (the
live inverse model). Names load on first use.
"""
from mr_damper_model.models.base import (cvkz_regressors, cvkz_separable_parts, get_model,
                                         HysteresisModel, MODEL_NAMES, ModelError,
                                         SeparableParts, Signals)

_LAZY = {'KwokCurrent': 'kwok_current', 'kwok_current_force': 'kwok_current',
         'kwok_current_coefficients': 'kwok_current', 'KwokCurrentInverse': 'inverse',
         'KwokCurrentLagInverse': 'inverse', 'inverse_current': 'inverse',
         'make_plant': 'plant', 'PLANT_NAMES': 'plant'}

__all__ = ['cvkz_regressors', 'cvkz_separable_parts', 'get_model', 'HysteresisModel',
           'MODEL_NAMES', 'ModelError', 'SeparableParts', 'Signals', *_LAZY]


def __getattr__(name):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f'{__name__}.{_LAZY[name]}'), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
