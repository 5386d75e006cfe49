"""
Identifier node: live current-dependent Kwok identification of the measured MR damper.

``ros2 run mr_damper_model identifier_node`` (console script ``identifier_node``).

Subscribes to ``mr_damper/measurement`` (``mr_damper_interfaces/DamperSamples``, batches of DAQ
samples taken as arrays; samples missing between batches are counted exactly from their stream
index, ``stream.lost``) and ``mr_damper/joint_measurement`` (``sensor_msgs/JointState``, one
message per sample, for DAQ drivers that publish that layout) and publishes the kwok-current
estimate on ``mr_damper/kwok_parameters`` (``mr_damper_interfaces/KwokParameters``, latched), the
count of samples received on ``mr_damper/samples_received`` (``std_msgs/UInt64``, every 0.1 s: the
rig's flow control reads it) and its health on ``/diagnostics``. Topic names are relative: remap
them (``-r mr_damper/measurement:=/fl/measurement``) or give the node a namespace (``-r
__ns:=/fl``). The work is done by :class:`mr_damper_model.live.worker.IdentifierRuntime` over
:class:`mr_damper_model.live.LiveIdentifier`; this file converts messages.

With ``use_sim_time:=true`` (a replay publishing ``/clock``) every time the node uses is ROS
time and every due window is fitted in order with an iteration-count stop (``backlog_windows``
of :class:`~mr_damper_model.live.LiveConfig` = ``sim_backlog_windows``), so the parameter
sequence does not depend on the replay speed.  Parameters: ``PARAMETERS`` (docs/nodes.md).
"""
import os
import sys
import time

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import JointState
from mr_damper_interfaces.msg import DamperSamples, KwokParameters
from std_msgs.msg import UInt64

from mr_damper_model.io.data import DataError
# imported before the first window: no import stall
from mr_damper_model.identification.identify import identify  # noqa: F401
from mr_damper_model.live import DYNAMIC_FIELDS, FitProcess, LiveConfig, LiveIdentifier
from mr_damper_model.live.worker import IdentifierRuntime
from mr_damper_common.messages import (kwok_parameters_msg, measurement_from_msg, MessageError,
                                       samples_from_msg)
from mr_damper_common.node_utils import (declare_parameters, DiagnosticsPublisher, DropCounter,
                                         PARAMETERS_QOS, MEASUREMENT_QOS, node_time_s, Param,
                                         run_node, set_realtime_priority, STATUS_QOS)
from mr_damper_model.io.params_file import load_params, save_params

#: Relative topic names: the rig's batches (``mr_damper_interfaces/DamperSamples``) and, for DAQ
#: drivers that publish one ``sensor_msgs/JointState`` per sample, the single-sample layout.
MEASUREMENT = 'mr_damper/measurement'
JOINT_MEASUREMENT = 'mr_damper/joint_measurement'

#: Period of ``mr_damper/samples_received`` [s, wall time: it paces the transport].
SAMPLES_RECEIVED_PERIOD_S = 0.1

_D = LiveConfig()
_BIG = 1e9
#: LiveConfig settings: name, description, low, high (dynamic: those in live.DYNAMIC_FIELDS).
_LIVE = (
    ('window_s', 'Sliding window length [s]', 0.05, 3600.0),
    ('hop_s', 'Window hop [s] (one parameter update per hop; at most window_s)', 0.001, 3600.0),
    ('budget_s', 'Compute budget per window [s] (0: none; ignored under use_sim_time)',
     0.0, 3600.0),
    ('maxiter', 'PSO iterations per window (0: identify default)', 0, 1000000),
    ('swarm_size', 'PSO particles', 2, 100000),
    ('seed', 'PSO seed of every window (under use_sim_time: of window 0, the others derived '
     'from it)', 0, 2 ** 31 - 1),
    ('warm_start', 'Warm-start each window from the previous solution', None, None),
    ('unbounded', 'Use the wide thesis-comparison bounds', None, None),
    ('i_ref_a', 'Reference current of the kwok-current model [A]', 0.001, 1000.0),
    ('max_nrmse_percent', 'Validity threshold on the fit NRMSE [%]', 1e-6, 1000.0),
    ('current_bin_a', 'Current bin width [A]', 1e-4, 100.0),
    ('min_bin_fraction', 'Bin used once it holds this fraction of a window [1]', 0.0, 1.0),
    ('bin_max_age_s', 'Drop current bins older than this [s] (0: never)', 0.0, _BIG),
    ('max_fit_samples', 'Decimate fit data above this count [samples] (0: never)', 0, 10 ** 8),
    ('max_rate_hz', 'Highest expected sample rate [Hz] (buffer size)', 1.0, 1e6),
    ('min_window_samples', 'Minimum samples in a window [samples]', 0, 10 ** 8),
    ('min_velocity_rms_m_s', 'Minimum velocity RMS of a window [m/s]', 0.0, 1000.0),
    ('min_force_std_n', 'Minimum force standard deviation of a window [N]', 0.0, _BIG),
    ('min_direction_fraction', 'Minimum fraction of samples moving in each direction [1]',
     0.0, 0.5),
    ('restart_samples', 'Consecutive increasing out-of-order samples that restart the stream '
     '[samples]', 1, 10 ** 8),
    ('max_future_s', 'Refuse a batch stamped more than this ahead of the stream\'s own clock '
     '(its newest stamp advanced at its measured rate) [s] (future_stamp; 0: no check)', 0.0,
     _BIG),
    ('force_limit_n', 'Reject samples with a force magnitude above this [N]', 1e-6, _BIG),
    ('velocity_limit_m_s', 'Reject samples with a velocity magnitude above this [m/s]',
     1e-9, 1e6),
    ('displacement_limit_m', 'Reject samples with a displacement magnitude above this [m]',
     1e-9, 1e3),
    ('current_limit_min_a', 'Reject samples with a current below this [A]', -1000.0, 1000.0),
    ('current_limit_max_a', 'Reject samples with a current above this [A]', -1000.0, 1000.0),
    ('max_gap_s', 'Skip windows with a stamp step above this [s]', 1e-9, 3600.0),
    ('outlier_mad_k', 'Outlier threshold in robust standard deviations (1.4826 MAD) of the '
     'force from its 5-sample running median [1]', 1e-6, 1e6),
    ('outlier_floor_fraction', 'Outlier threshold floor as a fraction of the robust force '
     'range [1]', 0.0, 100.0),
    ('stuck_s', 'A force exactly constant this long [s] is a stuck load cell (dropout at 0)',
     1e-6, _BIG),
    ('max_error_ratio', 'Refuse a set whose RMSE on data covered by the last valid set exceeds '
     'this times that set\'s (plus the floor) [1]', 1e-6, 1e6),
    ('max_shift_ratio', 'Skip new samples the last valid set explains this times worse than '
     'its own data in the same state cells (plus the floor) [1]', 1e-6, 1e6),
    ('error_floor_percent', 'Floor of both comparisons [% of the robust force range]',
     0.0, 1000.0),
    ('pinned_fraction', 'Refuse sets with a parameter this fraction of its bound span from a '
     'non-zero bound [1]', 0.0, 0.499),
    ('inconsistent_reset_s', 'Forget the reference and bins after this long of consecutive '
     'inconsistent windows [s] (0: never; a persistent sensor fault is then identified as the '
     'damper)', 0.0, _BIG),
    ('acceptance_checks', 'Review each valid set before it replaces the set in use (excitation, '
     'comparison on the newest window and held-back data, force offsets); a refused set is '
     'counted and the set in use re-published', None, None),
    ('min_amplitude_ratio', 'Refuse a set whose window velocity amplitude at a current level is '
     'below this fraction of the set in use\'s [1]', 0.0, 1.0),
    ('velocity_bins', 'Velocity bins over +- the amplitude of each current level [bins]',
     2, 1000),
    ('min_velocity_bin_share', 'Refuse a set with a velocity bin holding less than this share '
     'of its level\'s samples [1]', 0.0, 0.5),
    ('max_condition_number', 'Refuse a set whose separable least-squares problem at a level '
     'has a larger condition number (unit-norm columns) [1]', 1.0, 1e12),
    ('replace_margin', 'A new set must beat the set in use by this fraction of its RMS error on '
     'the newest window and on held-back data (0: at least as good) [1]', 0.0, 0.99),
    ('holdout_s', 'Held-back data: admitted samples of this long before the window, longer '
     'to the second most recent velocity reversal (both stroke ends) [s]', 1e-3, 3600.0),
    ('holdout_max_s', 'Longest held-back part (a slow excitation) [s]', 1e-3,
     3600.0),
    ('offset_window_s', 'Running-median length of the force-offset screen [s]', 1e-4, 60.0),
    ('offset_ratio', 'Flag a force offset beyond this times the RMS error of the set in use '
     '(plus the error floor) [1]', 1e-3, 1e6),
    ('drift_window_s', 'The f0 trend (status) is the slope over the accepted sets of this long '
     '[s]', 1.0, _BIG),
    ('force_step_percent', 'Refuse a set whose own fit data holds a force step: comparable '
     'whole cycles whose mean forces differ, or a lasting mid-stroke jump of its residual, '
     'beyond this [% of the robust force range] (0: no check)', 0.0, 100.0),
)

#: Every parameter of the node (the one place they are declared).
PARAMETERS = tuple(
    Param(name, getattr(_D, name), description, low, high, dynamic=name in DYNAMIC_FIELDS)
    for name, description, low, high in _LIVE) + (
    Param('params_file', '', 'JSON file of the last valid parameters (read at start, written '
          'on updates); empty: none'),
    Param('save_period_s', 2.0, 'Minimum time between parameter-file writes [s] (ROS time)',
          0.0, 86400.0, dynamic=True),
    Param('fit_in_process', True, 'Fit windows in a worker process (the receiving threads '
          'never wait for the GIL held by a fit); false: in a thread of this process'),
    Param('realtime_priority', 0, 'SCHED_FIFO priority of the receiving threads (0: normal '
          'scheduling)', 0, 99),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s] (wall time)',
          0.01, 3600.0),
    Param('no_sample_timeout_s', 5.0, 'Diagnostics ERROR after this long without a sample [s] '
          '(ROS time; 0: never)', 0.0, _BIG, dynamic=True),
    Param('sim_backlog_windows', 300, 'Under use_sim_time: due windows held for in-order '
          'fitting [windows] (more are passed over and counted: windows_overflow)', 1, 100000),
)


class IdentifierNode(Node):
    """Thin ROS adapter over :class:`mr_damper_model.live.worker.IdentifierRuntime`."""

    def __init__(self, **node_kwargs):
        super().__init__('mr_damper_identifier', **node_kwargs)
        p = declare_parameters(self, PARAMETERS, self._on_set)
        sim_time = bool(self.get_parameter('use_sim_time').value)
        config = LiveConfig(**{name: p[name] for name, *_ in _LIVE},
                            backlog_windows=p['sim_backlog_windows'] if sim_time else 0)
        params_file = p['params_file']
        fit = FitProcess() if p['fit_in_process'] else None
        initial, source = None, 'none'
        if params_file and os.path.exists(params_file):
            try:
                initial, source = load_params(params_file), 'file'
            except DataError as exc:
                self._refuse_file(params_file, exc)
                source = 'file_error'
        try:
            live = LiveIdentifier(config, initial=initial, fit=fit)
        except (ValueError, KeyError) as exc:
            self._refuse_file(params_file, exc)
            source = 'file_error'
            live = LiveIdentifier(config, fit=fit)
        # a file it cannot resume from (e.g. an offline kwok-current-lag fit) is the user's:
        # never overwritten
        save = ((lambda est: save_params(params_file, est.params_file_dict()))
                if params_file and source != 'file_error' else None)
        self.runtime = IdentifierRuntime(
            live, self._now, save=save, save_period_s=p['save_period_s'], fit_process=fit,
            no_sample_timeout_s=p['no_sample_timeout_s'], initial_source=source)
        self.drops = DropCounter(self.get_logger())
        self._pub_params = self.create_publisher(KwokParameters, 'mr_damper/kwok_parameters',
                                                 PARAMETERS_QOS)
        self._pub_received = self.create_publisher(UInt64, 'mr_damper/samples_received',
                                                   STATUS_QOS)
        self._received_msg = UInt64()
        if live.estimate is not None:   # latched at once: it needs no fit process
            est = live.estimate
            self.get_logger().info(f'initial parameters from {params_file} '
                                   f'({"valid" if est.valid else "not valid: " + est.reason})')
            self._publish_estimate(est)
        # ready to fit before subscribing: the fit process imports numpy, scipy and the models
        # (1-4 s on a busy machine); a publisher waiting for subscribers waits for this node
        self.runtime.fit_ready = self._warm_up(fit)
        # batches that never reached this node (stalled or restarted identifier, a writer the
        # rig replaced) are counted from their sequence numbers as `message_lost`
        self.drops.subscribe(self, DamperSamples, MEASUREMENT, self._on_samples,
                             MEASUREMENT_QOS, 'message_lost')
        # a DAQ driver that publishes one sensor_msgs/JointState per sample (suite layout): no
        # sequence; a gap in its stamps skips the window (`windows_skipped.gap`)
        self.drops.subscribe(self, JointState, JOINT_MEASUREMENT, self._on_measurement,
                             MEASUREMENT_QOS)
        # wall-time timer: the count paces the rig's transport (a stopped /clock must not stop
        # it, or a rig waiting for the count before it advances the clock would wait forever)
        self.create_timer(SAMPLES_RECEIVED_PERIOD_S, self._publish_received,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics = DiagnosticsPublisher(
            self, self._health, period_s=p['diagnostics_period_s'], hardware_id='mr_damper',
            drops=self.drops)
        self._realtime = set_realtime_priority(p['realtime_priority'], self.get_logger())
        self.runtime.start(self._on_outcome, normal_priority=self._realtime)
        self.get_logger().info(
            f'identifying {self.resolve_topic_name(MEASUREMENT)} -> '
            f'{self.resolve_topic_name("mr_damper/kwok_parameters")}: window {config.window_s} s'
            f' every {config.hop_s} s, '
            + (f'every window in order (sim time), maxiter {config.maxiter}' if sim_time else
               f'budget {config.budget_s} s'))

    def _refuse_file(self, params_file, exc):
        self.get_logger().error(
            f'parameter file {params_file} not resumed and not overwritten ({exc}); the '
            'identifier fits kwok-current: set params_file to another path to save its sets')

    def _now(self):
        """ROS time [s] (sim time under ``use_sim_time``)."""
        return node_time_s(self)

    def _warm_up(self, fit):
        """Start the fit process and import the fitting code in it; return True if ready."""
        if fit is None:
            return True          # in-thread fits: identify was imported with this module
        start = time.monotonic()  # wall time: how long the process start took
        try:
            fit.warm_up()
        except Exception as exc:  # noqa: B902 - the first fit will retry and report
            self.get_logger().warning(f'fit process did not start: {exc}')
            return False
        self.get_logger().info(f'fit process ready in {time.monotonic() - start:.2f} s')
        return True

    def _on_set(self, changes):
        """Apply dynamic parameters (validated by ``LiveIdentifier.reconfigure``)."""
        live_changes = {k: v for k, v in changes.items() if k in DYNAMIC_FIELDS}
        try:
            self.runtime.live.reconfigure(**live_changes)
        except ValueError as exc:
            return str(exc)
        if 'no_sample_timeout_s' in changes:
            self.runtime.health_rules.no_sample_timeout_s = float(changes['no_sample_timeout_s'])
        if 'save_period_s' in changes and self.runtime.saver is not None:
            self.runtime.saver.period_s = float(changes['save_period_s'])
        return ''

    # measurement callbacks: conversion only (the fit runs in the runtime's worker thread)
    def _on_samples(self, msg):
        try:
            t, x, v, f, i = samples_from_msg(msg)
        except MessageError as exc:
            self.runtime.reject(exc.reason)
            self.get_logger().warning(f'rejected measurement batch: {exc}',
                                      throttle_duration_sec=1.0)
            return
        rejected = self.runtime.receive_batch(t, x, v, f, i, first_index=msg.first_index,
                                              period_s=msg.sample_period_s)
        if rejected:
            k, reason = rejected[0]
            self.get_logger().warning(
                f'rejected {len(rejected)} of {len(t)} samples of batch {msg.sequence}, first '
                f'at t={t[k]:.6f} s: {reason}', throttle_duration_sec=1.0)

    def _on_measurement(self, msg):
        try:
            sample = measurement_from_msg(msg)
        except MessageError as exc:
            self.runtime.reject(exc.reason)
            self.get_logger().warning(f'rejected measurement: {exc}', throttle_duration_sec=1.0)
            return
        reason = self.runtime.receive(*sample)
        if reason:
            self.get_logger().warning(f'rejected measurement at t={sample[0]:.6f} s: {reason}',
                                      throttle_duration_sec=1.0)

    def _on_outcome(self, outcome):
        """Worker thread: publish an estimate, log skips and errors; True if published."""
        log = self.get_logger()
        if outcome.error:
            log.error(f'window fit failed: {outcome.error}', throttle_duration_sec=5.0)
            return False
        est = outcome.estimate
        if est is None:
            if outcome.skip in ('inconsistent', 'gap'):
                log.warning(f'window ending at {outcome.end_s:.3f} s skipped: {outcome.skip} '
                            '(sensor fault suspected; see the diagnostics)',
                            throttle_duration_sec=2.0)
            return False
        if not est.valid:
            log.warning(f'window ending at {est.window_end_s:.3f} s: parameters not valid '
                        f'({est.reason})', throttle_duration_sec=2.0)
        return self._publish_estimate(est)

    def _publish_estimate(self, est):
        return self.drops.publish(self._pub_params, kwok_parameters_msg(
            est.message_values(), stamp_s=self._now()), 'parameters_publish_failed')

    def _publish_received(self):
        self._received_msg.data = int(self.runtime.live.counters['samples_received'])
        self.drops.publish(self._pub_received, self._received_msg,
                           'samples_received_publish_failed')
        error = self.runtime.flush_saves()
        if error:
            self.get_logger().error(f'cannot write the parameter file: {error}',
                                    throttle_duration_sec=10.0)

    def _health(self):
        return self.runtime.health({'dropped': self.drops.counts(), 'realtime': self._realtime,
                                    'use_sim_time': self.runtime.live.config.backlog_windows > 0})

    def shutdown(self):
        """Stop the worker and write the last valid parameters (well within 2 s)."""
        error = self.runtime.shutdown(wait_s=1.0)
        if error:
            self.get_logger().error(f'cannot write the parameter file: {error}')


def main(args=None):
    """Run the identifier node until Ctrl-C."""
    # short GIL switch interval: measurement callbacks are not held up by a fit for long
    sys.setswitchinterval(0.001)
    # ValueError: bad parameter values (LiveConfig names the parameter)
    return run_node(IdentifierNode, 'identifier_node', (ValueError,),
                    finish=lambda node: node.shutdown(), args=args)


if __name__ == '__main__':
    sys.exit(main())
