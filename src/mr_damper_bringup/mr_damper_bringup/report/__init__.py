"""
Summary and plots of one suite run (``mr-damper-suite``), without ROS.

Inputs, in the run's output folder:

- ``suite.mcap``: the run's one recording (``mr-damper-record``, :mod:`mr_damper_bringup.
  recorder`): every suite topic with its receive time, and on ``/mr_damper/suite_config`` the
  parameter YAML the nodes were started with, and on ``/mr_damper/node_parameters`` the
  parameters each node reported running with (defaults included; :func:`effective_config`
  merges both, so the settings are the nodes' own; the fallback values in this module only
  matter for a recording without them). :func:`read_recording` reads it back in one streamed
  pass (rosbags): measurements into a temporary column log (t, x, v, f, i and the
  receive time), parameter messages into a temporary JSON-lines file, and the bounded rest
  (counters, true parameters, the last status of each node, the last ride metrics);
- ``quarter_car_log.f64/.json``: column log of every control step of the quarter-car node
  (``live_loop.TRACE_COLUMNS``), streamed by the node; its header holds ``dt`` and the final
  status;
- ``process_stats.json`` (optional): CPU and memory of the processes (the launcher).

Memory is bounded for runs of any length: every figure over the whole record is computed in
streamed passes over the files (chunks of 65,536 rows); plots and the offline best fit use at
most a few hundred thousand evenly spaced rows; percentiles of loop timing use at most two
million evenly spaced periods (every period up to ~33 minutes at 1 kHz).

Outputs: ``summary.json`` (keys below) and, with ``plots=True``, ``hysteresis.png`` (measured
force against velocity and displacement per current level, with the final identified model on
the same samples), ``convergence.png`` (parameters and identification error over time) and
``ride.png`` (body acceleration of the live controller and of the passive damper on the same
road, coil current command, fail-safe periods).

``summary.json`` keys: ``duration_s``; ``identification`` {``rmse_n``, ``nrmse_percent`` (final
valid model on every recorded measurement), ``updates``, ``valid_updates``, ``first_valid_s``
(wall seconds from the recorder's start), ``parameters``, ``truth``, ``history``, ...};
``ride`` {``skyhook`` (the live controller, whatever its name), ``passive`` (the safe current on
the same road, seed and plant, simulated offline here), ``passive_0a`` (the softest setting,
best for comfort), same metric keys, ``window_s``};
``failsafe_s``; ``messages_lost`` (total) and ``messages`` (breakdown); ``loop`` (timing);
``control`` (whether and when the run reached control, the same keys for every configuration:
:mod:`mr_damper_bringup.report.control`).

Command line (regenerate from a finished run): ``python -m mr_damper_bringup.report OUT``.

Modules: ``recording`` (the recording read back), ``identification``, ``ride``, ``losses``
(lost messages, restarts, the CAN link), ``control`` (reaching control) and ``summary``
(:func:`make_report`, :func:`format_summary`). ``python -m mr_damper_bringup.report OUT``
remakes the summary of a finished run.
"""
from mr_damper_bringup.report.control import (control_from_recording,  # noqa: F401
                                              control_summary, ControlWatch, format_control)
from mr_damper_bringup.report.identification import (fit_error,  # noqa: F401
                                                     identification_summary,
                                                     measurement_to_parameters,
                                                     offline_best_fit, record_error)
from mr_damper_bringup.report.losses import (attribute_losses, can_summary,  # noqa: F401
                                             messages_summary, restart_figures, restart_lines)
from mr_damper_bringup.report.recording import (CHUNK_ROWS, MEAS_COLUMNS,  # noqa: F401
                                                ParamsLog, read_recording, RECORDING,
                                                recording_state)
from mr_damper_bringup.report.ride import (loop_figures, passive_reference,  # noqa: F401
                                           ride_summary)
from mr_damper_bringup.report.summary import (effective_config, format_summary,  # noqa: F401
                                              main, make_report)
