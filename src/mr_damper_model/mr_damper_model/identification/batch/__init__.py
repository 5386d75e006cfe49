"""
Identification at scale: one model per damper of an archive, checked against a master model.

``mr-damper-identify --batch ROOT`` (see docs/batch.md) finds the dampers of an archive
(:func:`discover`), fits one model per damper (:func:`process_damper`, seeded by the damper's id),
computes its force envelope (:func:`force_envelope`), judges it against a master model within
stated tolerances, and writes one row per damper into a CSV table and a JSON summary
(:func:`run_batch`). The dampers run serially in this process or as tasks on a Dask cluster
(a loopback-only ``LocalCluster`` or an existing scheduler); a task gets everything it needs
in its arguments and its seed from the damper's id, so the table does not depend on the
number of workers or on the order in which they finish. A re-run skips the dampers whose row
is already in the table (same files, same settings) unless ``force``.
:func:`trend` reports each parameter and envelope force against the test time of the records
of one serial number (ageing, fluid loss) and :func:`trend_figure` plots it.

Modules: ``settings``, ``envelope`` (the master and the force envelope), ``archive``
(discovery), ``damper`` (one damper, the Dask task), ``table``, ``run`` (serial or Dask,
resume, summary), ``trend``.

No ROS here: the package is imported by the command-line tool and the benchmark only.
"""
from mr_damper_model.identification.batch.settings import (BatchSettings, DEFAULT_ABS_TOL_N,
                                                           DEFAULT_CURRENTS_A,
                                                           DEFAULT_MAX_NRMSE_PERCENT,
                                                           DEFAULT_REL_TOL, DEFAULT_STROKE_M,
                                                           DEFAULT_VELOCITIES_MPS, TABLE_COLUMNS)
from mr_damper_model.identification.batch.envelope import (envelope_columns, envelope_ratio,
                                                           force_envelope, load_master,
                                                           master_currents)
from mr_damper_model.identification.batch.archive import (DamperTask, discover)
from mr_damper_model.identification.batch.damper import (process_damper)
from mr_damper_model.identification.batch.table import (read_table, row_params,
                                                        write_params_files)
from mr_damper_model.identification.batch.run import (process_dampers, run_batch)
from mr_damper_model.identification.batch.trend import (trend, trend_figure, write_trend)

__all__ = ['BatchSettings', 'DamperTask', 'discover', 'process_damper', 'process_dampers',
           'force_envelope', 'envelope_ratio', 'envelope_columns', 'run_batch', 'read_table',
           'row_params', 'write_params_files',
           'trend',
           'write_trend', 'trend_figure', 'load_master', 'master_currents',
           'DEFAULT_VELOCITIES_MPS', 'DEFAULT_CURRENTS_A', 'DEFAULT_STROKE_M', 'DEFAULT_REL_TOL',
           'DEFAULT_ABS_TOL_N', 'DEFAULT_MAX_NRMSE_PERCENT', 'TABLE_COLUMNS']
