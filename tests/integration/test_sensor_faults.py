"""
Sensor faults in a live stream -> a real identifier_node process: no fault becomes a valid model.

A publisher in the test process streams the thesis cam (1.1 Hz, 30 mm, 1 kHz stamps) through a
known kwok-current damper (``presets.thesis_kwok_current``, 2 N noise) at 0 A then 2 A until the
identifier has published a valid set over 0..2 A; then one fault after another, each followed by
clean samples: spikes (1e30 N and in-range), a stuck load cell, a dropout to zero, a force offset
step, a load cell sign flip, a current probe stuck at 2 A while the coil goes to 0 A, and a time
gap.  The stream is paced on the identifier's own counts (``processed_up_to_s``: every sample
up to it has been judged), never on wall time, and a status snapshot after each fault attributes
the counters to it.  Checked: every valid set published reproduces the true force within ``TOL``
on clean cycles at each current it covers and has no parameter pinned at a bound; each fault is
counted under its reason; the identifier publishes valid sets again after the faults.
"""
import json
import math

import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from mr_damper_interfaces.msg import DamperSamples, KwokParameters

from integration.ros_helpers import NodeProcess
from mr_damper_common.health import WARN
from mr_damper_model.models.validity import pinned_parameters
from mr_damper_common.messages import identified_set_from_msg, samples_to_msg
from mr_damper_model.identification.presets import thesis_kwok_current

pytestmark = [pytest.mark.integration, pytest.mark.slow]

RATE = 1000.0
MODEL, TRUTH = thesis_kwok_current()
P_TRUE = np.array([TRUTH[k] for k in MODEL.param_names])
TOL = 0.03            # RMS force error of a valid set over the force range, per current level
#: the identifier's diagnostics status (namespace `faults`), as often as its JSON status was
DIAG_NAME = 'faults/mr_damper_identifier'
DIAG = {'diagnostics_period_s': 0.2}
KEEP_ALL = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL,
                      reliability=ReliabilityPolicy.RELIABLE)
#: samples published ahead of the identifier's judged stamp (below Fast DDS's 5000 limit)
LEAD_S = 2.5
# hang guard of each count-based wait (two CI runs at once on 2 cores: the identifier not
# subscribed 30 s after its start)
WAIT_S = 120.0


def cam(t):
    w = 2 * np.pi * 1.1
    return 0.03 * np.sin(w * t), 0.03 * w * np.cos(w * t)


def segment(t0, duration_s, current_a, seed):
    """Clean samples [t0, t0 + duration) at one true current: t, x, v, f, i (measured = true)."""
    t = t0 + np.arange(int(round(duration_s * RATE))) / RATE
    x, v = cam(t)
    i = np.full(t.size, current_a)
    f = MODEL.force(P_TRUE, x, v, i=i) + 2.0 * np.random.default_rng(seed).standard_normal(t.size)
    return [t, x, v, f, i]


def force_error(est):
    """Worst RMS error over the force range at the current levels the set covers (clean)."""
    t = np.arange(2000) / RATE
    x, v = cam(t)
    p = np.array([est['parameters'][k] for k in MODEL.param_names])
    worst = 0.0
    levels = {est['current_min_a'], est['current_max_a']}
    for level in levels:
        i = np.full(t.size, level)
        f_true = MODEL.force(P_TRUE, x, v, i=i)
        err = MODEL.force(p, x, v, i=i) - f_true
        worst = max(worst, float(np.sqrt(np.mean(err ** 2)) / np.ptp(f_true)))
    return worst


class Stream:
    """Publishes samples paced on the identifier's diagnostics; keeps status snapshots."""

    def __init__(self, lis, pub, diag, ident):
        self.lis, self.pub, self.diag, self.ident = lis, pub, diag, ident
        self.sent = 0
        self.batches = 0
        self.t_last = -1.0

    def last(self):
        return self.diag.values(DIAG_NAME)

    def judged_up_to(self):
        """Return the stamp up to which every sample was judged (-1 before any window)."""
        value = self.last().get('processed_up_to_s')   # NaN before the first window
        return value if isinstance(value, float) and math.isfinite(value) else -1.0

    def may_send(self, t):
        # the first window is due once the stream spans window_s (2 s)
        return t <= max(self.judged_up_to(), 2.0) + LEAD_S

    def wait(self, predicate, what):
        assert self.lis.wait_for(predicate, WAIT_S, procs=[self.ident]), \
            (what, self.last(), self.ident.output()[-3000:])

    def publish(self, arrays):
        """Publish the samples as the rig does: DamperSamples batches of 20."""
        t = arrays[0]
        for k in range(0, t.size, 20):
            if k % 100 == 0 and not self.may_send(t[k]):
                self.wait(lambda: self.may_send(t[k]), f'pace at {t[k]:.3f}')
            part = [a[k:k + 20] for a in arrays]
            self.pub.publish(samples_to_msg(*part, sequence=self.batches,
                                            first_index=self.sent))
            self.sent += part[0].size
            self.batches += 1
        self.t_last = float(t[-1])

    def snapshot(self, t_judged):
        """Wait until every sample up to ``t_judged`` was judged; return the status."""
        self.wait(lambda: self.judged_up_to() >= t_judged, f'judged up to {t_judged}')
        return self.last()

    def settle(self, params):
        """Wait until every due window was judged and every estimate fitted was received."""
        last_due = 2.0 + 0.2 * np.floor((self.t_last - 2.0) / 0.2 + 1e-9)
        self.snapshot(last_due - 1e-6)

        def published():
            s = self.last()
            return (s.get('parameters_published') == s.get('windows_fitted')
                    and len(params) >= s['parameters_published'])
        self.wait(published, 'estimates received')

    def clean_until(self, predicate, params, t0, what):
        """Publish clean 2 A samples in 0.5 s steps (at most 20) until ``predicate()``."""
        for step in range(21):
            self.settle(params)
            if predicate():
                return t0
            assert step < 20, (what, self.last())
            self.publish(segment(t0, 0.5, 2.0, 100 + step))
            t0 += 0.5


def diff(after, before, key):
    return {k: after[key][k] - before[key].get(k, 0) for k in after[key]}


def test_sensor_faults_never_become_valid_models(listener):
    lis = listener
    params = lis.subscribe('/faults/mr_damper/kwok_parameters', KwokParameters)
    diag = lis.diagnostics()
    pub = lis.publisher('/faults/mr_damper/measurement', DamperSamples, KEEP_ALL)
    ident = NodeProcess('identifier_node', DIAG, namespace='faults')
    with ident:
        assert lis.wait_for(lambda: pub.get_subscription_count() > 0, WAIT_S,
                            procs=[ident]), ident.output()
        run_faults(lis, Stream(lis, pub, diag, ident), params)
        assert ident.alive()


def run_faults(lis, stream, params):
    def estimates():
        return [identified_set_from_msg(m).to_dict() for _, m in params]

    def valid_full():
        return [e for e in estimates() if e['valid'] and e['current_max_a'] > 1.99
                and e['current_min_a'] < 0.01]

    # --- clean: 0 A then 2 A until a valid set over 0..2 A is published
    stream.publish(segment(0.0, 3.0, 0.0, 1))
    stream.publish(segment(3.0, 3.0, 2.0, 2))
    t0 = stream.clean_until(valid_full, params, 6.0, 'convergence over 0..2 A')
    n_converged = len(estimates())
    snaps = [stream.snapshot(t0 - 1.0)]
    n_levels = len(stream.diag.levels(DIAG_NAME))

    # --- spikes: 5 samples of 1e30 N (range check), 10 in-range spikes of 3000 N (outliers)
    seg = segment(t0, 2.0, 2.0, 3)
    seg[3][np.arange(5) * 331 + 17] = 1e30
    seg[3][np.arange(10) * 173 + 40] = 3000.0
    stream.publish(seg)
    stream.publish(segment(t0 + 2.0, 1.0, 2.0, 4))
    snaps.append(stream.snapshot(t0 + 2.5))
    t0 += 3.0

    # --- stuck load cell 0.6 s, clean 0.6 s, dropout to zero 0.6 s, clean
    seg = segment(t0, 2.4, 2.0, 5)
    seg[3][:600] = seg[3][0]
    seg[3][1200:1800] = 0.0
    stream.publish(seg)
    stream.publish(segment(t0 + 2.4, 1.0, 2.0, 6))
    snaps.append(stream.snapshot(t0 + 2.9))
    t0 += 3.4

    # --- force offset step +150 N for 2 s, load cell sign flip for 2 s, current probe stuck
    # at 2 A while the coil goes to 0 A for 2 s; each followed by 1.5 s clean at 2 A
    for kind in ('offset', 'sign_flip', 'current_stuck'):
        seg = segment(t0, 2.0, 0.0 if kind == 'current_stuck' else 2.0, 7)
        if kind == 'offset':
            seg[3] += 150.0
        elif kind == 'sign_flip':
            seg[3] *= -1.0
        else:
            seg[4][:] = 2.0
        stream.publish(seg)
        stream.publish(segment(t0 + 2.0, 1.5, 2.0, 8))
        snaps.append(stream.snapshot(t0 + 2.0))
        t0 += 3.5

    # --- gap: 0.4 s without samples, then clean
    stream.publish(segment(t0 + 0.4, 4.0, 2.0, 9))
    snaps.append(stream.snapshot(t0 + 3.0))
    t_end = stream.t_last

    # --- the identifier recovers: a valid full-range set from a window after the faults
    t_gap_end = t0 + 0.4
    stream.clean_until(
        lambda: any(e['valid'] and e['window_end_s'] > t_gap_end + 2.0 for e in valid_full()),
        params, t_end + 0.001, 'valid set after the faults')
    assert lis.wait_for(lambda: stream.last().get('samples_received', 0) == stream.sent, WAIT_S)
    final = stream.last()

    # no valid set is wrong or pinned, before or after the faults
    lo, hi = MODEL.default_bounds()
    published = estimates()
    assert len(published) > n_converged
    for est in published:
        if est['valid']:
            assert force_error(est) < TOL, (est, force_error(est))
            assert not pinned_parameters(MODEL.param_names,
                                         [est['parameters'][k] for k in MODEL.param_names],
                                         lo, hi, 1e-3), est

    # every fault counted under its reason (snapshots attribute counts to faults)
    base, spikes, stuck, offset, flip, current, gap = snaps
    assert diff(spikes, base, 'out_of_range') == {'force': 5, 'velocity': 0,
                                                  'displacement': 0, 'current': 0}
    assert 10 <= diff(spikes, base, 'samples_flagged')['outlier'] <= 12
    flagged = diff(stuck, spikes, 'samples_flagged')
    seen = {key: (diff(stuck, spikes, key) if isinstance(stuck[key], dict)
                  else stuck[key] - spikes[key])
            for key in ('samples_flagged', 'rejected', 'windows_skipped', 'samples_unbinned',
                        'windows_superseded')}
    print('stuck/dropout segment:', json.dumps(seen))
    # each 600-sample fault is counted under its own reason but for its onset: the batches
    # refused as they arrive (the first one and those within max_gap_s, 50 ms: at most 80
    # samples) and, when a window ended before the run reached stuck_s (0.2 s, one hop), up to
    # a hop's 200 samples judged inconsistent with the set in use (how the run falls on the
    # window grid depends on when the windows were fitted: a loaded run saw 359 dropout + 200
    # inconsistent, a quiet one 520 + 0). All 1,200 are kept out under a fault reason but a
    # sample or two at a run's edge (the stuck run's first sample is a clean value: 1,199
    # quiet); a part judged inconsistent may hold clean samples before the fault (up to a hop)
    refused = seen['rejected']['inconsistent_batch']
    assert 600 - 80 - 200 <= flagged['stuck'] <= 600, seen
    assert 600 - 80 - 200 <= flagged['dropout'] <= 600, seen
    kept_out = flagged['stuck'] + flagged['dropout'] + flagged['inconsistent'] + refused
    assert 1200 - 5 <= kept_out <= 1200 + 200, seen
    for before, after in ((stuck, offset), (offset, flip), (flip, current)):
        assert diff(after, before, 'windows_skipped')['inconsistent'] >= 1
        assert diff(after, before, 'samples_flagged')['inconsistent'] >= 1000
    # the gap is counted once where the samples come in; the windows across it are skipped
    # (`gap`) unless a slow fit had them all superseded
    assert gap['stamp_gaps'] - current['stamp_gaps'] == 1
    assert (diff(gap, current, 'windows_skipped')['gap'] >= 1
            or gap['windows_superseded'] > current['windows_superseded'])
    # nothing lost: every accepted sample judged once (binned, flagged or in a skipped window)
    assert final['samples_lost'] == 0
    assert final['samples_received'] == stream.sent
    # a batch the set in use cannot explain is refused whole as it arrives (inconsistent_batch,
    # issue 32): which fault batches meet a set that refuses them depends on when the fits end,
    # so count them; they are fault batches only (at most the 7,200 faulty samples), nothing
    # else is refused, and the 5 out-of-range samples are never accepted
    refused = final['rejected']
    assert refused['inconsistent_batch'] <= 7200, refused
    assert sum(refused.values()) == refused['inconsistent_batch'], refused
    assert final['samples_accepted'] == stream.sent - 5 - refused['inconsistent_batch']
    assert final['fit_errors'] == 0
    # and said so in its diagnostics (WARN while the faults' counts rose) and its log
    assert WARN in stream.diag.levels(DIAG_NAME)[n_levels:]
    assert 'skipped: inconsistent (sensor fault suspected' in stream.ident.output()
