"""A window of samples and the parameter set the live identifier fitted on it (no ROS)."""
from dataclasses import dataclass, field
import math

from mr_damper_common.contract import IdentifiedSet
import numpy as np

from mr_damper_model.io.data import DamperData


@dataclass
class Window:
    """
    Samples of one due window (copies), its scheduled end [s] and the samples new to it.

    ``span`` holds the samples from the older of the window start and the first new sample up
    to ``end_s`` (time order); its last ``n_new`` samples are the ones no earlier window handed
    out (more than a window's worth when windows were superseded).  ``index`` is the
    window's position ``m`` in its stream (end ``t0 + window_s + m * hop_s``).
    """

    data: DamperData
    end_s: float
    span: DamperData = None
    n_new: int = 0
    first_new_seq: int = 0
    index: int = 0

    @property
    def new(self):
        """Samples handed out for the first time (the last ``n_new`` of ``span``)."""
        span = self.span if self.span is not None else self.data
        return span.select(slice(span.n - self.n_new, None))


@dataclass
class LiveEstimate:
    """
    One published estimate: kwok-current parameters and what they rest on.

    Attributes
    ----------
    parameters : dict
        The ten kwok-current parameters (SI units).
    valid : bool
        Passed the validity checks.
    reason : str
        Why not valid ('' if valid).
    model_fitted : str
        ``'kwok'`` (one current bin) or ``'kwok-current'``; ``'file'`` for a loaded estimate.
    i_ref_a, window_start_s, window_end_s, current_min_a, current_max_a : float
        Model constant and data coverage (stamps [s], currents [A]).
    rmse_n, nrmse_percent : float
        Fit quality on the fitted data (``nrmse_percent`` as the offline tool reports it:
        RMSE over the full force range).
    robust_nrmse_percent : float
        RMSE over the robust (0.5-99.5 percentile) force range of the fitted data [%]: the
        figure validity is judged on.
    seconds : float
        Compute time of the window [s].
    n_samples : int
        Samples fitted.
    bins_a : list of float
        Current levels of the bins fitted [A].
    result : object
        The :class:`~mr_damper_model.identification.identify.IdentificationResult` (None for a
        loaded one).
    held : str
        '' for a set fitted on its window; for the set in use re-published because the
        window's set was refused by the acceptance review, the reason
        (:mod:`~mr_damper_model.identification.acceptance`).

    """

    parameters: dict
    valid: bool
    reason: str = ''
    model_fitted: str = 'kwok-current'
    i_ref_a: float = 2.0
    window_start_s: float = math.nan
    window_end_s: float = math.nan
    current_min_a: float = math.nan
    current_max_a: float = math.nan
    rmse_n: float = math.nan
    nrmse_percent: float = math.nan
    robust_nrmse_percent: float = math.nan
    seconds: float = 0.0
    n_samples: int = 0
    bins_a: list = field(default_factory=list)
    result: object = None
    held: str = ''

    def identified_set(self):
        """Return the set the ``kwok_parameters`` message carries (an ``IdentifiedSet``)."""
        return IdentifiedSet(self.parameters, i_ref_a=self.i_ref_a,
                             window_start_s=self.window_start_s, window_end_s=self.window_end_s,
                             current_min_a=self.current_min_a,
                             current_max_a=self.current_max_a, rmse_n=self.rmse_n,
                             nrmse_percent=self.nrmse_percent, valid=self.valid,
                             reason=self.reason)

    def params_file_dict(self, source=''):
        """Return the parameter-file dictionary (``params_file.save_params``)."""
        metrics = dict(self.result.metrics) if self.result is not None else {
            'rmse_n': self.rmse_n, 'nrmse_percent': self.nrmse_percent}
        return {'model': 'kwok-current',
                'parameters': {k: float(v) for k, v in self.parameters.items()},
                'model_options': {'i_ref_a': float(self.i_ref_a)},
                'current_min_a': float(self.current_min_a),
                'current_max_a': float(self.current_max_a),
                'metrics': metrics, 'valid': bool(self.valid),
                'seed': None if self.result is None else self.result.seed,
                'source': source or f'identifier window ending at {self.window_end_s:.3f} s'}


def catch_up_parts(clean, end_s, window_s):
    """
    Split a window's screened new samples into consecutive ``window_s`` spans.

    Returns ``[(span_end_s, samples), ...]`` in time order; the last span is the window's
    own (after ``end_s - window_s``), the earlier ones end at ``end_s - j * window_s``.
    Only windows that follow superseded ones carry samples before their own span.  Judging
    those against the reference one span at a time, with a fit after each, bounds the age
    of the reference a sample is judged against by ``window_s`` whatever the fitter's
    delay: the damper's slow memory (e.g. the force shift of a Bouc-Wen damper back at 0 A
    after a 2 A dwell) is then judged against a set fitted on the levels in between, as a
    window of its own would have been, not against a set of the first level only.
    """
    ws = window_s
    lower = end_s - ws + 1e-9                  # the window's own samples: t > lower
    k_own = int(np.searchsorted(clean.t, lower, side='right'))
    parts = [(end_s, clean.select(slice(k_own, None)))]
    if k_own:
        span = np.floor((lower - clean.t[:k_own]) / ws).astype(np.int64) + 1
        for j in range(int(span[0]), 0, -1):   # oldest first (stamps increase)
            part = clean.select(np.flatnonzero(span == j))
            if part.n:
                parts.insert(-1, (end_s - j * ws, part))
    return parts
