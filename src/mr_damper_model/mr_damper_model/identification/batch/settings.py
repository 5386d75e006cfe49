"""Settings of a batch identification and the names of its table columns."""
from dataclasses import asdict, dataclass, field
import hashlib
import json
import math


#: Envelope defaults: peak piston velocities [m/s] of the reference sine strokes ...
DEFAULT_VELOCITIES_MPS = (0.025, 0.05, 0.1)


#: ... coil currents [A] when there is no master with a current range ...
DEFAULT_CURRENTS_A = (0.0, 1.0)


#: ... and the stroke amplitude [m] of the reference sine.
DEFAULT_STROKE_M = 0.01


#: Envelope tolerance: a point passes if abs(F - F_master) <= max(rel * abs(F_master), abs).
DEFAULT_REL_TOL = 0.10


DEFAULT_ABS_TOL_N = 20.0


#: A fit worse than this NRMSE [%] is not trusted: the damper fails ("fit").
DEFAULT_MAX_NRMSE_PERCENT = 10.0


#: Reference sine of the envelope: cycles simulated (the last one is measured), samples each.
ENVELOPE_CYCLES = 3


ENVELOPE_SAMPLES_PER_CYCLE = 400


#: Columns every row has, in this order; then the metrics, parameters (``p_<name>``) and
#: envelope forces (``env_...``).
TABLE_COLUMNS = ('record', 'serial', 'test_time', 'status', 'reason', 'error', 'files',
                 'samples', 'current_min_a', 'current_max_a', 'model', 'method', 'seed',
                 'envelope_worst_ratio', 'fingerprint', 'config')


METRIC_COLUMNS = ('rmse_n', 'nrmse_percent', 'mean_abs_error_n', 'mean_percent_error',
                  'max_percent_error')


RECORD_SUFFIXES = ('.csv', '.mcap', '.db3')


#: Seconds to wait for an existing Dask scheduler (``scheduler``) to answer.
SCHEDULER_TIMEOUT_S = 30


#: Dampers go to the cluster in about this many tasks per worker (a task costs the scheduler,
#: the worker and the client some milliseconds of CPU each; a damper of a short end-of-line
#: test takes tens of milliseconds to fit).
CHUNKS_PER_WORKER = 8


#: Default model for records at several current levels (as the single-record tool).
MULTI_CURRENT_MODEL = 'kwok-current-amp'


def _one_line(text):
    return ' '.join(str(text).split())


@dataclass(frozen=True)
class BatchSettings:
    """
    Everything a damper task needs besides its files (picklable, sent to the workers).

    Attributes
    ----------
    model : str or None
        Model fitted to every damper; None: the master's model, else ``kwok-current-amp`` for
        records at several current levels and ``kwok`` otherwise.
    method, unbounded, topic
        As ``mr-damper-identify`` (``--method``, ``--unbounded``, ``--topic``).
    seed : int
        Base seed; each damper's swarm seed is derived from it and the damper's id.
    master : dict or None
        ``{'model', 'parameters', 'model_options', 'source'}`` of the master model.
    velocities_mps, currents_a : tuple of float
        Envelope points: peak piston velocity [m/s] of the reference sine and coil current [A].
    stroke_m : float
        Amplitude of the reference sine [m].
    rel_tol, abs_tol_n : float
        Envelope tolerance: abs(F - F_master) <= max(rel_tol * abs(F_master), abs_tol_n).
    max_nrmse_percent : float
        Fits with a larger NRMSE fail.
    param_ranges : tuple of (name, lo, hi)
        Parameter ranges a passing damper's parameters must lie in.

    """

    model: object = None
    method: str = 'separable'
    unbounded: bool = False
    topic: object = None
    seed: int = 1
    master: object = None
    velocities_mps: tuple = DEFAULT_VELOCITIES_MPS
    currents_a: tuple = DEFAULT_CURRENTS_A
    stroke_m: float = DEFAULT_STROKE_M
    rel_tol: float = DEFAULT_REL_TOL
    abs_tol_n: float = DEFAULT_ABS_TOL_N
    max_nrmse_percent: float = DEFAULT_MAX_NRMSE_PERCENT
    param_ranges: tuple = ()
    master_envelope: tuple = field(default=None, compare=False)

    def __post_init__(self):
        for name in ('velocities_mps', 'currents_a'):
            vals = tuple(float(v) for v in getattr(self, name))
            if not vals or not all(math.isfinite(v) for v in vals):
                raise ValueError(f'`{name}` must be a non-empty list of finite numbers.')
            object.__setattr__(self, name, vals)
        if any(v <= 0 for v in self.velocities_mps):
            raise ValueError('`velocities_mps` must be positive.')
        for name in ('stroke_m', 'abs_tol_n', 'max_nrmse_percent'):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f'`{name}` must be a positive number, got {v}.')
        if not (math.isfinite(self.rel_tol) and self.rel_tol >= 0):
            raise ValueError(f'`rel_tol` must be >= 0, got {self.rel_tol}.')
        ranges = tuple((str(n), float(lo), float(hi)) for n, lo, hi in self.param_ranges)
        for n, lo, hi in ranges:
            if not lo <= hi:
                raise ValueError(f'parameter range of {n}: {lo} > {hi}')
        object.__setattr__(self, 'param_ranges', ranges)
        if self.master is not None and self.master_envelope is None:
            from mr_damper_model.identification.batch.envelope import force_envelope
            env = force_envelope(self.master['model'], self.master.get('model_options'),
                                 self.master['parameters'], self.currents_a,
                                 self.velocities_mps, self.stroke_m)
            object.__setattr__(self, 'master_envelope', tuple(map(tuple, env.tolist())))

    @property
    def judged(self):
        """True if the dampers get a pass / fail (a master or parameter ranges given)."""
        return self.master is not None or bool(self.param_ranges)

    def config_hash(self):
        """Return a short hash of the settings that change a row (other settings: redone)."""
        d = asdict(self)
        d.pop('master_envelope')
        if d['master'] is not None:         # the master's content, not where it was read from
            d['master'] = {k: d['master'].get(k) for k in ('model', 'parameters',
                                                           'model_options')}
        text = json.dumps(d, sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()[:16]
