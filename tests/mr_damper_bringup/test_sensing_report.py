"""
Tests of mr_damper_bringup.sensing_report: the injected dropout in the summary (no ROS graph).

Synthetic recordings of the body accelerometer (the recorder node's CDR bytes): a dropout
window the car reached is reported as counted (or not) as fail-safe; one it never reached, as
not reached, never as a fail-safe that did not happen.
"""
import math

from mr_damper_bringup.recorder import SuiteRecorder
from mr_damper_bringup.sensing_report import format_sensing, sensing_summary
from mr_damper_bringup.topics import topic_table

T0 = 1000.0


def _imu_recording(path, end_s, nan_from=None, nan_to=None, rate_hz=100.0):
    """Write body accelerometer readings stamped 0..``end_s`` [s], NaN in the given span."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu
    with SuiteRecorder(path, topic_table(['body_imu'])) as rec:
        for k in range(int(end_s * rate_hz) + 1):
            t = k / rate_hz
            msg = Imu()
            msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(round(t % 1 * 1e9))
            lost = nan_from is not None and nan_from <= t < nan_to
            msg.linear_acceleration.z = math.nan if lost else 9.81
            rec.write('body_imu', serialize_message(msg), int((T0 + t) * 1e9))
    return path


def _car_status(window, t_sim):
    return {'t_sim': t_sim, 'sensing': {'dropout_window_s': list(window),
                                        'dropout_sensors': ['body_accel'], 'sensors': {}}}


def test_a_dropout_window_the_car_never_reached_is_not_reached(tmp_path):
    rec = _imu_recording(tmp_path / 'suite.mcap', end_s=5.0)
    s = sensing_summary({}, _car_status((12.0, 1.0), 5.0), [rec])
    assert s['dropout_reached'] is False and s['dropout_failsafe'] is None
    assert s['car_time_end_s'] == 5.0 and s['dropout_seen'] is None
    line = [x for x in format_sensing(s) if 'injected dropout' in x][0]
    assert "not reached (the car's time ended at 5.00 s)" in line
    assert 'fail-safe' not in line
    # without a recording, from the car's final status
    s = sensing_summary({}, _car_status((12.0, 1.0), 7.5), [])
    assert s['dropout_reached'] is False and s['car_time_end_s'] == 7.5


def test_a_reached_dropout_is_counted_as_fail_safe_or_not(tmp_path):
    rec = _imu_recording(tmp_path / 'suite.mcap', end_s=5.0, nan_from=2.0, nan_to=3.0)
    counted = {'estimator': {'invalid_entries': {'dropout_body_accel': 1}},
               'controller': {'state_rejected': {'non_finite': 40}}}
    s = sensing_summary(counted, _car_status((2.0, 1.0), 5.0), [rec])
    assert s['dropout_reached'] is True and s['dropout_failsafe'] is True
    assert s['dropout_seen'][2] == 100                  # 100 NaN readings in the window
    assert any('counted as fail-safe yes' in x for x in format_sensing(s))
    # reached, but the chain did not answer it: said loudly
    s = sensing_summary({}, _car_status((2.0, 1.0), 5.0), [rec])
    assert s['dropout_reached'] is True and s['dropout_failsafe'] is False
    assert any('counted as fail-safe NO' in x for x in format_sensing(s))
