"""
Piston displacement commands checked before the rig applies them (no ROS).

Coil current commands are checked by :class:`mr_damper_common.commands.CurrentCommandLimiter`
(shared with the car). Displacement commands (hardware-in-the-loop, ``excitation:=commanded``)
go through :class:`DisplacementCommandGuard`: clamped to the stroke, non-finite refused, and a
silent commander makes the actuator hold, then return to neutral (all counted);
:class:`CommandFollower` samples the rig with the guarded target and keeps the tracking error
(``mr_damper_common.tracking.TrackingMonitor``, as the car's HIL monitor).
"""
import math

from mr_damper_common.commands import clamp_command, OUTCOMES
from mr_damper_common.tracking import TrackingMonitor

#: Counter keys of :attr:`DisplacementCommandGuard.counts`.
DISPLACEMENT_OUTCOMES = OUTCOMES + ('stale_timeouts', 'stale_samples')


class DisplacementCommandGuard:
    """
    Displacement commands of the rig's actuator: stroke clamp, non-finite refusal, stale timeout.

    A command outside ``center_m +- stroke_m`` is clamped to the stroke end and counted; a NaN or
    infinite command is refused (the previous one stays) and counted. When no new command has
    come for ``timeout_s`` (sample time of the rig), the rig holds the last command until then
    and afterwards returns to the neutral position ``center_m`` at ``return_speed_m_s`` (one
    ``stale_timeouts`` per silence, ``stale_samples`` for every sample past the timeout); the
    next command takes over again at once.

    Parameters
    ----------
    stroke_m : float
        Half stroke [m] around ``center_m`` (> 0).
    timeout_s : float
        Command age [s] after which the actuator returns to neutral (> 0).
    return_speed_m_s : float
        Speed of the return to neutral [m/s] (> 0).
    center_m : float
        Neutral position [m].

    Raises
    ------
    ValueError
        On a non-finite or non-positive setting (the message names the argument).

    """

    def __init__(self, stroke_m=0.08, timeout_s=0.05, return_speed_m_s=0.05, center_m=0.0):
        if not math.isfinite(float(center_m)):
            raise ValueError(f'`center_m` must be finite, got {center_m}')
        self.configure(stroke_m=stroke_m, timeout_s=timeout_s,
                       return_speed_m_s=return_speed_m_s)
        self.center_m = float(center_m)
        self.counts = dict.fromkeys(DISPLACEMENT_OUTCOMES, 0)
        self.last_command_t = None
        self.target_m = self.center_m
        self._stale = False
        self._t_prev = None

    def configure(self, *, stroke_m=None, timeout_s=None, return_speed_m_s=None):
        """
        Change the stroke [m], timeout [s] and return speed [m/s] (None: unchanged).

        Also while running; all are checked before any is applied.

        Raises
        ------
        ValueError
            On a non-finite or non-positive value (the message names the argument).

        """
        new = {'stroke_m': stroke_m, 'timeout_s': timeout_s,
               'return_speed_m_s': return_speed_m_s}
        for name, value in new.items():
            if value is not None and not (math.isfinite(float(value)) and float(value) > 0):
                raise ValueError(f'`{name}` must be a positive number, got {value}')
        for name, value in new.items():
            if value is not None:
                setattr(self, name, float(value))

    def command(self, x_m, t_s):
        """
        Take one displacement command received at rig time ``t_s`` [s].

        Parameters
        ----------
        x_m : float
            Requested piston displacement [m].
        t_s : float
            Rig sample time [s] when it arrived.

        Returns
        -------
        target_m : float or None
            The displacement the actuator will follow [m]; None if refused.
        outcome : str
            One of ``accepted``, ``clamped_low``, ``clamped_high``, ``refused_non_finite``
            (also counted).

        """
        x_m, outcome = clamp_command(x_m, self.center_m - self.stroke_m,
                                     self.center_m + self.stroke_m)
        self.counts[outcome] += 1
        if x_m is None:
            return None, outcome
        self.target_m = x_m
        self.last_command_t = float(t_s)
        self._stale = False
        return x_m, outcome

    def target(self, t_s):
        """
        Return the actuator command [m] for the rig sample at time ``t_s`` [s].

        Before the first command: neutral. Within ``timeout_s`` of the last command: that
        command. Later: a ramp back to neutral (counted).
        """
        t_s = float(t_s)
        dt = 0.0 if self._t_prev is None else max(t_s - self._t_prev, 0.0)
        self._t_prev = t_s
        if self.last_command_t is None or t_s - self.last_command_t <= self.timeout_s:
            return self.target_m
        if not self._stale:
            self._stale = True
            self.counts['stale_timeouts'] += 1
        self.counts['stale_samples'] += 1
        step = self.return_speed_m_s * dt
        gap = self.center_m - self.target_m
        self.target_m = self.center_m if abs(gap) <= step else self.target_m + math.copysign(
            step, gap)
        return self.target_m


class CommandFollower:
    """
    A virtual rig whose actuator follows guarded displacement commands, sampled one by one.

    Parameters
    ----------
    rig : mr_damper_rig.virtual_rig.VirtualRig
        Rig driven by a :class:`mr_damper_rig.actuator.CommandedMotion`.
    guard : DisplacementCommandGuard
        Checks the commands and supplies the target of each sample.

    Attributes
    ----------
    tracking : mr_damper_common.tracking.TrackingMonitor
        Guarded target minus measured piston displacement of every sample (actuator lag and
        delay, stroke clamps, return to neutral, DAQ quantisation and noise); the target's
        velocity (its difference over one sample) gives the remaining-delay estimate.

    """

    def __init__(self, rig, guard):
        from mr_damper_rig.actuator import CommandedMotion
        if not isinstance(rig.excitation, CommandedMotion):
            raise ValueError('the rig must be driven by a CommandedMotion excitation')
        self.rig = rig
        self.guard = guard
        self.samples = 0
        self.tracking = TrackingMonitor(rig.dt)
        self._target_prev = None

    @property
    def t_next(self):
        """Rig time [s] of the next sample."""
        return self.samples * self.rig.dt

    def command(self, x_m):
        """Take a displacement command [m] now (``DisplacementCommandGuard.command``)."""
        return self.guard.command(x_m, self.t_next)

    def sample(self):
        """Step the actuator to the guarded target; return the DAQ sample ``(t, x, v, f, i)``."""
        target = self.guard.target(self.t_next)
        self.rig.excitation.command(target)
        self.samples += 1
        sample = self.rig.sample()
        v_target = (0.0 if self._target_prev is None
                    else (target - self._target_prev) / self.rig.dt)
        self._target_prev = target
        self.tracking.update(target, v_target, sample[1])
        return sample
