"""Tracking error of a rig: desired (or commanded) against measured displacement (no ROS)."""
import math


class TrackingMonitor:
    """
    Running tracking error of a rig: desired (or commanded) vs measured piston displacement.

    The one home of the tracking error: the car's side of hardware in the loop (desired travel
    vs the rig's measured displacement) and the rig's own command follower
    (``mr_damper_rig.commands.CommandFollower``: guarded target vs measured) both keep one.
    A non-finite error is counted apart (``non_finite``) and left out of the sums; a non-finite
    desired velocity leaves the sample out of the delay estimate only.

    Parameters
    ----------
    dt : float
        Sample interval [s].
    forgetting_s : float
        Time constant [s] of the recent remaining-delay estimate.

    """

    def __init__(self, dt, forgetting_s=1.0):
        self.dt = float(dt)
        self._lam = math.exp(-self.dt / float(forgetting_s))
        self.reset()

    def reset(self):
        """Clear the sums."""
        self.n = 0
        self.non_finite = 0
        self.last_m = math.nan
        self._e2 = 0.0
        self.peak_m = 0.0
        self._ev = 0.0
        self._vv = 0.0
        self._rev = 0.0
        self._rvv = 0.0

    def update(self, x_desired_m, v_desired_m_s, x_measured_m):
        """Add one sample (desired displacement [m] and velocity [m/s], measured [m])."""
        e = float(x_desired_m) - float(x_measured_m)
        self.last_m = e
        if not math.isfinite(e):
            self.non_finite += 1
            return
        self.n += 1
        self._e2 += e * e
        if abs(e) > self.peak_m:
            self.peak_m = abs(e)
        if not math.isfinite(v_desired_m_s):
            return
        ev = e * v_desired_m_s
        vv = v_desired_m_s * v_desired_m_s
        self._ev += ev
        self._vv += vv
        lam = self._lam
        self._rev = lam * self._rev + ev
        self._rvv = lam * self._rvv + vv

    @property
    def recent_delay_s(self):
        """Remaining delay [s] over the last ``forgetting_s`` (nan without motion)."""
        return self._rev / self._rvv if self._rvv > 0 else math.nan

    @property
    def rms_m(self):
        """Root mean square of the finite errors [m] (nan before the first)."""
        return math.sqrt(self._e2 / self.n) if self.n else math.nan

    def as_dict(self):
        """
        Return the figures for a status or summary.

        ``rms_m``, ``peak_m`` (largest magnitude) [m], ``delay_s`` (least-squares remaining
        delay over the whole run [s]), ``n`` (finite samples), ``non_finite`` (samples left
        out), ``last_m`` (the latest error [m], nan if it was not finite); nan where undefined.
        """
        return {'rms_m': self.rms_m,
                'peak_m': self.peak_m if self.n else math.nan,
                'delay_s': self._ev / self._vv if self._vv > 0 else math.nan,
                'n': self.n, 'non_finite': self.non_finite, 'last_m': self.last_m}
