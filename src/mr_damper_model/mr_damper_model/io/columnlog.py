"""
Deprecated: moved to :mod:`mr_damper_common.recording.columnlog` (issue 33).

This path goes in the next release.

Importing it warns (``DeprecationWarning``) and re-exports every name of the new module.
"""
import warnings

from mr_damper_common.recording import columnlog as _moved

globals().update({k: v for k, v in vars(_moved).items() if not k.startswith('__')})

warnings.warn(f'mr_damper_model.io.columnlog moved to {_moved.__name__}; import it from there',
              DeprecationWarning, stacklevel=2)
