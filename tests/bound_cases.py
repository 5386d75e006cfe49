"""A damper model for the offline bounds' analytic limit (quarter car and full car)."""
import numpy as np


class WideLinearDamper:
    """
    Linear damper with a current offset so wide that no limit ever binds.

    Model force ``c v + K (i - 1)`` [N], i in 0..2 A, K = 1e7 N/A: on the body any force in
    about +-1e7 N, so the bound must find the unconstrained (fully active) optimum.
    """

    i_min, i_max, c, k_i = 0.0, 2.0, 800.0, 1.0e7

    def body_force_range(self, travel, v_rel):
        a = -(self.c * v_rel + self.k_i * (self.i_min - 1.0))
        b = -(self.c * v_rel + self.k_i * (self.i_max - 1.0))
        return min(a, b), max(a, b)

    def body_force_range_array(self, travel, v_rel):
        v = np.asarray(v_rel, dtype=float)
        a = -(self.c * v + self.k_i * (self.i_min - 1.0))
        b = -(self.c * v + self.k_i * (self.i_max - 1.0))
        return np.minimum(a, b), np.maximum(a, b)

    def currents(self, f_body, travel, v_rel):
        return 1.0 + (-np.asarray(f_body) - self.c * np.asarray(v_rel)) / self.k_i
