"""Supervision on a vehicle: the corners' models, control-cycle deadlines (no ROS)."""
from semi_active_control.supervision.corner_models import (CornerModels, FILE_TIMEOUT_S,
                                                           load_model_file)
from semi_active_control.supervision.deadline import DeadlineMonitor, REASONS

__all__ = ['CornerModels', 'FILE_TIMEOUT_S', 'load_model_file', 'DeadlineMonitor', 'REASONS']
