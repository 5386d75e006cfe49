"""Shared full-car test helpers: a simulated car's corners as the corner messages carry them."""
from quarter_car_sim.full_car.controller_core import CornerState
from quarter_car_sim.full_car.runtime import corner_car_state


def corners_of(state):
    """Return the four corner states of a full-car state, as the corner messages carry them."""
    out = []
    for i in range(4):
        c = corner_car_state(state, i)
        out.append(CornerState(c.t, c.z_s, c.v_s, c.a_s, c.z_u, c.v_u, c.travel, c.v_rel,
                               c.z_r))
    return out
