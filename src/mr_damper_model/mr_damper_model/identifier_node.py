"""
Identifier node: live current-dependent Kwok identification of the measured MR damper.

``ros2 run mr_damper_model identifier_node`` (console script ``identifier_node``).

Subscribes to the measurement topic (``sensor_msgs/JointState``, one message per DAQ sample),
fits sliding windows with :mod:`mr_damper_model.live` in a worker thread (so the measurement
callbacks keep up with 1 kHz while a window is fitted) and publishes the kwok-current estimate
(``mr_damper_interfaces/KwokParameters``) and a JSON status (``std_msgs/String``).  The last valid
parameters are saved to ``params_file`` and reloaded at start-up.  Parameters: see the README
table or ``--ros-args -p name:=value``.
"""
import math
import os
import sys
import threading
import time

import numpy as np
from rclpy.node import Node
from rcl_interfaces.msg import ParameterDescriptor
from sensor_msgs.msg import JointState
from mr_damper_interfaces.msg import KwokParameters
from std_msgs.msg import String

from .data import DataError
from .identify import identify  # noqa: F401  (imported before the first window: no import stall)
from .live import FitProcess, LiveConfig, LiveIdentifier
from .messages import (MessageError, kwok_parameters_msg, measurement_from_msg, status_msg)
from .node_utils import (DropCounter, LATCHED_QOS, MEASUREMENT_QOS, run_node,
                         set_realtime_priority, STATUS_QOS)
from .params_file import load_params, save_params

#: Parameters: latched for late subscribers.
PARAMETERS_QOS = LATCHED_QOS

#: Samples kept for the stamp-age (latency) percentiles of the status.
_AGES = 10000

_LIVE_DESCRIPTIONS = {
    'window_s': 'Sliding window length [s]',
    'hop_s': 'Window hop [s] (one parameter update per hop)',
    'budget_s': 'Compute budget per window [s] (0: none)',
    'maxiter': 'PSO iterations per window (0: identify default)',
    'swarm_size': 'PSO particles',
    'seed': 'PSO seed of every window',
    'warm_start': 'Warm-start each window from the previous solution',
    'unbounded': 'Use the wide thesis-comparison bounds',
    'i_ref_a': 'Reference current of the kwok-current model [A]',
    'max_nrmse_percent': 'Validity threshold on the fit NRMSE [%]',
    'current_bin_a': 'Current bin width [A]',
    'min_bin_fraction': 'Bin used once it holds this fraction of a window',
    'bin_max_age_s': 'Drop current bins older than this [s] (0: never)',
    'max_fit_samples': 'Decimate fit data above this count (0: never)',
    'max_rate_hz': 'Highest expected sample rate [Hz] (buffer size)',
    'min_window_samples': 'Minimum samples in a window',
    'min_velocity_rms_m_s': 'Minimum velocity RMS of a window [m/s]',
    'min_force_std_n': 'Minimum force standard deviation of a window [N]',
    'min_direction_fraction': 'Minimum fraction of samples moving in each direction',
    'restart_samples': 'Consecutive increasing out-of-order samples that restart the stream',
    'force_limit_n': 'Reject samples with |force| above this [N]',
    'velocity_limit_m_s': 'Reject samples with |velocity| above this [m/s]',
    'displacement_limit_m': 'Reject samples with |displacement| above this [m]',
    'current_limit_min_a': 'Reject samples with a current below this [A]',
    'current_limit_max_a': 'Reject samples with a current above this [A]',
    'max_gap_s': 'Skip windows with a stamp step above this [s]',
    'outlier_mad_k': 'Outlier threshold in robust standard deviations (1.4826 MAD) of the '
                     'force from its 5-sample running median',
    'outlier_floor_fraction': 'Outlier threshold floor as a fraction of the robust force range',
    'stuck_s': 'A force exactly constant this long [s] is a stuck load cell (dropout at 0)',
    'max_error_ratio': 'Refuse a set whose RMSE on data covered by the last valid set exceeds '
                       'this times that set\'s (plus the floor)',
    'max_shift_ratio': 'Skip new samples the last valid set explains this times worse than '
                       'its own data in the same state cells (plus the floor)',
    'error_floor_percent': 'Floor of both comparisons [% of the robust force range]',
    'pinned_fraction': 'Refuse sets with a parameter this fraction of its bound span from a '
                       'non-zero bound',
    'inconsistent_reset_s': 'Forget the reference and bins after this long of consecutive '
                            'inconsistent windows [s] (0: never; a persistent sensor fault is '
                            'then identified as the damper)',
}


class IdentifierNode(Node):
    """Thin ROS adapter over :class:`mr_damper_model.live.LiveIdentifier`."""

    def __init__(self):
        super().__init__('mr_damper_identifier')
        defaults = LiveConfig()
        for name, description in _LIVE_DESCRIPTIONS.items():
            self.declare_parameter(name, getattr(defaults, name),
                                   ParameterDescriptor(description=description))
        self.declare_parameter('measurement_topic', '/mr_damper/measurement')
        self.declare_parameter('parameters_topic', '/mr_damper/kwok_parameters')
        self.declare_parameter('status_topic', '/mr_damper/identifier_status')
        self.declare_parameter('params_file', '', ParameterDescriptor(
            description='JSON file of the last valid parameters (read at start, written on '
                        'updates); empty: none'))
        self.declare_parameter('save_period_s', 2.0, ParameterDescriptor(
            description='Minimum wall time between parameter-file writes [s]'))
        self.declare_parameter('fit_in_process', True, ParameterDescriptor(
            description='Fit windows in a worker process (the receiving threads never wait '
                        'for the GIL held by a fit); false: in a thread of this process'))
        self.declare_parameter('realtime_priority', 0, ParameterDescriptor(
            description='SCHED_FIFO priority of the receiving threads (0: normal scheduling)'))
        self.declare_parameter('status_period_s', 0.2, ParameterDescriptor(
            description='Status publication period [s]'))
        p = self.get_parameter
        config = LiveConfig(**{name: p(name).value for name in _LIVE_DESCRIPTIONS})
        self._params_file = p('params_file').value
        self._save_period = float(p('save_period_s').value)
        self._fit_process = FitProcess() if p('fit_in_process').value else None
        fit = self._fit_process
        initial = None
        self._initial_source = 'none'
        if self._params_file and os.path.exists(self._params_file):
            try:
                initial = load_params(self._params_file)
                self._initial_source = 'file'
            except DataError as exc:
                self.get_logger().error(f'ignoring parameter file: {exc}')
                self._initial_source = 'file_error'
        try:
            self.live = LiveIdentifier(config, initial=initial, fit=fit)
        except (ValueError, KeyError) as exc:
            self.get_logger().error(f'ignoring parameter file {self._params_file}: {exc}')
            self._initial_source = 'file_error'
            self.live = LiveIdentifier(config, fit=fit)

        self.drops = DropCounter(self.get_logger())
        self._pub_params = self.create_publisher(
            KwokParameters, p('parameters_topic').value, PARAMETERS_QOS)
        self._pub_status = self.create_publisher(String, p('status_topic').value, STATUS_QOS)
        self._ages = np.zeros(_AGES)
        self._n_ages = 0
        self._published = 0
        self._saved = 0
        self._last_save = -math.inf
        self._pending_save = None
        self._stop = threading.Event()
        if self.live.estimate is not None:   # latched at once: it needs no fit process
            est = self.live.estimate
            self.get_logger().info(
                f'initial parameters from {self._params_file} '
                f'({"valid" if est.valid else "not valid: " + est.reason})')
            self._publish_estimate(est)
        # ready to fit before subscribing: the fit process imports numpy, scipy and the models
        # (1-4 s on a busy machine); a publisher waiting for subscribers waits for this node
        self._fit_ready = self._warm_up()
        # samples the rig's bounded history dropped before this node took them (stalled or
        # restarted identifier) are reported by the middleware and counted as `message_lost`
        self.drops.subscribe(self, JointState, p('measurement_topic').value,
                             self._on_measurement, MEASUREMENT_QOS, 'message_lost')
        self.create_timer(float(p('status_period_s').value), self._publish_status)
        self._realtime = set_realtime_priority(int(p('realtime_priority').value),
                                               self.get_logger())
        self._worker = threading.Thread(target=self._work, name='identifier_fit', daemon=True)
        self._worker.start()
        self.get_logger().info(
            f'identifying {p("measurement_topic").value} -> {p("parameters_topic").value}: '
            f'window {config.window_s} s every {config.hop_s} s, budget {config.budget_s} s')

    def _warm_up(self):
        """Start the fit process and import the fitting code in it; return True if ready."""
        if self._fit_process is None:
            return True          # in-thread fits: identify was imported with this module
        start = time.monotonic()
        try:
            self._fit_process.warm_up()
        except Exception as exc:  # the first fit will retry and report
            self.get_logger().warning(f'fit process did not start: {exc}')
            return False
        self.get_logger().info(f'fit process ready in {time.monotonic() - start:.2f} s')
        return True

    # measurement callback: conversion and checks only (the fit runs in the worker thread)
    def _on_measurement(self, msg):
        try:
            sample = measurement_from_msg(msg)
        except MessageError as exc:
            self.live.count_rejected(exc.reason)
            self.get_logger().warning(f'rejected measurement: {exc}', throttle_duration_sec=1.0)
            return
        reason = self.live.add_sample(*sample)
        # stamp age at receipt [s]: the transport latency when stamps are wall-clock time
        self._ages[self._n_ages % _AGES] = self.get_clock().now().nanoseconds * 1e-9 - sample[0]
        self._n_ages += 1
        if reason:
            self.get_logger().warning(f'rejected measurement at t={sample[0]:.6f} s: {reason}',
                                      throttle_duration_sec=1.0)

    def _work(self):
        if self._realtime:   # fits run at normal priority, below the receiving threads
            try:
                os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
            except OSError:
                pass
        while not self._stop.is_set():
            window = self.live.next_window()
            if window is None:
                self._stop.wait(0.005)
                continue
            try:
                est = self.live.process(window)
            except Exception as exc:  # never let one window kill the node
                if self._stop.is_set():   # the fit process was ended by shutdown()
                    break
                self.live.counters['fit_errors'] += 1
                self.live.last_error = f'{type(exc).__name__}: {exc}'
                self.get_logger().error(f'window fit failed: {self.live.last_error}',
                                        throttle_duration_sec=5.0)
                continue
            if est is None:
                if self.live.last_skip in ('inconsistent', 'gap'):
                    self.get_logger().warning(
                        f'window ending at {window.end_s:.3f} s skipped: {self.live.last_skip}'
                        ' (sensor fault suspected; see the status counters)',
                        throttle_duration_sec=2.0)
                continue
            if not est.valid:
                self.get_logger().warning(
                    f'window ending at {est.window_end_s:.3f} s: parameters not valid '
                    f'({est.reason})', throttle_duration_sec=2.0)
            self._publish_estimate(est)
            if est.valid:
                self._save(est)

    def _publish_estimate(self, est):
        if self.drops.publish(self._pub_params, kwok_parameters_msg(
                est.message_values(), stamp_s=self.get_clock().now().nanoseconds * 1e-9),
                              'parameters_publish_failed'):
            self._published += 1

    def _save(self, est, force=False):
        if not self._params_file:
            return
        now = time.monotonic()
        if not force and now - self._last_save < self._save_period:
            self._pending_save = est
            return
        try:
            save_params(self._params_file, est.params_file_dict())
            self._saved += 1
            self._last_save = now
            self._pending_save = None
        except OSError as exc:
            self.get_logger().error(f'cannot write {self._params_file}: {exc}',
                                    throttle_duration_sec=10.0)

    def _publish_status(self):
        if self._pending_save is not None:
            self._save(self._pending_save)
        status = self.live.status()
        ages = self._ages[:min(self._n_ages, _AGES)]
        if ages.size:
            p50, p99 = np.percentile(ages, [50, 99]) * 1e3
            status['stamp_age_ms'] = {'p50': p50, 'p99': p99, 'max': float(ages.max()) * 1e3,
                                      'n': int(ages.size)}
        status.update(parameters_published=self._published, params_file_writes=self._saved,
                      initial_source=self._initial_source, worker_alive=self._worker.is_alive(),
                      realtime=self._realtime, fit_ready_at_subscribe=self._fit_ready,
                      dropped=self.drops.counts())
        self.drops.publish(self._pub_status, status_msg(status))

    def shutdown(self):
        """Stop the worker and write the last valid parameters (well within 2 s)."""
        self._stop.set()
        if self._fit_process is not None:
            # a fit in progress ends with its process (the worker sees a failed fit and stops)
            self._fit_process.close(wait_s=0.5)
        self._worker.join(timeout=1.0)
        if self.live.last_good is not None and self.live.last_good.model_fitted != 'file':
            self._save(self.live.last_good, force=True)


def main(args=None):
    """Run the identifier node until Ctrl-C."""
    # short GIL switch interval: measurement callbacks are not held up by a fit for long
    sys.setswitchinterval(0.001)
    # ValueError: bad parameter values (LiveConfig names the parameter)
    return run_node(IdentifierNode, 'identifier_node', (ValueError,),
                    finish=lambda node: node.shutdown(), args=args)


if __name__ == '__main__':
    sys.exit(main())
