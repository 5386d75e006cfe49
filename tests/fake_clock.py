"""The one hand-moved clock of the unit tests (no wall time anywhere)."""


class FakeClock:
    """A clock the test moves by hand [s]: set or add to ``t`` (``now`` is the same value)."""

    def __init__(self, t=100.0):
        self.t = t

    @property
    def now(self):
        return self.t

    @now.setter
    def now(self, value):
        self.t = value

    def __call__(self):
        return self.t
