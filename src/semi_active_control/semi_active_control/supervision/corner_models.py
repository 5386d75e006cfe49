"""
The four corners' damper models of a vehicle: an end-of-line file or a live identifier each.

Each corner's identified Kwok-current model comes from one of two sources:

- a parameter file (``mr-damper-identify --out`` or ``--batch --params-dir``: the damper's
  end-of-line record), read at configure time through ``io.params_file.load_params`` and
  offered once to that corner's supervisor; a file model does not age (its supervisor's
  timeout is :data:`FILE_TIMEOUT_S`), a file that cannot be read or holds another model is
  refused (``undecodable``) and a record marked invalid (a damper that failed its end-of-line
  check) is refused as ``invalid_flag``: that corner stays on its safe current;
- the live identifier of that corner (``<c>/mr_damper/kwok_parameters``): every set is offered
  to the supervisor, which refuses bad ones and drops a model older than ``timeout_s``.

Either way the gatekeeper is the same
:class:`semi_active_control.supervision.failsafe.ModelSupervisor` (one per corner) the controller's
corner cores use; :meth:`CornerModels.force_model` gives the active model's force for the state
estimator's known input.
"""
import math

from semi_active_control.supervision.failsafe import ModelSupervisor
from semi_active_control.car.full_car import CORNERS

#: Model timeout of a corner whose model comes from a file [s]: a record does not age.
FILE_TIMEOUT_S = 1.0e9


def load_model_file(path):
    """
    Read one corner's parameter file as the set its supervisor takes.

    Returns
    -------
    mr_damper_common.contract.IdentifiedSet
        The file's set (ten Kwok-current parameters, ``i_ref_a``, identified current range,
        ``valid``: False for a record marked invalid, which the supervisor refuses as
        ``invalid_flag``).

    Raises
    ------
    ValueError
        Unreadable file, not JSON, another model, missing or non-finite parameters (the
        message names the file).

    """
    from mr_damper_model.io.params_file import load_identified_set
    return load_identified_set(path)


class CornerModels:
    """
    The four corners' model sources and supervisors (see the module docstring).

    Parameters
    ----------
    model_files : sequence of 4 str
        Per corner (``fl, fr, rl, rr``) a parameter file, or '' for the live identifier.
    timeout_s : float
        Model timeout of a live corner [s].
    **supervisor_settings
        Other :class:`~semi_active_control.supervision.failsafe.ModelSupervisor` settings
        (``safe_current_a``, ``i_min_a``, ``i_max_a``, ``min_current_span_a``, ``hold_on_reject``).

    Attributes
    ----------
    supervisors : list of ModelSupervisor
    files : list of str
    load_errors : dict
        Corner -> why its file was refused (configure).

    """

    def __init__(self, model_files=('', '', '', ''), *, timeout_s=1.0, **supervisor_settings):
        files = [str(f or '') for f in model_files]
        if len(files) != len(CORNERS):
            raise ValueError(f'`model_files` needs one entry per corner ({", ".join(CORNERS)}; '
                             f'"" for the live identifier), got {len(files)}')
        self.files = files
        self.supervisors = [ModelSupervisor(timeout_s=FILE_TIMEOUT_S if f else timeout_s,
                                            **supervisor_settings) for f in files]
        self.load_errors = {}
        self._inverse = [None] * len(CORNERS)
        self._inverse_of = [None] * len(CORNERS)

    @staticmethod
    def index(corner):
        """Return the index 0..3 of ``corner`` (index or name)."""
        return CORNERS.index(corner) if isinstance(corner, str) else int(corner)

    def source(self, corner):
        """Return ``'file'`` or ``'live'``."""
        return 'file' if self.files[self.index(corner)] else 'live'

    def load_files(self, t_clock):
        """
        Read every file corner's model and offer it to its supervisor (configure).

        Returns
        -------
        dict
            Corner -> the supervisor's ``Verdict`` (a file that cannot be read is refused as
            ``undecodable``, its reason in :attr:`load_errors`).

        """
        out = {}
        self.load_errors = {}
        for i, path in enumerate(self.files):
            if not path:
                continue
            try:
                values = load_model_file(path)
            except (ValueError, OSError) as exc:
                self.load_errors[CORNERS[i]] = str(exc)
                out[CORNERS[i]] = self.supervisors[i].refuse('undecodable', str(exc), t_clock)
                continue
            out[CORNERS[i]] = self.supervisors[i].offer(values, t_clock)
        return out

    def offer_live(self, corner, values, t_clock):
        """
        Offer a live identifier's set to a live corner (a file corner ignores it: None).

        ``values`` is the decoded set, or the ``ValueError`` its decoder raised: refused with
        the decoder's reason when the supervisor knows it (``bad_i_ref``), else as
        ``undecodable``. Returns the supervisor's ``Verdict``.
        """
        i = self.index(corner)
        if self.files[i]:
            return None
        sup = self.supervisors[i]
        if isinstance(values, ValueError):
            reason = getattr(values, 'reason', None)
            return sup.refuse(reason if reason in sup.rejected else 'undecodable',
                              str(values), t_clock)
        return sup.offer(values, t_clock)

    def update(self, t_clock):
        """Advance every supervisor to ``t_clock`` [s]; return the modes."""
        return [s.update(t_clock) for s in self.supervisors]

    def force_model(self, corner):
        """
        Return the active model of ``corner`` as an object with ``force(i, x, v)``, or None.

        ``force`` is the model's damper force [N] at coil current ``i`` [A], piston
        displacement ``x`` [m] and velocity ``v`` [m/s] (the model's convention: the force on
        the body is its negative).
        """
        i = self.index(corner)
        params = self.supervisors[i].active
        if params is None:
            return None
        if params is not self._inverse_of[i]:
            from mr_damper_model.models.inverse import KwokCurrentInverse
            sup = self.supervisors[i]
            self._inverse[i] = KwokCurrentInverse(params.parameters, i_ref_a=params.i_ref_a,
                                                  i_min=sup.i_min_a, i_max=sup.i_max_a)
            self._inverse_of[i] = params
        return self._inverse[i]

    def status(self, t_clock=None):
        """Return per corner ``source``, ``file``, the supervisor's status and ``param_age_s``."""
        out = {}
        for i, c in enumerate(CORNERS):
            sup = self.supervisors[i]
            st = dict(sup.status(), source=self.source(i), file=self.files[i])
            if c in self.load_errors:
                st['load_error'] = self.load_errors[c]
            if t_clock is not None and self.files[i] == '':
                st['param_age_s'] = sup.age(t_clock)
            elif t_clock is not None:
                st['param_age_s'] = math.nan
            out[c] = st
        return out
