"""
Deprecated: moved to :mod:`mr_damper_common.recording.batch_index` (issue 33).

This path goes in the next release.

Importing it warns (``DeprecationWarning``) and re-exports every name of the new module.
"""
import warnings

from mr_damper_common.recording import batch_index as _moved

globals().update({k: v for k, v in vars(_moved).items() if not k.startswith('__')})

warnings.warn(f'mr_damper_model.live.sample_stream moved to {_moved.__name__}; import it from it',
              DeprecationWarning, stacklevel=2)
