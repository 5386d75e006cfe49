"""Shared records and helpers of the live identifier tests (tests/mr_damper_model/test_live*)."""
import numpy as np

from mr_damper_model.io.data import DamperData
from mr_damper_model.identification.presets import thesis_kwok_current

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


def quiroz(stem):
    """Read a shared Quiroz record by its name without extension (``.csv`` or ``.csv.gz``)."""
    from conftest import QUIROZ_DIR
    from mr_damper_model.io.data import read_csv
    return read_csv(next(iter(sorted(QUIROZ_DIR.glob(stem + '.csv*')))))


def steady_mask(data):
    """
    Mask of the steady part of a record that starts and stops.

    The samples whose velocity amplitude (largest ``|v|`` over one excitation period around
    them, the period of the strongest displacement harmonic) is within 10 % of the record's
    median amplitude: the longest such run, less one period at each end.
    """
    from scipy.ndimage import maximum_filter1d
    dt = float(np.median(np.diff(data.t)))
    x = data.x - np.mean(data.x)
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size)))
    freq = np.fft.rfftfreq(x.size, dt)
    n_period = max(int(round(1.0 / float(freq[1 + int(np.argmax(spec[1:]))]) / dt)), 1)
    amp = maximum_filter1d(np.abs(data.v), size=n_period, mode='nearest')
    ok = np.abs(amp - np.median(amp)) <= 0.1 * np.median(amp)
    edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(np.int8), 0]))
    starts, ends = edges[::2], edges[1::2]
    k = int(np.argmax(ends - starts))
    mask = np.zeros(data.n, dtype=bool)
    mask[starts[k] + n_period:max(starts[k] + n_period, ends[k] - n_period)] = True
    return mask


def inject_faults(data, steady):
    """
    Return the record with four load-cell faults in its steady part, and their spans [s].

    A 1e30 N spike at 15 % of the steady part, the force stuck for 0.3 s from 30 %, a 0.2 s
    dropout to 0 N from 45 % and a 1 s +400 N offset step from 60 %.
    """
    t = data.t
    ts = t[steady]
    a, span = float(ts[0]), float(ts[-1] - ts[0])
    f = data.f.copy()
    k = int(np.searchsorted(t, a + 0.15 * span))
    f[k] = 1e30
    spans = {'spike': (float(t[k]), float(t[k]))}
    for name, frac, length in (('stuck', 0.3, 0.3), ('dropout', 0.45, 0.2),
                               ('offset', 0.6, 1.0)):
        idx = np.flatnonzero((t >= a + frac * span) & (t < a + frac * span + length))
        f[idx] = (f[idx[0]] if name == 'stuck' else 0.0 if name == 'dropout'
                  else f[idx] + 400.0)
        spans[name] = (float(t[idx[0]]), float(t[idx[-1]]))
    return DamperData(t, data.x, data.v, f, data.i, source=data.source), spans


#: The start-of-stream fault of issue 32: a 1 s +400 N load-cell offset 1.5 s after the start
#: of the stream, a 1e30 N spike 4 s after it; ``inject_start_faults`` shifts both by whole
#: windows (the fault in the first, second, third window, before a good set exists).
START_OFFSET = (1.5, 1.0, 400.0)
START_SPIKE_S = 4.0


def inject_start_faults(data, window, window_s=2.0):
    """
    Return the record with the start-of-stream faults in its ``window``-th window (1, 2, 3...).

    A ``START_OFFSET`` step (1 s of +400 N from 1.5 s) and a 1e30 N spike at 4 s, both
    ``(window - 1) * window_s`` later, times from the record's first stamp; the parts beyond
    the record's end are left out. Returns ``(data, spans)`` as :func:`inject_faults`.
    """
    t = data.t
    shift = float(t[0]) + (int(window) - 1) * float(window_s)
    start, length, offset = START_OFFSET
    f = data.f.copy()
    idx = np.flatnonzero((t >= shift + start) & (t < shift + start + length))
    spans = {}
    if idx.size:
        f[idx] += offset
        spans['offset'] = (float(t[idx[0]]), float(t[idx[-1]]))
    k = int(np.searchsorted(t, shift + START_SPIKE_S))
    if k < data.n:
        f[k] = 1e30
        spans['spike'] = (float(t[k]), float(t[k]))
    return DamperData(t, data.x, data.v, f, data.i, source=data.source), spans


def clean_reference(errors, end):
    """
    Error of the clean replay's set to judge a faulted set published at window end ``end``.

    The set the clean replay held then, or, before its first valid set, that first set (a
    faulted replay that publishes a set earlier than the clean one is judged against the
    clean replay's first); None if the clean replay never published a valid set.
    """
    held = held_at(errors, end)
    if held is None and errors:
        held = errors[0][1]
    return held


def replay_published(li, data):
    """Feed a record sample by sample; return [(window end [s], published estimate)]."""
    out = []
    for row in zip(data.t, data.x, data.v, data.f, data.i):
        li.add_sample(*row)
        window = li.next_window()
        if window is not None:
            est = li.process(window)
            if est is not None:
                out.append((float(window.end_s), est))
    return out


def steady_errors(published, data, mask, i_ref_a=2.0):
    """[(window end, RMS error [N] on the masked samples of the valid set published then)]."""
    from mr_damper_model.models.kwok_current import kwok_current_force
    out = []
    for end, est in published:
        if est.valid:
            f = kwok_current_force(dict(est.parameters, i_ref_a=i_ref_a), data.x[mask],
                                   data.v[mask], data.i[mask])
            out.append((end, float(np.sqrt(np.mean((data.f[mask] - f) ** 2)))))
    return out


def held_at(errors, end):
    """Error of the valid set a replay held at window end ``end`` (None before its first)."""
    held = None
    for e, err in errors:
        if e > end + 1e-9:
            break
        held = err
    return held


def alpha_scaled_fit(after, factor):
    """Return a ``fit_data`` replacement that scales alpha by ``factor`` from call ``after`` on."""
    from mr_damper_model.live import fit_data
    from mr_damper_model.identification.metrics import fit_metrics
    from mr_damper_model.models import get_model
    calls = []

    def fit(data, model, config, x0=None):
        result = fit_data(data, model, config, x0=x0)
        calls.append(model)
        if len(calls) > after:
            params = dict(result.parameters)
            for name in ('alpha', 'alpha0', 'alpha1', 'alpha2'):
                if name in params:
                    params[name] *= factor
            mdl = get_model(model, **({'i_ref_a': 2.0} if model == 'kwok-current' else {}))
            p = np.array([params[n] for n in mdl.param_names])
            result.parameters = params
            result.metrics = fit_metrics(data.f, mdl.force(p, data.x, data.v, i=data.i))
        return result
    return fit
