"""Shared full-car test helpers: a simulated car's corners as the corner messages carry them."""


def corners_of(state):
    """Return the four corner states of a full-car state, as the corner messages carry them."""
    return [state.corner(i) for i in range(4)]
