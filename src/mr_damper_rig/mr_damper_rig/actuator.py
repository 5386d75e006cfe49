"""
Servo-hydraulic actuator of a damper test rig following a displacement command.

Models (command ``u`` [m] held over each sample, zero-order hold; exact discrete update):

* ``'first'``: first-order lag ``tau x' = u - x`` (an actuator under a proportional position
  loop; its low-frequency delay is ``tau``);
* ``'second'``: ``x'' + 2 zeta wn x' + wn**2 x = wn**2 u`` (servo-valve and oil-column dynamics;
  low-frequency delay ``2 zeta / wn``);
* ``'ideal'``: the piston is exactly at the command (for checks against model-in-the-loop).

Each can add a pure transport delay of ``delay_s`` (rounded to whole samples: controller, DAQ
and network latency), applied to the command before the dynamics.

Typical values (defaults): ``tau_s = 0.012`` s, ``wn = 2 pi 25`` rad/s, ``zeta = 0.7``,
``delay_s = 0.002`` s, i.e. 10-14 ms of equivalent delay. Order of magnitude recalled (not
re-checked here) from the real-time hybrid testing literature on servo-hydraulic actuators with
MR dampers (Carrion & Spencer 2007, "Model-based strategies for real-time hybrid testing", UIUC
NSEL report series; Chen & Ricles 2009), which reports equivalent delays of about 10-30 ms. The
vRTHS benchmark DanielMaurelE/vRTHS_AMBC_MRdamper identifies an all-pole transfer function of
its actuator from laboratory data (Cap6_ModeloActuador, MFDID) and runs at 4096 Hz with 18-bit
channels; its fitted coefficients are in .mat files not read here. The defaults are
representative, not measured on the thesis rig.
"""
import math

import numpy as np
from scipy.linalg import expm

from mr_damper_rig.excitation import Excitation, ExcitationError

ACTUATOR_KINDS = ('first', 'second', 'ideal')


def _non_negative(value, name, positive=False):
    value = float(value)
    if not math.isfinite(value) or value < 0 or (positive and value == 0):
        kind = 'positive' if positive else 'non-negative'
        raise ExcitationError(f'`{name}` must be a {kind} number, got {value}')
    return value


class ServoActuator:
    """
    Displacement-controlled actuator, stepped once per sample.

    Parameters
    ----------
    kind : {'first', 'second', 'ideal'}
        Dynamics (module docstring).
    dt : float
        Sample interval [s].
    tau_s : float
        Time constant of the first-order lag [s].
    wn_rad_s : float
        Natural frequency of the second-order model [rad/s].
    zeta : float
        Damping ratio of the second-order model [-].
    delay_s : float
        Transport delay [s], rounded to whole samples.
    x0_m : float
        Initial position (at rest) [m].

    """

    def __init__(self, kind='first', dt=1e-3, *, tau_s=0.012, wn_rad_s=2 * math.pi * 25.0,
                 zeta=0.7, delay_s=0.002, x0_m=0.0):
        if kind not in ACTUATOR_KINDS:
            raise ExcitationError(f'`kind` must be one of {ACTUATOR_KINDS}, got {kind!r}')
        self.kind = kind
        self.dt = _non_negative(dt, 'dt', positive=True)
        self.tau_s = _non_negative(tau_s, 'tau_s', positive=True)
        self.wn_rad_s = _non_negative(wn_rad_s, 'wn_rad_s', positive=True)
        self.zeta = _non_negative(zeta, 'zeta')
        self.delay_s = _non_negative(delay_s, 'delay_s')
        self.delay_samples = int(round(self.delay_s / self.dt))
        self.x0_m = float(x0_m)
        if kind == 'first':
            a = math.exp(-self.dt / self.tau_s)
            self._phi = np.array([[a, 0.0], [0.0, 0.0]])
            self._gam = np.array([1.0 - a, 0.0])
        elif kind == 'second':
            wn, z = self.wn_rad_s, self.zeta
            m = np.zeros((3, 3))
            m[0, 1] = 1.0
            m[1, 0] = -wn * wn
            m[1, 1] = -2.0 * z * wn
            m[1, 2] = wn * wn
            e = expm(m * self.dt)
            self._phi = e[:2, :2]
            self._gam = e[:2, 2]
        self.reset()

    @property
    def equivalent_delay_s(self):
        """Low-frequency delay [s] of the actuator (dynamics + transport), what to compensate."""
        lag = {'first': self.tau_s, 'second': 2.0 * self.zeta / self.wn_rad_s, 'ideal': 0.0}
        return lag[self.kind] + self.delay_samples * self.dt

    def reset(self, x0_m=None):
        """Return to rest at ``x0_m`` (default: the constructor's) with the delay line filled."""
        x0 = self.x0_m if x0_m is None else float(x0_m)
        self.x = x0
        self.v = 0.0
        self._line = [(x0, math.nan)] * self.delay_samples
        self._u_prev = x0
        self.n = 0

    def step(self, u_m, v_ff_m_s=None):
        """
        Hold the command ``u_m`` [m] over one sample; return the position and velocity after it.

        Parameters
        ----------
        u_m : float
            Displacement command [m].
        v_ff_m_s : float or None
            Velocity of the command [m/s] (feed-forward); only the ideal actuator uses it.

        Returns
        -------
        tuple of float
            (x [m], v [m/s]) at the end of the sample. The ideal actuator's velocity is the
            (delayed) feed-forward velocity, or without one the finite difference of the
            (delayed) command.

        """
        u = float(u_m)
        vff = math.nan if v_ff_m_s is None else float(v_ff_m_s)
        if not (math.isfinite(u) and (v_ff_m_s is None or math.isfinite(vff))):
            raise ExcitationError('actuator command must be finite')
        if self.delay_samples:
            self._line.append((u, vff))
            u, vff = self._line.pop(0)
        if self.kind == 'ideal':
            self.v = vff if vff == vff else (u - self._u_prev) / self.dt
            self.x = u
        elif self.kind == 'first':
            self.x = self._phi[0, 0] * self.x + self._gam[0] * u
            self.v = (u - self.x) / self.tau_s
        else:
            p, g = self._phi, self._gam
            x, v = self.x, self.v
            self.x = p[0, 0] * x + p[0, 1] * v + g[0] * u
            self.v = p[1, 0] * x + p[1, 1] * v + g[1] * u
        self._u_prev = u
        self.n += 1
        return self.x, self.v

    def response(self, u_m):
        """
        Return the positions [m] after each sample of the command array ``u_m`` [m].

        Resets first; vectorised callers (tests, benches) use this.
        """
        self.reset()
        return np.array([self.step(u)[0] for u in np.asarray(u_m, dtype=float)])


class CommandedMotion(Excitation):
    """
    Excitation of :class:`~mr_damper_rig.virtual_rig.VirtualRig` that follows commands.

    The rig calls ``exc(t)`` once per DAQ sample (streaming, scalar ``t``); each call with a
    new ``t`` steps the actuator once with the latest command from :meth:`command`. The same
    ``t`` again returns the same sample. ``center_m`` is the initial position.

    Parameters
    ----------
    actuator : ServoActuator
        Actuator model; its ``dt`` should be the rig's sample interval.

    """

    name = 'commanded'

    def __init__(self, actuator):
        self.actuator = actuator
        self.center_m = actuator.x0_m
        self._u = actuator.x0_m
        self._t_last = None
        self._last = (actuator.x, actuator.v)
        self._v = None
        self.commands = 0

    def command(self, x_m, v_m_s=None):
        """Set the displacement [m] (and velocity feed-forward [m/s]) for the next sample."""
        x_m = float(x_m)
        if not math.isfinite(x_m) or (v_m_s is not None and not math.isfinite(v_m_s)):
            raise ExcitationError('displacement command must be finite')
        self._u = x_m
        self._v = v_m_s
        self.commands += 1

    def __call__(self, t):
        """Step the actuator for sample time ``t`` [s]; return (x [m], v [m/s])."""
        if np.ndim(t) != 0:
            raise ExcitationError('CommandedMotion streams: call it with one time at a time')
        t = float(t)
        if self._t_last is None or t != self._t_last:
            if self._t_last is not None and t < self._t_last:
                raise ExcitationError(f'time went back from {self._t_last} to {t} s')
            self._last = self.actuator.step(self._u, self._v)
            self._t_last = t
        return self._last

    def reset(self):
        """Reset the actuator and forget the last command."""
        self.actuator.reset()
        self._u = self.actuator.x0_m
        self._v = None
        self._t_last = None
        self._last = (self.actuator.x, self.actuator.v)
