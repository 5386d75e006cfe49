"""
mr_damper_model: MR damper models, their identification and the live identifier.

Sub-packages by role, each with a short public API in its ``__init__``:

- :mod:`mr_damper_model.models`: the force laws (Kwok, current-dependent Kwok and its lag and
  amplitude variants, Bingham, Bouc-Wen, Spencer), plants for simulation, the inverse model;
- :mod:`mr_damper_model.identification`: particle swarm, separable least squares, fit metrics,
  acceptance of a new live set, batch identification of an archive;
- :mod:`mr_damper_model.io`: DAQ CSV files, bags, MCAP, column logs, parameter files;
- :mod:`mr_damper_model.live`: the sliding-window identifier and its runtime (no ROS);
- :mod:`mr_damper_model.nodes`: the identifier node;
- :mod:`mr_damper_model.tools`: ``mr-damper-identify`` and plots.

What every node shares (node helpers, message conversions, health, command limits, stamps) is
in the ``mr_damper_common`` package.
"""
