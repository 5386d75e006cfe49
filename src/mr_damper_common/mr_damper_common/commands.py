"""
Coil current commands checked before a coil takes them: clamped to the range, or refused (no ROS).

A command below ``i_min_a`` or above ``i_max_a`` is clamped to the range and counted; a NaN or
infinite command is refused (the coil keeps its current) and counted. Both the rig (its coil)
and the car (an external controller's command, ``semi_active_control.runtime.controller_core``)
check commands with :class:`CurrentCommandLimiter`; ``counts`` goes into their status. The rule
itself, :func:`clamp_command`, is also the rig's for displacement commands
(``mr_damper_rig.commands.DisplacementCommandGuard``).
"""
import math

#: Outcome keys of :attr:`CurrentCommandLimiter.counts`.
OUTCOMES = ('accepted', 'clamped_low', 'clamped_high', 'refused_non_finite')


def clamp_command(value, lo, hi):
    """
    Check one command against the range ``[lo, hi]``: the one rule of every command guard.

    Parameters
    ----------
    value : float
        Requested value (a coil current [A], a piston displacement [m], ...).
    lo, hi : float
        Range, ``lo < hi``.

    Returns
    -------
    value : float or None
        ``value`` within the range, or the range end it passed; None if not finite.
    outcome : str
        ``accepted``, ``clamped_low``, ``clamped_high`` or ``refused_non_finite``.

    """
    value = float(value)
    if not math.isfinite(value):
        return None, 'refused_non_finite'
    if value < lo:
        return lo, 'clamped_low'
    if value > hi:
        return hi, 'clamped_high'
    return value, 'accepted'


class CurrentCommandLimiter:
    """
    Clamp coil current commands to ``[i_min_a, i_max_a]``, refuse non-finite ones, count both.

    Parameters
    ----------
    i_min_a, i_max_a : float
        Coil current range [A], finite, ``i_min_a < i_max_a``.

    Raises
    ------
    ValueError
        On a non-finite or empty range (the message names the argument).

    """

    def __init__(self, i_min_a=0.0, i_max_a=2.0):
        self.set_range(i_min_a, i_max_a)
        self.counts = dict.fromkeys(OUTCOMES, 0)

    def set_range(self, i_min_a, i_max_a):
        """
        Set the coil current range [A] (also while running); nothing changes on an error.

        Raises
        ------
        ValueError
            On a non-finite or empty range (the message names the argument).

        """
        i_min_a, i_max_a = float(i_min_a), float(i_max_a)
        for name, value in (('i_min_a', i_min_a), ('i_max_a', i_max_a)):
            if not math.isfinite(value):
                raise ValueError(f'`{name}` must be finite, got {value}')
        if not i_min_a < i_max_a:
            raise ValueError(f'`i_min_a` ({i_min_a}) must be below `i_max_a` ({i_max_a})')
        self.i_min_a = i_min_a
        self.i_max_a = i_max_a

    def apply(self, i_a):
        """
        Check one command.

        Parameters
        ----------
        i_a : float
            Requested coil current [A].

        Returns
        -------
        current_a : float or None
            The current to apply [A], within the range; None if the command is refused.
        outcome : str
            One of :data:`OUTCOMES` (also counted).

        """
        current, outcome = clamp_command(i_a, self.i_min_a, self.i_max_a)
        self.counts[outcome] += 1
        return current, outcome
