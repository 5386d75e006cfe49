"""
Hardware in the loop over ROS 2 topics: the rig node follows the quarter-car node's commands.

Real node processes (console scripts of the venv), LOCALHOST discovery, the private domain of
tests/conftest.py. Order of events and counts only, no wall-clock thresholds:

- the rig in commanded mode, fed by a test publisher: commands followed, out-of-stroke ones
  clamped, non-finite ones refused, a silent commander timed out back to neutral, all counted;
- rig (commanded) + identifier + car (``plant:=rig``, probing) with the parameters of
  ``src/mr_damper_bringup/config/suite_hil.yaml``: the rig receives the car's commands and
  publishes measurements, the car drives on them (tracking RMS finite and below the travel RMS),
  the probe makes every current bin of the identifier hold data, the identifier publishes valid
  parameters over the coil range and the car leaves fail-safe on them.
"""
import math

import pytest
import yaml

from conftest import REPO
from integration.ros_helpers import NodeProcess

pytestmark = [pytest.mark.integration, pytest.mark.slow]

#: Hang guard [s] of the waits below (not a performance threshold: a run that needs longer
#: is a hang).
HANG_S = 240.0


def _suite_params(node, **overrides):
    """Parameters of ``node`` in suite_hil.yaml (``/**`` merged), plus ``overrides``."""
    cfg = yaml.safe_load((REPO / 'src/mr_damper_bringup/config/suite_hil.yaml').read_text())
    params = dict(cfg['/**']['ros__parameters'])
    params.update(cfg[node]['ros__parameters'])
    params.update(overrides)
    # as -p name:=value: an empty string cannot be given (the node's default is ''), a JSON
    # string must be quoted so that it stays a string
    return {k: (f"'{v}'" if isinstance(v, str) and v.startswith('{') else v)
            for k, v in params.items() if v != ''}


def test_rig_follows_clamps_refuses_and_times_out_displacement_commands(listener):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64
    from mr_damper_interfaces.msg import DamperSamples
    # the rig in namespace hilrig: its relative topics resolve to /hilrig/mr_damper/...
    params = _suite_params('mr_damper_rig', wait_for_subscribers=1,
                           realtime_priority=0, actuator='ideal', actuator_delay_s=0.0,
                           command_timeout_s=0.05, return_speed_m_s=0.2, stroke_m=0.05,
                           diagnostics_period_s=0.1, noise_n=0.0)
    diag = listener.diagnostics()
    meas = listener.subscribe('/hilrig/mr_damper/hil_measurement', DamperSamples, QoSProfile(
        depth=10000, reliability=ReliabilityPolicy.RELIABLE))
    pub = listener.publisher('/hilrig/mr_damper/displacement_command', Float64,
                             QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    name = 'hilrig/mr_damper_rig'
    with NodeProcess('rig_node', params=params, namespace='hilrig') as rig:
        assert listener.wait_for(lambda: diag.count(name) and pub.get_subscription_count(),
                                 HANG_S, procs=[rig]), rig.output()

        def status():
            return diag.values(name).get('displacement_commands') or {}

        def send(values):
            for v in values:
                pub.publish(Float64(data=v))

        # before any command: no sample (lockstep with the commander), nothing stale
        assert status()['stale_timeouts'] == 0 and not meas
        # 1. ordinary, out-of-stroke and non-finite commands, counted by outcome
        send([0.01, 0.02, 0.03, 0.2, -0.3, math.nan, math.inf])
        assert listener.wait_for(lambda: status().get('refused_non_finite') == 2
                                 and status().get('accepted') == 3, HANG_S, procs=[rig])
        assert listener.wait_for(lambda: len(meas) >= 7, HANG_S, procs=[rig])
        # lockstep: one sample per message, in stream order
        assert all(len(m.x_m) == 1 and m.first_index == k
                   for k, (_, m) in enumerate(list(meas)[:7]))
        first = [m.x_m[0] for _, m in list(meas)[:7]]
        # one sample per command (ideal actuator): the guarded targets, the last one held
        assert first == pytest.approx([0.01, 0.02, 0.03, 0.05, -0.05, -0.05, -0.05], abs=1e-4)
        st = status()
        assert st['clamped_high'] == 1 and st['clamped_low'] == 1
        # 2. the last good command (-0.3 clamped to -0.05) is held, then, silent for longer
        #    than command_timeout_s, the actuator returns to neutral (counted)
        assert listener.wait_for(lambda: status().get('stale_timeouts') == 1, HANG_S,
                                 procs=[rig])
        n = len(meas)
        assert listener.wait_for(lambda: len(meas) > n + 300, HANG_S, procs=[rig])
        xs = [x for _, m in list(meas) for x in m.x_m]
        assert min(xs) == pytest.approx(-0.05, abs=1e-4)      # clamped, held: the stroke end
        assert max(abs(x) for x in xs) <= 0.05 + 1e-4          # never beyond the stroke
        assert xs[-1] == pytest.approx(0.0, abs=1e-4)          # back to neutral
        # 3. a new command takes over at once: a second silence is a second timeout
        send([0.01])
        assert listener.wait_for(lambda: status().get('accepted') == 4
                                 and status().get('stale_timeouts') == 2, HANG_S, procs=[rig])
        assert diag.values(name)['samples_published'] > 0
        # the tracking error of the ideal actuator: the guarded target exactly (DAQ
        # quantisation aside), over every sample published
        track = diag.values(name)['tracking_error']
        assert track['n'] == diag.values(name)['samples_published']
        assert track['non_finite'] == 0 and track['peak_m'] <= 1e-4
        assert rig.stop() == 0


def test_hil_suite_rig_follows_the_car_and_the_identifier_fills_every_bin(listener):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from mr_damper_interfaces.msg import KwokParameters
    from mr_damper_common.messages import identified_set_from_msg
    # coarser bins than the shipped config (5 instead of 9) so that the probe covers them in
    # fewer windows; the same bins in the car's probe and the identifier
    bins = {'probe_bin_a': 0.5}
    rig_p = _suite_params('mr_damper_rig', realtime_priority=0)
    ident_p = _suite_params('mr_damper_identifier', current_bin_a=0.5)
    car_p = _suite_params('quarter_car_node', realtime_priority=0, road_duration_s=600.0,
                          diagnostics_period_s=0.1, **bins)
    diag = listener.diagnostics()
    params = listener.subscribe('/mr_damper/kwok_parameters', KwokParameters, QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL))
    with NodeProcess('identifier_node', params=ident_p) as ident, \
            NodeProcess('quarter_car_node', params=car_p) as car, \
            NodeProcess('rig_node', params=rig_p) as rig:
        procs = [ident, car, rig]
        levels = [0.0, 0.5, 1.0, 1.5, 2.0]

        def car_status():
            return diag.values('quarter_car_node')

        def bins_held():
            held = diag.values('mr_damper_identifier').get('bins_a') or []
            return all(any(abs(h - lv) < 0.25 for h in held) for lv in levels)

        def probe_covered():
            probe = car_status().get('probe') or {}
            return probe.get('bins') == len(levels) and probe.get('covered') == len(levels)

        # events: probe covers every bin; the identifier holds every bin; the car goes normal
        assert listener.wait_for(probe_covered, HANG_S, procs=procs), \
            (car_status().get('probe'), car.output()[-2000:], rig.output()[-2000:])
        assert listener.wait_for(bins_held, HANG_S, procs=procs), \
            diag.values('mr_damper_identifier')
        assert listener.wait_for(lambda: car_status().get('mode') == 'normal', HANG_S,
                                 procs=procs), (car_status(), ident.output()[-2000:])
        # the car's tracking after it has driven on the rig's force
        n_status = diag.count('quarter_car_node')
        assert listener.wait_for(lambda: diag.count('quarter_car_node') > n_status + 5, HANG_S,
                                 procs=procs)
        st = car_status()
        hil = st['hil']
        n_rig = diag.count('mr_damper_rig')   # a rig status published after the car's
        assert listener.wait_for(lambda: diag.count('mr_damper_rig') > n_rig + 1, HANG_S,
                                 procs=procs)
        rig_status = diag.values('mr_damper_rig')
        for proc in (car, rig, ident):        # car first: the rig then times the car out
            assert proc.stop() == 0, proc.output()[-3000:]
    # the rig received the car's commands and published measurements; the car took them
    cmds = rig_status['displacement_commands']
    assert cmds['accepted'] > 0 and cmds['refused_non_finite'] == 0
    assert rig_status['samples_published'] > 0 and rig_status['current_commands'] > 0
    # lockstep: one sample per command taken (plus samples of its own clock if the car fell
    # silent); the car cannot have taken more measurements than the rig published
    taken = sum(cmds[k] for k in ('accepted', 'clamped_low', 'clamped_high',
                                  'refused_non_finite'))
    assert rig_status['samples_published'] >= taken
    assert 0 < hil['counts']['measurements'] <= rig_status['samples_published']
    assert hil['counts']['non_finite'] == 0 and hil['counts']['out_of_order'] == 0
    tr = hil['tracking']
    assert tr['n'] > 0 and math.isfinite(tr['rms_m']) and math.isfinite(hil['travel_rms_m'])
    assert tr['rms_m'] < hil['travel_rms_m']
    assert tr['peak_m'] >= tr['rms_m']
    # valid parameters over the whole coil range, thanks to the probe; the car took one
    sets = [identified_set_from_msg(m).to_flat() for _, m in params]
    valid = [p for p in sets if p.get('valid') == 1.0]
    assert valid, sets[-3:]
    assert any(p['current_max_a'] - p['current_min_a'] >= 1.0 for p in valid)
    assert all(math.isfinite(v) for p in valid for k, v in p.items()
               if k not in ('valid', 'reason', 'window_start_s', 'window_end_s'))
    assert st['params_accepted'] >= 1
    assert math.isfinite(st['first_normal_t_sim'])
