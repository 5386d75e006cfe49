"""Tests of quarter_car_sim.runtime.hil: delay compensation, tracking, the remote rig plant."""
import math

import numpy as np
import pytest

from mr_damper_rig.actuator import ServoActuator
from quarter_car_sim.runtime import hil

DT = 1e-3


def _track(act, comp, seconds=2.0, freq_hz=2.0, amp_m=0.01):
    t = DT * np.arange(int(seconds / DT))
    xd = amp_m * np.sin(2 * math.pi * freq_hz * t)
    xm = np.array([act.step(x if comp is None else comp(x))[0] for x in xd])
    half = t.size // 2                                 # after the start-up transient
    return hil.tracking_error(xd[half:], xm[half:], DT)


def test_tracking_error_recovers_a_known_pure_delay():
    t = DT * np.arange(3000)
    xd = 0.01 * np.sin(2 * math.pi * 1.5 * t)
    xm = 0.01 * np.sin(2 * math.pi * 1.5 * (t - 0.008))
    e = hil.tracking_error(xd, xm, DT)
    assert e['delay_s'] == pytest.approx(0.008, rel=0.02)
    # sine of amplitude A delayed by tau: error amplitude 2 A sin(pi f tau)
    amp = 2 * 0.01 * math.sin(math.pi * 1.5 * 0.008)
    assert e['peak_m'] == pytest.approx(amp, rel=1e-3)
    assert e['rms_m'] == pytest.approx(amp / math.sqrt(2), rel=1e-2)


def test_tracking_monitor_counts_non_finite_errors_apart_and_keeps_the_last():
    mon = hil.TrackingMonitor(DT)
    assert math.isnan(mon.as_dict()['rms_m']) and math.isnan(mon.as_dict()['peak_m'])
    mon.update(0.003, 0.1, 0.0)
    mon.update(math.nan, 0.1, 0.0)            # a NaN target: left out, counted
    mon.update(0.0, 0.1, math.inf)            # an infinite measurement: the same
    mon.update(0.0, math.nan, 0.004)          # no desired velocity: out of the delay only
    d = mon.as_dict()
    assert d['n'] == 2 and d['non_finite'] == 2 and d['last_m'] == pytest.approx(-0.004)
    assert d['peak_m'] == pytest.approx(0.004)
    assert d['rms_m'] == pytest.approx(math.sqrt((0.003 ** 2 + 0.004 ** 2) / 2))
    assert d['delay_s'] == pytest.approx(0.003 * 0.1 / 0.1 ** 2)
    mon.update(math.nan, 0.0, 0.0)
    assert math.isnan(mon.as_dict()['last_m']) and mon.as_dict()['n'] == 2
    mon.reset()
    assert mon.as_dict()['n'] == 0 and mon.as_dict()['non_finite'] == 0


@pytest.mark.parametrize('kind', ['first', 'second'])
def test_polynomial_compensation_cuts_tracking_error_on_a_sine(kind):
    act = ServoActuator(kind, DT, delay_s=0.002)
    plain = _track(act, None)
    act.reset()
    comp = hil.DelayCompensator(DT, act.equivalent_delay_s, order=2)
    compensated = _track(act, comp)
    assert plain['delay_s'] == pytest.approx(act.equivalent_delay_s, rel=0.15)
    assert compensated['rms_m'] < plain['rms_m'] / 4
    assert compensated['peak_m'] < plain['peak_m'] / 4
    assert abs(compensated['delay_s']) < 0.2 * plain['delay_s']


def test_adaptive_horizon_converges_to_the_true_delay():
    act = ServoActuator('ideal', DT, delay_s=0.010)
    comp = hil.DelayCompensator(DT, 0.0, order=2, adapt_gain=2.0)
    mon = hil.TrackingMonitor(DT)
    t = DT * np.arange(8000)
    xd = 0.01 * np.sin(2 * math.pi * 1.0 * t)
    vd = 0.01 * 2 * math.pi * np.cos(2 * math.pi * 1.0 * t)
    for k in range(t.size):
        xm = act.step(comp(xd[k]))[0]
        mon.update(xd[k], vd[k], xm)
        if (k + 1) % 100 == 0:
            comp.adapt(mon.recent_delay_s, 0.1)
    assert comp.delay_s == pytest.approx(0.010, abs=0.001)


def test_compensator_refuses_bad_settings():
    with pytest.raises(hil.HilError, match='order'):
        hil.DelayCompensator(DT, 0.01, order=5)
    with pytest.raises(hil.HilError, match='delay_s'):
        hil.DelayCompensator(DT, -0.01)


def test_remote_plant_refuses_a_future_stamp_and_follows_a_rig_clock_jump():
    """One measurement stamped +1e6 s costs that measurement; a jump back re-bases."""
    plant = hil.make_remote_plant(DT, compensation='none')
    now = 1.7e9                                                # the car's clock (ROS time)
    for k in range(10):
        assert plant.receive(5.0 + k * DT, 0.0, 0.0, 10.0 * k, 1.0, now=now + k * DT)
    assert not plant.receive(5.0 + 10 * DT + 1e6, 0.0, 0.0, 999.0, 1.0, now=now + 10 * DT)
    assert plant.receive(5.0 + 10 * DT, 0.0, 0.0, 100.0, 1.0, now=now + 10 * DT)
    assert plant.force_n == 100.0 and plant.counts['future_stamp'] == 1
    assert plant.counts['gaps'] == 0
    # the rig's clock jumps back 4 s: refused until the run re-bases, then taken again
    taken = [plant.receive(1.0 + k * DT, 0.0, 0.0, 7.0, 1.0, now=now + (11 + k) * DT)
             for k in range(60)]
    assert taken == [False] * 49 + [True] * 11
    assert plant.counts['out_of_order'] == 49 and plant.counts['stamp_rebases'] == 1
    assert plant.counts['gaps'] == 0 and plant.counts['measurements'] == 11 + 11


def test_remote_plant_counts_refused_gapped_and_stale_measurements():
    plant = hil.make_remote_plant(DT, compensation='none', stale_after_s=0.005)
    assert plant.step(DT, 0.01, 0.0, 1.0) == 0.0              # nothing measured yet
    assert not plant.answered
    assert plant.receive(0.0, 0.001, 0.0, 100.0, 1.0)
    assert plant.answered                                      # the rig took the command
    assert plant.step(DT, 0.01, 0.0, 1.0) == 100.0
    assert not plant.answered
    plant.count_wait(False)
    plant.count_wait(True)
    assert not plant.receive(math.nan, 0.0, 0.0, 0.0, 0.0)     # non-finite: refused
    assert not plant.receive(0.0, 0.0, 0.0, 0.0, 0.0)          # same stamp: refused
    assert not plant.receive(-0.5, 0.0, 0.0, 0.0, 0.0)         # older: refused
    assert plant.receive(0.004, 0.002, 0.0, 50.0, 1.5)         # 3 samples missing
    for _ in range(10):                                        # no new measurement: stale
        assert plant.step(DT, 0.01, 0.0, 1.0) == 50.0
    assert plant.current == 1.5 and plant.last_command_m == 0.01
    st = plant.as_dict()
    assert st['counts'] == {'measurements': 2, 'gaps': 3, 'out_of_order': 1, 'duplicate': 1,
                            'future_stamp': 0, 'stamp_rebases': 0, 'non_finite': 1,
                            'no_measurement_steps': 1, 'stale_steps': 5, 'wait_timeouts': 1}
    assert st['tracking']['n'] == 11
    assert st['tracking']['peak_m'] == pytest.approx(0.009)
    assert st['travel_rms_m'] == pytest.approx(0.01)
    with pytest.raises(hil.HilError, match='stale_after_s'):
        hil.make_remote_plant(DT, stale_after_s=0.0)
    with pytest.raises(hil.HilError, match='compensation'):
        hil.make_remote_plant(DT, compensation='smith')
