"""
ROS 2 message conversions of the MR damper suite (the only model module that imports msgs).

Topic payloads (see the README topic table):

- measurement: ``mr_damper_interfaces/DamperSamples``, a batch of consecutive DAQ samples
  (arrays ``t_offset_s, x_m, v_m_s, f_n, i_a`` from ``header.stamp``, with a message
  ``sequence`` and the stream index ``first_index`` of its first sample, so a reader counts lost
  samples exactly): :func:`samples_to_msg`, :func:`samples_from_msg`.
- single-sample measurement (the layout of earlier recordings and of DAQ drivers that publish
  one message per sample): ``sensor_msgs/JointState``; ``header.stamp`` is the sample time,
  joints ``('mr_damper_piston', 'mr_damper_coil')``; piston position = displacement [m],
  velocity [m/s], effort = damper force [N]; coil effort = coil current [A], coil position and
  velocity NaN. :func:`measurement_arrays` reads either kind into arrays.
- parameters: ``mr_damper_interfaces/KwokParameters`` (one field per coefficient, window times,
  current range, fit quality, ``valid`` and ``reason``), typed as
  :class:`mr_damper_common.contract.IdentifiedSet`: :func:`kwok_parameters_msg`,
  :func:`identified_set_from_msg`.
- true damper of a simulation: ``mr_damper_interfaces/DamperModel`` (named parameters) or
  ``KwokParameters`` for a kwok-current truth.
- a corner's state: ``mr_damper_interfaces/QuarterCarState`` (the fields of
  :class:`mr_damper_common.contract.CornerState`, the current command and the commander's mode):
  :func:`corner_state_to_msg`, :func:`corner_state_from_msg`.
- road preview: ``mr_damper_interfaces/RoadPreview`` (a look-ahead sensor's frame: heights per
  track at distances ahead of the front axle, stamp, speed signal, validity):
  :func:`road_preview_msg`, :func:`road_preview_fields`.
- health: ``diagnostic_msgs/DiagnosticArray`` on ``/diagnostics`` (levels and flat key-values,
  see :mod:`mr_damper_common.health`).

One module per family: :mod:`.measurement`, :mod:`.model`, :mod:`.vehicle`,
:mod:`.diagnostics`, and :mod:`.header` (stamps and :class:`MessageError`); every public name
is exported here, so ``from mr_damper_common.messages import ...`` reaches all of them.
These modules import message types but not rclpy, so they work in any process.
"""
from mr_damper_common.messages.header import (MessageError, seconds_to_stamp, stamp_to_seconds)
from mr_damper_common.messages.measurement import (measurement_arrays, measurement_from_msg,
                                                   MEASUREMENT_JOINTS, measurement_to_msg,
                                                   samples_from_msg, samples_to_msg)
from mr_damper_common.messages.model import (damper_model_from_msg, damper_model_msg,
                                             identified_set_from_msg, kwok_parameters_msg)
from mr_damper_common.messages.vehicle import (chassis_sensors_msg, corner_state_from_msg,
                                               corner_state_to_msg, full_car_command_fields,
                                               full_car_command_msg, full_car_state_fields,
                                               full_car_state_msg, road_preview_fields,
                                               road_preview_msg)
from mr_damper_common.messages.diagnostics import (diagnostic_array_msg, diagnostic_status_msg,
                                                   health_from_diagnostic)

__all__ = ['MessageError', 'stamp_to_seconds', 'seconds_to_stamp', 'measurement_to_msg',
           'measurement_from_msg', 'samples_to_msg', 'samples_from_msg', 'measurement_arrays',
           'MEASUREMENT_JOINTS', 'kwok_parameters_msg', 'identified_set_from_msg',
           'damper_model_msg', 'damper_model_from_msg', 'corner_state_to_msg',
           'corner_state_from_msg', 'chassis_sensors_msg', 'full_car_state_msg',
           'full_car_state_fields', 'full_car_command_msg', 'full_car_command_fields',
           'road_preview_msg', 'road_preview_fields', 'diagnostic_status_msg',
           'diagnostic_array_msg', 'health_from_diagnostic']
