"""
Supervision of the control laws: which identified model may be used, deadlines, health.

Public API::

    from semi_active_control.supervision import ModelSupervisor, Verdict, SupervisorError
    from semi_active_control.supervision import as_identified_set, clip_current, REASONS
    from semi_active_control.supervision import COIL_SETTINGS
    from semi_active_control.supervision import ControllerHealth, failsafe_message
    from semi_active_control.supervision import CornerModels, load_model_file, DeadlineMonitor

Modules: ``failsafe`` (the model supervisor: model acceptance, staleness, fail-safe current),
``health`` (the controller node's health rules and the fail-safe messages), ``corner_models``
(each corner's model from its end-of-line file or the live identifier, one supervisor each),
``deadline`` (control-cycle deadline misses and sensor timeouts as fail-safe reasons,
``DEADLINE_REASONS``), ``lifecycle_chain`` (the managed vehicle nodes' order of transitions).
"""
from semi_active_control.supervision.corner_models import (CornerModels,  # noqa: F401
                                                           FILE_TIMEOUT_S, load_model_file)
from semi_active_control.supervision.deadline import DeadlineMonitor  # noqa: F401
from semi_active_control.supervision.deadline import REASONS as DEADLINE_REASONS  # noqa: F401
from semi_active_control.supervision.failsafe import (as_identified_set,  # noqa: F401
                                                      clip_current, COIL_SETTINGS,
                                                      kwok_current_bounds,
                                                      ModelSupervisor, REASONS,
                                                      SupervisorError, Verdict)
from semi_active_control.supervision.health import (ControllerHealth,  # noqa: F401
                                                    FAILSAFE_MESSAGES, failsafe_message)
