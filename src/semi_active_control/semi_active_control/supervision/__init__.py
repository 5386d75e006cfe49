"""
Supervision of the control laws: which identified model may be used, and the node's health.

Public API::

    from semi_active_control.supervision import ModelSupervisor, Verdict, SupervisorError
    from semi_active_control.supervision import as_identified_set, clip_current, REASONS
    from semi_active_control.supervision import ControllerHealth, failsafe_message

Modules: ``failsafe`` (the model supervisor: model acceptance, staleness, fail-safe current),
``health`` (the controller node's health rules and the fail-safe messages).
"""
from semi_active_control.supervision.failsafe import (as_identified_set,  # noqa: F401
                                                      clip_current, kwok_current_bounds,
                                                      ModelSupervisor, REASONS,
                                                      SupervisorError, Verdict)
from semi_active_control.supervision.health import (ControllerHealth,  # noqa: F401
                                                    FAILSAFE_MESSAGES, failsafe_message)
