"""Shared records and helpers of the live identifier tests (tests/mr_damper_model/test_live*)."""
import numpy as np

from mr_damper_model.data import DamperData
from mr_damper_model.presets import thesis_kwok_current

RATE = 1000.0


def cam_record(currents=(0.0, 0.5, 1.0, 1.5, 2.0), hold_s=2.0, noise_n=2.0, seed=0, t0=0.0):
    """Thesis cam (1.1 Hz, 30 mm) through the kwok-current truth, current steps."""
    model, truth = thesis_kwok_current()
    n = int(round(hold_s * RATE)) * len(currents)
    t = t0 + np.arange(n) / RATE
    w = 2 * np.pi * 1.1
    x = 0.03 * np.sin(w * (t - t0))
    v = 0.03 * w * np.cos(w * (t - t0))
    i = np.repeat(np.asarray(currents, dtype=float), int(round(hold_s * RATE)))
    p = np.array([truth[k] for k in model.param_names])
    f = model.force(p, x, v, i=i) + noise_n * np.random.default_rng(seed).standard_normal(n)
    return DamperData(t, x, v, f, i), model, truth


#: small, deterministic fits (1 s windows every 0.5 s over 6 s of data: ends 1.0 .. 5.5 s,
#: 10 windows)
FAST = dict(window_s=1.0, hop_s=0.5, maxiter=5, swarm_size=10, backlog_windows=50)
N_WINDOWS = 10


def drain(li):
    """Process every due window now; return the estimates in order."""
    out = []
    while True:
        window = li.next_window()
        if window is None:
            return out
        est = li.process(window)
        if est is not None:
            out.append(est)


def fed_fast(li, data):
    """All samples first, then the fits (a replay far faster than the fitter)."""
    for row in zip(data.t, data.x, data.v, data.f, data.i):
        li.add_sample(*row)
    return drain(li)


def sequence(ests):
    return [(e.window_end_s, e.valid, e.reason, e.parameters) for e in ests]
