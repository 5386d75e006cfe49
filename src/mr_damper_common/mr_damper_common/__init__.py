"""
mr_damper_common: what every node of the suite shares, and nothing that fits a model.

- :mod:`~mr_damper_common.node_utils`: parameters with descriptions and ranges, QoS profiles,
  ``/diagnostics``, drop counting, the spin loop and ``run_node`` (SIGINT / SIGTERM);
- :mod:`~mr_damper_common.messages`: typed-message conversions (measurement batches, Kwok
  parameters, diagnostics);
- :mod:`~mr_damper_common.contract`: names on the wire the cores share (no ROS);
- :mod:`~mr_damper_common.health`: node health and its key-values;
- :mod:`~mr_damper_common.commands`: coil-current and displacement command limits;
- :mod:`~mr_damper_common.stamps`: stamp sanity (future stamps, clock jumps);
- :mod:`~mr_damper_common.stop_flag`: the stop request set by SIGINT / SIGTERM;
- :mod:`~mr_damper_common.scheduling`: SCHED_FIFO for a thread a library makes (no ROS);
- :mod:`~mr_damper_common.tracking`: a rig's tracking error;
- :mod:`~mr_damper_common.recording`: column logs, MCAP files read to their last complete
  chunk, lost samples of a batched stream (``mcap`` and ``rosbags`` load only when an MCAP file
  is read).

A rig or controller node imports this package and the models it evaluates, never the fitting
stack (numba, rosbags, matplotlib, Dask).
"""
