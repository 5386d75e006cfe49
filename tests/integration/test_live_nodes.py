"""
Rig / replay node -> identifier node over real ROS 2 topics (separate processes).

- sim rig (kwok-current truth) -> identifier: the published model reproduces the true force
  within 3 % of the peak force over 0..2 A; the last valid set is saved and, after a restart of
  the identifier, published again (latched) as the initial, valid estimate;
- sim rig (Spencer truth) -> identifier: within 1 percentage point of NRMSE of the offline
  kwok-current best fit of the very samples the identifier received;
- replay of a shared Quiroz file as CSV and as rosbag2 (sqlite3, MCAP, written here with
  rosbags) -> valid parameters identical to ``mr-damper-identify`` on the same window's samples
  (same seed, no warm start, no wall-time budget: the same identify() call);
- bad messages from a test publisher (NaN, out-of-order, duplicate stamps, wrong joint names)
  -> counted by reason in the diagnostics, node alive, parameters equal to the clean stream's;
- a bad replay file -> exit status 2, one error naming the file, nothing published.

Rigs run faster than real time (rate_factor 2, or 0 = as fast as the identifier takes it).
"""
import array
import json
import math
import subprocess

import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from mr_damper_interfaces.msg import DamperSamples, KwokParameters

from conftest import csv_text, QUIROZ_DIR, VENV_BIN
from integration.ros_helpers import NodeProcess
from mr_damper_model.io.data import DamperData
from mr_damper_model.models.kwok_current import kwok_current_force
from mr_damper_common.messages import (identified_set_from_msg, measurement_arrays,
                                       measurement_to_msg, samples_to_msg)
from mr_damper_model.io.params_file import load_params

pytestmark = [pytest.mark.integration, pytest.mark.slow]

QUIROZ = QUIROZ_DIR / 'quiroz_sine_5mm3Hz_0p5A.csv.gz'
KEEP_ALL = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL,
                      reliability=ReliabilityPolicy.RELIABLE)
#: identifier settings that make each window's fit exactly the offline tool's call
#: identifier settings that make its last window's fit the offline tool's on the same samples
#: (no warm start, no budget; the acceptance review off: it may keep samples of the record's
#: stop out of the fit and hold an earlier set, tested in tests/mr_damper_model)
OFFLINE_SAME = {'warm_start': False, 'budget_s': 0.0, 'maxiter': 0, 'swarm_size': 25,
                'seed': 1, 'acceptance_checks': False}
#: identifier diagnostics as often as its JSON status was published
DIAG = {'diagnostics_period_s': 0.2}


class Topics:
    """Subscriptions of one run on its own topic names (runs never see each other)."""

    def __init__(self, lis, tag, measurement=False):
        self.names = {'measurement_topic': f'/{tag}/measurement',
                      'joint_topic': f'/{tag}/joint_measurement',
                      'parameters_topic': f'/{tag}/kwok_parameters'}
        # the identifier runs in namespace `tag`: its diagnostics status is `tag/...`
        self.tag = tag
        self.diag_name = f'{tag}/mr_damper_identifier'
        self.params = lis.subscribe(self.names['parameters_topic'], KwokParameters)
        self.diag = lis.diagnostics()
        self.meas = (lis.subscribe(self.names['measurement_topic'], DamperSamples, KEEP_ALL)
                     if measurement else None)

    def rig_remap(self, tag):
        """Remappings of the rig's relative topic names onto this run's names."""
        return {'mr_damper/measurement': self.names['measurement_topic'],
                'mr_damper/samples_received': f'/{tag}/samples_received',
                'mr_damper/true_parameters': f'/{tag}/true_parameters',
                'mr_damper/true_spencer_parameters': f'/{tag}/true_spencer_parameters'}

    def ident(self, params):
        """Start the identifier of this run (namespace `tag`, topics remapped onto its names)."""
        remap = {'mr_damper/measurement': self.names['measurement_topic'],
                 'mr_damper/joint_measurement': self.names['joint_topic'],
                 'mr_damper/kwok_parameters': self.names['parameters_topic'],
                 'mr_damper/samples_received': f'/{self.tag}/samples_received'}
        return NodeProcess('identifier_node', dict(DIAG, **params), remap=remap,
                           namespace=self.tag)

    def last_status(self):
        return self.diag.values(self.diag_name)

    def estimates(self):
        return [identified_set_from_msg(m).to_dict() for _, m in self.params]


def wait_identified(lis, topics, n_samples, procs, timeout=60.0):
    """Wait until the identifier received n samples and fitted the last due window."""
    def done():
        s = topics.last_status()
        return (s.get('samples_received', 0) >= n_samples
                and s.get('windows_fitted', 0) > 0
                and s.get('windows_due', 0) == (s.get('windows_fitted', 0)
                                                + sum(s['windows_skipped'].values())))
    lis.wait_for(lambda: topics.last_status().get('samples_received', 0) >= n_samples,
                 timeout, procs=procs)
    # the worker may still be fitting the last window: a couple of status periods more
    return lis.wait_for(done, 30.0, procs=procs[:1])


def run_summary(status, estimates, t0):
    """Status counters and (end [s from t0], current range [A], valid) of each estimate."""
    keys = ('windows_due', 'windows_superseded', 'windows_fitted', 'windows_valid',
            'windows_skipped', 'windows_refused', 'catch_up_fits', 'reference_resets',
            'samples_flagged', 'samples_binned', 'samples_unbinned', 'samples_pending',
            'samples_lost', 'bins_a', 'last_check', 'compute_s_max')
    return ({k: status.get(k) for k in keys},
            [(round(e['window_end_s'] - t0, 3), e['current_min_a'], e['current_max_a'],
              e['valid']) for e in estimates])


def received_data(meas):
    cols = [measurement_arrays(m) for _, m in meas]
    return DamperData(*(np.concatenate(c) for c in zip(*cols)))


@pytest.mark.parametrize('plant', ['kwok-current', 'spencer'])
def test_sim_rig_to_identifier_converges(listener, tmp_path, plant):
    tag = f'sim_{plant.replace("-", "_")}'
    topics = Topics(listener, tag, measurement=True)
    truth = listener.subscribe(f'/{tag}/true_parameters', KwokParameters)
    params_file = tmp_path / 'identified.json'
    duration = 12.0
    n = int(duration * 1000)
    ident = topics.ident(dict(params_file=str(params_file), save_period_s=0.5))
    rig = NodeProcess('rig_node', dict(mode='sim', plant=plant,
                                       duration_s=duration, step_s=2.0, rate_factor=2.0,
                                       wait_for_subscribers=2, seed=3),
                      remap=topics.rig_remap(tag))
    with ident, rig:
        assert rig.wait(90) == 0, rig.output()
        assert wait_identified(listener, topics, n, [ident]), \
            (topics.last_status(), ident.output())
        assert ident.alive()
    status = topics.last_status()
    assert status['samples_received'] == status['samples_accepted'] == n   # nothing lost
    # the test's own copy (hang guard only: a starved test process takes a while)

    def copied():
        return sum(len(m.x_m) for _, m in list(topics.meas))      # samples of the batches
    assert listener.wait_for(lambda: copied() >= n, 180.0)
    assert copied() == n
    final = topics.estimates()[-1]
    data = received_data(topics.meas)
    # what happened, should an assertion fail: counters and the published estimates
    why = (run_summary(status, topics.estimates(), data.t[0]), ident.output()[-2000:])
    assert final['valid'], why
    assert final['current_min_a'] == pytest.approx(0.0, abs=0.01), why
    assert final['current_max_a'] == pytest.approx(2.0, abs=0.01), why
    # every sample was judged once and none lost, whatever windows were superseded (the fit
    # process is ready before the node subscribes, and superseded windows' samples are binned)
    assert status['samples_lost'] == 0, why
    flagged = status['samples_flagged']
    assert status['samples_binned'] + status['samples_unbinned'] + sum(flagged.values()) \
        + status['samples_pending'] == n, why
    # a healthy damper raises no fault, whatever windows a slow fitter superseded (their
    # samples are judged against sets fitted on the levels in between: catch_up_fits)
    assert flagged['inconsistent'] == flagged['stuck'] == flagged['dropout'] == 0, why
    assert flagged['outlier'] <= 10, why
    # so no current level goes missing: steps every 2 s from t = 0 (2 A from 8 s); the 2 A
    # bin holds the 500 samples it needs by 8.5 s, so the first window processed after 8.6 s
    # (whenever the fitter got to it) covers 0..2 A; a valid set over 0..2 A was published
    later = [e for e in topics.estimates() if e['window_end_s'] - data.t[0] >= 8.6]
    assert later and later[0]['current_min_a'] < 0.01 and later[0]['current_max_a'] > 1.99, why
    full = [e for e in topics.estimates() if e['valid'] and e['current_max_a'] > 1.99]
    assert full, why
    f_est = kwok_current_force(final['parameters'], data.x, data.v, data.i)   # i_ref_a 2 A
    peak = np.max(np.abs(data.f))
    if plant == 'kwok-current':
        # converges to the truth: force error below 3 % of the peak force everywhere
        true = identified_set_from_msg(truth[-1][1]).to_dict()
        assert true['valid'] and true['current_max_a'] == 2.0
        f_true = kwok_current_force(true['parameters'], data.x, data.v, data.i)
        assert np.max(np.abs(f_est - f_true)) < 0.03 * peak
    else:
        # converges to the offline best fit of the same samples (kwok-current cannot be exact)
        from mr_damper_model.identification.identify import identify
        from mr_damper_model.identification.metrics import fit_metrics
        offline = identify(data, 'kwok-current', seed=1, model_options={'i_ref_a': 2.0})
        live = fit_metrics(data.f, f_est)['nrmse_percent']
        assert live <= offline.metrics['nrmse_percent'] + 1.0, (live, offline.metrics)
    # the last valid set was saved ...
    saved = load_params(params_file, model='kwok-current')
    assert saved.valid
    last_valid = [e for e in topics.estimates() if e['valid']][-1]
    assert saved.parameters == pytest.approx(last_valid['parameters'], rel=1e-12)
    if plant == 'spencer':
        return
    # ... and a restarted identifier starts from it: latched initial estimate, valid
    topics2 = Topics(listener, tag + '_restart')
    with topics2.ident(dict(params_file=str(params_file))) as p:
        assert listener.wait_for(lambda: topics2.params and topics2.last_status(), 20.0,
                                 procs=[p])
        first = topics2.estimates()[0]
        assert first['valid'] and math.isnan(first['window_end_s'])   # from a file: no window
        assert first['parameters'] == pytest.approx(saved.parameters, rel=1e-12)
        assert first['current_max_a'] == pytest.approx(saved.current_max_a)
        assert topics2.last_status()['initial_source'] == 'file'


def offline_tool(tmp_path, data):
    """Run mr-damper-identify on a CSV of exactly these samples (full precision)."""
    path = tmp_path / 'window.csv'
    np.savetxt(path, np.column_stack([data.t, data.x, data.v, data.f, data.i]), delimiter=',',
               header='t,x,v,f,i', comments='', fmt='%.17g')
    out = subprocess.run([str(VENV_BIN / 'mr-damper-identify'), str(path), '--model', 'kwok',
                          '--seed', '1', '--json'], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


@pytest.mark.parametrize('source', ['csv', 'sqlite3', 'mcap'])
def test_replay_matches_offline_tool(listener, tmp_path, source):
    from mr_damper_rig.replay import read_csv_stream, write_bag
    data = read_csv_stream(QUIROZ)
    if source == 'csv':
        rig_params = {'mode': 'csv', 'file': str(QUIROZ), 'rate_factor': 2.0}
    else:
        write_bag(tmp_path / 'bag', data, storage=source)
        rig_params = {'mode': 'bag', 'file': str(tmp_path / 'bag'), 'rate_factor': 0.0}
    tag = f'replay_{source}'
    topics = Topics(listener, tag)
    ident = topics.ident(OFFLINE_SAME)
    rig = NodeProcess('rig_node', dict(wait_for_subscribers=1, **rig_params),
                      remap=topics.rig_remap(tag))
    with ident, rig:
        assert rig.wait(90) == 0, rig.output()
        assert wait_identified(listener, topics, data.n, [ident]), topics.last_status()
    status = topics.last_status()
    assert status['samples_accepted'] == data.n and status['last_model'] == 'kwok'
    final = topics.estimates()[-1]
    assert final['valid'] and final['current_min_a'] == final['current_max_a'] == 0.5
    eps = 1e-6
    window = data.select((data.t >= status['last_window_start_s'] - eps)
                         & (data.t <= status['last_window_end_s'] + eps))
    assert window.n == 2000
    offline = offline_tool(tmp_path, window)
    p = offline['parameters'] if 'parameters' in offline else offline['results'][0]['parameters']
    live = final['parameters']
    mapped = {'c0': p['c'], 'k': p['k'], 'alpha0': p['alpha'], 'beta0': p['beta'],
              'delta': p['delta'], 'f0': p['f0']}
    for name, value in mapped.items():
        assert live[name] == pytest.approx(value, rel=1e-9, abs=1e-9), name


def test_bad_messages_are_counted_and_harmless(listener):
    from mr_damper_model.identification.identify import identify
    from mr_damper_model.live import fit_kwargs, LiveConfig
    from mr_damper_rig.replay import read_csv_stream
    data = read_csv_stream(QUIROZ).select(slice(0, 3000))
    topics = Topics(listener, 'badmsg')
    # the single-sample layout (a DAQ driver's JointState per sample) and one malformed batch
    pub = listener.publisher(topics.names['joint_topic'], JointState, KEEP_ALL)
    batches = listener.publisher(topics.names['measurement_topic'], DamperSamples, KEEP_ALL)
    with topics.ident(OFFLINE_SAME) as ident:
        assert listener.wait_for(lambda: pub.get_subscription_count() > 0
                                 and batches.get_subscription_count() > 0, 15.0, procs=[ident])
        bad_batch = samples_to_msg([0.0, 1e-3], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0],
                                   sequence=0, first_index=0)
        bad_batch.f_n = array.array('d', [1.0])        # arrays of unequal length
        batches.publish(bad_batch)
        sent = {'nonfinite': 0, 'out_of_order': 0, 'duplicate': 0, 'joint_names': 0}
        for k, row in enumerate(zip(data.t, data.x, data.v, data.f, data.i)):
            pub.publish(measurement_to_msg(*row))
            if k % 100 == 50:
                pub.publish(measurement_to_msg(row[0] + 1e-4, math.nan, *row[2:]))
                pub.publish(measurement_to_msg(row[0] - 0.01, 0.5, 1.0, 999.0, 2.0))
                pub.publish(measurement_to_msg(*row))
                bad = measurement_to_msg(row[0] + 2e-4, 0.0, 0.0, 0.0, 0.0)
                bad.name = ['piston', 'coil']
                pub.publish(bad)
                for key in sent:
                    sent[key] += 1
        assert wait_identified(listener, topics, data.n + sum(sent.values()) + 1, [ident])
        assert ident.alive()
    status = topics.last_status()
    assert status['samples_accepted'] == data.n
    assert status['rejected'] == dict(sent, layout=1, future_stamp=0, inconsistent_batch=0)
    # the newest set is the fit of its own window (a newer window the identifier refused would
    # leave the set in use published again, with its window)
    final = topics.estimates()[-1]
    window = data.select((data.t >= final['window_start_s'] - 1e-6)
                         & (data.t <= final['window_end_s'] + 1e-6))
    clean = identify(window, 'kwok', **fit_kwargs(LiveConfig(**OFFLINE_SAME)))
    assert final['parameters']['c0'] == pytest.approx(clean.parameters['c'], rel=1e-9)
    assert final['parameters']['alpha0'] == pytest.approx(clean.parameters['alpha'], rel=1e-9)
    assert final['nrmse_percent'] == pytest.approx(clean.metrics['nrmse_percent'], rel=1e-9)


def test_bad_replay_file_exits_2_and_publishes_nothing(listener, tmp_path):
    lines = csv_text(QUIROZ).splitlines()
    lines[len(lines) // 2] = lines[len(lines) // 2].rsplit(',', 1)[0] + ',nan'
    bad = tmp_path / 'half_bad.csv'
    bad.write_text('\n'.join(lines) + '\n')
    meas = listener.subscribe('/badfile/measurement', DamperSamples, KEEP_ALL)
    remap = {'mr_damper/measurement': '/badfile/measurement'}
    rig = NodeProcess('rig_node', {'mode': 'csv', 'file': str(bad)}, remap=remap)
    code = rig.wait(60)
    out = rig.output()
    # (a CI run saw -11 here once: the node's log, with faulthandler's stacks, tells where)
    assert code == 2, out
    assert f'{bad}: column i has 1 NaN/inf value' in out, out
    assert meas == []
    rig2 = NodeProcess('rig_node', {'mode': 'bag', 'file': str(tmp_path / 'nobag')},
                       remap=remap)
    assert rig2.wait(60) == 2 and 'nobag: bag not found' in rig2.output()
    assert meas == []
