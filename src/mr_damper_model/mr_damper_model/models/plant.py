"""
Streaming (sample-by-sample) MR damper plants for the virtual rig and the quarter car.

A plant is advanced with ``step(dt, x, v, i_cmd)``: over ``dt`` [s] the piston moves to
displacement ``x`` [m] with velocity ``v`` [m/s] at the end of the step, and the coil command
``i_cmd`` [A] is held. The command first passes an optional slew-rate limit (the current driver,
``slew_a_per_s`` [A/s]), then the coil's first-order lag; ``current`` is the actual coil current
after both [A]. The first call (or any call with dt = 0) only sets the state and returns the force
at the current state. Everything inside ``step`` is plain Python floats and ``math`` (no numpy)
because it runs in 1 kHz loops.

* ``KwokCurrentPlant``: current-dependent Kwok force; lag time constant ``coil_tau_s``
  (default 1/190 s, Spencer's eta = 190 1/s). Given constant current it equals
  ``KwokCurrent.force`` exactly.
* ``SpencerPlant``: Spencer modified Bouc-Wen; the lag is the model's own u-filter (eta);
  sub-stepped exactly as ``Spencer.force`` (the same formulae), so with the same initial state it
  reproduces the batch model to rounding.
"""
import math

from mr_damper_model.models import ModelError, presets
from mr_damper_model.models.kwok_current import KwokCurrent, kwok_current_force_scalar
from mr_damper_model.models.spencer import (advance_scalar, advance_step_compiled, Spencer,
                                            substeps)

PLANT_NAMES = ('spencer', 'kwok-current')


def _as_params(model, params):
    if isinstance(params, dict):
        vec = model.from_dict(params)
    else:
        vec = model.from_dict(dict(zip(model.param_names, params)))
    return {k: float(val) for k, val in zip(model.param_names, vec)}


def _check_option(value, name, *, positive=False, allow_none=False):
    if value is None and allow_none:
        return None
    value = float(value)
    if not math.isfinite(value) or value < 0 or (positive and value == 0):
        raise ModelError(f'`{name}` must be a {"positive" if positive else "non-negative"} '
                         f'finite number, got {value}')
    return value


class DamperPlant:
    """
    Base class of the streaming plants.

    Attributes
    ----------
    model_name : str
        Name of the batch model the plant implements.
    params : dict
        Parameters {name: value} (SI).
    model_options : dict
        Options of the batch model (e.g. ``i_ref_a``).
    current : float
        Actual coil current [A].

    """

    model_name = ''

    def __init__(self, slew_a_per_s=None, initial_current_a=0.0):
        self.slew_a_per_s = _check_option(slew_a_per_s, 'slew_a_per_s', positive=True,
                                          allow_none=True)
        self.initial_current_a = float(initial_current_a)
        if not math.isfinite(self.initial_current_a):
            raise ModelError('`initial_current_a` must be finite')
        self.reset()

    def reset(self):
        """Return to the initial state (piston unknown, coil at ``initial_current_a``)."""
        self.current = self.initial_current_a
        self._drive = self.initial_current_a
        self._started = False

    def _driver(self, dt, i_cmd):
        """Slew-limited driver output held over the step [A]."""
        if self.slew_a_per_s is None:
            self._drive = i_cmd
        else:
            d = i_cmd - self._drive
            lim = self.slew_a_per_s * dt
            if d > lim:
                d = lim
            elif d < -lim:
                d = -lim
            self._drive += d
        return self._drive

    def step(self, dt, x, v, i_cmd):
        """
        Advance the plant by one step.

        Parameters
        ----------
        dt : float
            Step length [s] (>= 0).
        x : float
            Piston displacement at the end of the step [m].
        v : float
            Piston velocity at the end of the step [m/s].
        i_cmd : float
            Coil current command held over the step [A].

        Returns
        -------
        float
            Damper force at the end of the step [N].

        """
        if not dt >= 0.0:
            raise ModelError(f'`dt` must be >= 0, got {dt}')
        if not (math.isfinite(x) and math.isfinite(v) and math.isfinite(i_cmd)):
            raise ModelError('`x`, `v` and `i_cmd` must be finite')
        return self._step(dt, float(x), float(v), float(i_cmd))

    def _step(self, dt, x, v, i_cmd):
        raise NotImplementedError


class KwokCurrentPlant(DamperPlant):
    """
    Streaming current-dependent Kwok damper.

    Parameters
    ----------
    params : dict or sequence
        KwokCurrent parameters (SI).
    i_ref_a : float
        Reference current of the model [A].
    coil_tau_s : float
        Coil time constant [s] (0: no lag). Default 1/190 s.
    slew_a_per_s : float or None
        Driver slew-rate limit [A/s]; None: unlimited.
    initial_current_a : float
        Coil current after ``reset`` [A].

    """

    model_name = 'kwok-current'

    def __init__(self, params, i_ref_a=2.0, coil_tau_s=1.0 / 190.0, slew_a_per_s=None,
                 initial_current_a=0.0):
        self._model = KwokCurrent(i_ref_a=i_ref_a)
        self.params = _as_params(self._model, params)
        self.model_options = dict(self._model.options)
        self.coil_tau_s = _check_option(coil_tau_s, 'coil_tau_s')
        q = self.params
        self._p = tuple(q[n] for n in KwokCurrent.param_names)
        self._inv_ref = 1.0 / float(i_ref_a)
        super().__init__(slew_a_per_s, initial_current_a)

    def _step(self, dt, x, v, i_cmd):
        if dt > 0.0:
            drive = self._driver(dt, i_cmd)
            if self.coil_tau_s > 0.0:
                self.current = drive + (self.current - drive) * math.exp(-dt / self.coil_tau_s)
            else:
                self.current = drive
        return kwok_current_force_scalar(self._p, self.current * self._inv_ref, x, v)


class SpencerPlant(DamperPlant):
    """
    Streaming Spencer modified Bouc-Wen damper.

    Parameters
    ----------
    params : dict or sequence
        Spencer parameters (SI).
    slew_a_per_s : float or None
        Driver slew-rate limit [A/s]; None: unlimited.
    max_substep_s : float
        Largest integration sub-step [s].
    initial_current_a : float
        Coil current after ``reset`` [A].
    y0_m : float or None
        Internal displacement y at the first step [m]; None: the first x (damper at rest).
    compiled : bool
        Step with the numba-compiled sample interval (``spencer.advance_step_compiled``, the
        same arithmetic; compiled on first use or loaded from numba's cache); False: the
        interpreted ``spencer.advance_scalar`` (the reference).

    """

    model_name = 'spencer'

    def __init__(self, params, slew_a_per_s=None, max_substep_s=1e-4, initial_current_a=0.0,
                 y0_m=None, compiled=True):
        self._model = Spencer(max_substep_s=max_substep_s, y0_m=y0_m)
        self.params = _as_params(self._model, params)
        self._model._check(self._model.from_dict(self.params)[None, :])
        self.model_options = {'n': 2}
        self.max_substep_s = float(max_substep_s)
        self.y0_m = None if y0_m is None else float(y0_m)
        self._p = tuple(self.params[k] for k in Spencer.param_names)
        self._advance = None
        if compiled:
            self._advance = advance_step_compiled()
            # compiled (or loaded from numba's cache) here, with the argument types of every
            # step, not in a control loop's first step
            self._advance(self._p, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1e-3, 1)
        super().__init__(slew_a_per_s, initial_current_a)

    def reset(self):
        """Return to the initial state (z = 0, coil at ``initial_current_a``)."""
        super().reset()
        self._state = [0.0, 0.0, self.current]
        self._x = 0.0
        self._v = 0.0

    def _step(self, dt, x, v, i_cmd):
        if not self._started:
            y0 = x if self.y0_m is None else self.y0_m
            self._state = [y0, 0.0, self.current]
            self._started = True
            self._x, self._v = x, v
        if dt == 0.0:
            return self._force_now(x, v)
        drive = self._driver(dt, i_cmd)
        m = substeps(dt, self.max_substep_s)
        if self._advance is None:
            f = advance_scalar(self._state, self._p, self._x, self._v, x, v, drive, dt, m)
        else:
            s = self._state
            s[0], s[1], s[2], f = self._advance(self._p, s[0], s[1], s[2], self._x, self._v, x,
                                                v, drive, dt, m)
        self.current = self._state[2]
        self._x, self._v = x, v
        return f

    def _force_now(self, x, v):
        c0a, c0b, k0, c1a, c1b, k1, x0, aa, ab, gamma, beta, A, eta = self._p
        y, z, u = self._state
        c0 = c0a + c0b * u
        c1 = c1a + c1b * u
        return c1 * ((aa + ab * u) * z + c0 * v + k0 * (x - y)) / (c0 + c1) + k1 * (x - x0)


def make_plant(name='spencer', params=None, **options):
    """
    Build a streaming plant, by default the thesis-like "true" damper.

    Parameters
    ----------
    name : {'spencer', 'kwok-current'}
        Plant model.
    params : dict, sequence or None
        Parameters {name: value} (SI) or a vector in the model's order; None:
        ``presets.spencer_thesis_like()`` or ``presets.thesis_kwok_current()``. A parameter
        file (the rig's and the car's ``truth_file``) is read by
        ``mr_damper_model.io.params_file.load_plant``.
    **options
        Keyword options of ``SpencerPlant`` / ``KwokCurrentPlant``. For 'spencer' ``y0_m``
        defaults to 0.0: x is measured from mid-stroke and the internal displacement starts
        there, which is the periodic steady state of a motion centred on 0 (no slow start-up
        force offset, see ``mr_damper_model.models.spencer``).

    Returns
    -------
    DamperPlant

    """
    if isinstance(params, str) or hasattr(params, '__fspath__'):
        raise ModelError(f'make_plant takes parameters, not the file {str(params)!r}: read a '
                         'parameter file with mr_damper_model.io.params_file.load_plant')
    if name == 'spencer':
        options.setdefault('y0_m', 0.0)
        return SpencerPlant(presets.spencer_thesis_like() if params is None else params,
                            **options)
    if name == 'kwok-current':
        if params is None:
            model, params = presets.thesis_kwok_current()
            options.setdefault('i_ref_a', model.options['i_ref_a'])
        return KwokCurrentPlant(params, **options)
    raise ModelError(f'unknown plant {name!r}; expected one of {", ".join(PLANT_NAMES)}')
