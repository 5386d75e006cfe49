"""
Alias of :mod:`mr_damper_model.models.presets`, where the reference parameter sets live now.

The thesis and rig parameter sets are data of the models, not of the fitting, so they moved to
``models`` (issue 33: ``models`` imports nothing to its right). This name keeps working for one
release; import from ``mr_damper_model.models.presets``.
"""
from mr_damper_model.models.presets import (spencer_thesis_like,  # noqa: F401
                                            THESIS_CAM_AMPLITUDE_M, THESIS_CAM_FREQ_HZ,
                                            THESIS_TABLE_4_3, thesis_kwok_current)
