"""``python -m mr_damper_model.live``: the fit child process of :class:`FitProcess`."""
from mr_damper_model.live.fitting import _serve

_serve()
