"""
Names on the wire that the cores share with the message conversions (no ROS import).

- :data:`PISTON_JOINT`, :data:`COIL_JOINT`: the joint names of a measurement in a
  ``sensor_msgs/JointState`` (topics and bags): the piston carries x, v and the force, the coil
  carries the current (as its effort);
- :data:`KWOK_CURRENT_NAMES`: the ten parameters of the current-dependent Kwok model in the
  order ``mr_damper_interfaces/KwokParameters`` and the model
  (:class:`mr_damper_model.models.kwok_current.KwokCurrent`) use them.
"""
PISTON_JOINT = 'mr_damper_piston'
COIL_JOINT = 'mr_damper_coil'
KWOK_CURRENT_NAMES = ('c0', 'c1', 'k', 'alpha0', 'alpha1', 'alpha2', 'beta0', 'beta1', 'delta',
                      'f0')
