"""
The ``sensing`` section of a suite run on estimated states (``mr-damper-suite --sensing vehicle``).

No ROS. From the recording (``suite.mcap``): the estimates the state estimator published on
``/quarter_car/car_state`` against the car's true state on ``/quarter_car/true_state``, and the
sequence of the estimate's modes (valid, or invalid and why); from the nodes' last statuses: the
estimator's steps and invalid counts, the controller's answers to refused states (its safe
current) and the car's sensor counts with the injected dropout.

Alignment. An estimator clocked by the readings (``clock: readings``, the suite's setting) stamps
each estimate with the readings' stamp, the car's simulated time, as the true state is: the two
are paired by stamps. An estimator on its own timer stamps with its node clock: then the
recorder's receive times pair them, the true state interpolated at the estimate's receive time
less a lag (0 .. 10 ms) chosen to minimise the travel error (travel is measured to 0.05 mm), and
the errors include what is left of the transport delay. ``aligned_by`` says which.
"""
from array import array

import numpy as np

from .topics import SENSING_TOPICS, SUITE_TOPICS

#: states compared: name -> how to read it from a QuarterCarState (estimate or truth)
STATES = {
    'travel': lambda m: m.suspension_travel_m,
    'v_s': lambda m: m.body_velocity_m_s,
    'tyre_def': lambda m: m.wheel_displacement_m - m.road_height_m,
    'v_u': lambda m: m.wheel_velocity_m_s,
    'v_rel': lambda m: m.suspension_velocity_m_s,
    'a_s': lambda m: m.body_acceleration_m_s2,
}
#: estimates kept for the error figures (10 min at 1 kHz; later ones are counted, not used)
MAX_ROWS = 600_000
#: lags tried for the alignment [s]
LAGS_S = np.arange(0.0, 0.0101, 0.00025)
#: runs of the estimate's mode kept in the summary
MAX_RUNS = 200


def read_estimates(parts, dropout_window=None):
    """
    Read the estimates, the true states and the lost body accelerometer readings of a recording.

    Parameters
    ----------
    parts : list of path
        The recording's files (one pass each).
    dropout_window : sequence of (float, float), optional
        ``(start_s, duration_s)`` of the injected dropout [s, car time: the readings' stamps].

    Returns
    -------
    dict
        ``est`` and ``true``: ``{'t': receive times [s], state: values}`` as arrays (valid
        estimates only), ``runs`` (``[reason, messages, first_s, last_s]`` of consecutive
        estimates with the same ``fail_safe_reason``, ``'ok'`` when valid), ``dropout_seen``
        (``[first_s, last_s, n]`` of the lost (NaN) body accelerometer readings stamped inside
        the dropout window, or None), ``estimates``, ``valid``, ``truncated`` (estimates past
        :data:`MAX_ROWS`), ``imu_last_stamp_s`` (the latest stamp of a body accelerometer
        reading [s, car time], None without any: how far the car got). Times in seconds since
        the first message of these topics (receive times of the recorder).

    """
    from mr_damper_model.io.bag_types import suite_typestore
    from mr_damper_common.recording.mcap_scan import McapScan
    est_topic = SUITE_TOPICS['car_state'].name
    true_topic = SENSING_TOPICS['true_state'].name
    imu_topic = SENSING_TOPICS['body_imu'].name
    window = None
    if dropout_window is not None and len(dropout_window) == 2:
        window = (float(dropout_window[0]), float(dropout_window[0]) + float(dropout_window[1]))
    seen = imu_last = None
    typestore = suite_typestore()
    cols = {side: {k: array('d') for k in ('t', 'stamp', *STATES)} for side in ('est', 'true')}
    runs = []
    n = n_valid = truncated = 0
    t0 = None
    for part in parts:
        reader = McapScan(part)
        for topic, msgtype, t_ns, raw in reader.messages({est_topic, true_topic, imu_topic}):
            t = t_ns * 1e-9
            t0 = t if t0 is None else t0
            msg = reader.deserialize(raw, msgtype, typestore)
            if topic == imu_topic:
                stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
                imu_last = stamp if imu_last is None else max(imu_last, stamp)
                if (window is not None and window[0] <= stamp < window[1]
                        and msg.linear_acceleration.z != msg.linear_acceleration.z):
                    seen = [t - t0, t - t0, 0] if seen is None else seen
                    seen[1], seen[2] = t - t0, seen[2] + 1
                continue
            side = 'est' if topic == est_topic else 'true'
            if side == 'est':
                n += 1
                reason = 'ok' if int(msg.fail_safe_mode) == 0 else str(
                    msg.fail_safe_reason)
                if runs and runs[-1][0] == reason:
                    runs[-1][1] += 1
                    runs[-1][3] = t - t0
                elif len(runs) < MAX_RUNS:
                    runs.append([reason, 1, t - t0, t - t0])
                if reason != 'ok':
                    continue
                n_valid += 1
            if len(cols[side]['t']) >= MAX_ROWS:
                truncated += side == 'est'
                continue
            values = [f(msg) for f in STATES.values()]
            if not np.all(np.isfinite(values)):
                continue
            cols[side]['t'].append(t)
            cols[side]['stamp'].append(msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec)
            for k, v in zip(STATES, values):
                cols[side][k].append(v)
    arrays = {side: {k: np.frombuffer(v, dtype=float) if len(v) else np.zeros(0)
                     for k, v in c.items()} for side, c in cols.items()}
    return {**arrays, 'runs': runs, 'dropout_seen': seen, 'estimates': n, 'valid': n_valid,
            'truncated': truncated, 'imu_last_stamp_s': imu_last}


def estimation_errors(est, true):
    """
    Return the RMS error of each state of the valid estimates against the true state.

    Returns
    -------
    dict or None
        ``rms_error`` and ``rms_true`` per state [SI], ``rel_error`` (their ratio),
        ``pairs`` compared, ``lag_s`` of the alignment (see the module docstring); None when
        there is no estimate inside the span of true states.

    """
    if est['t'].size < 2 or true['t'].size < 2:
        return None
    # the estimate stamped with the readings' (car) time: pair by stamps, else receive times
    base = 'stamp' if (est['stamp'][0] >= true['stamp'][0]
                       and est['stamp'][-1] <= true['stamp'][-1]) else 't'
    tt = true[base]
    best = None
    for lag in LAGS_S:
        t = est[base] - lag
        inside = (t >= tt[0]) & (t <= tt[-1])
        if np.count_nonzero(inside) < 2:
            continue
        err = est['travel'][inside] - np.interp(t[inside], tt, true['travel'])
        rms = float(np.sqrt(np.mean(err ** 2)))
        if best is None or rms < best[0]:
            best = (rms, lag, inside)
    if best is None:
        return None
    _, lag, inside = best
    t = est[base][inside] - lag
    out = {'pairs': int(np.count_nonzero(inside)), 'lag_s': float(lag),
           'aligned_by': 'stamps' if base == 'stamp' else 'receive_times', 'rms_error': {},
           'rms_true': {}, 'rel_error': {}}
    for k in STATES:
        ref = np.interp(t, tt, true[k])
        e = float(np.sqrt(np.mean((est[k][inside] - ref) ** 2)))
        r = float(np.sqrt(np.mean(ref ** 2)))
        out['rms_error'][k], out['rms_true'][k] = e, r
        out['rel_error'][k] = e / r if r > 0 else None
    return out


def sensing_summary(status, car_status, parts):
    """
    Return the ``sensing`` section of the summary.

    Parameters
    ----------
    status : dict
        The last status of each node (``read_recording(...)['status']``): ``estimator``,
        ``controller``.
    car_status : dict
        The car's final status (its log's header): ``sensing`` (sensor counts, dropout window).
    parts : list of path
        The recording's files.

    Returns
    -------
    dict
        ``estimator`` (steps, invalid steps and entries by reason, lost samples, readings),
        ``controller`` (``state_rejected``, fail-safe entries and time, commands),
        ``car_sensors``, ``estimate_runs`` and ``dropout_seen`` (:func:`read_estimates`),
        ``estimates``, ``valid_estimates``,
        ``dropout_failsafe`` (an invalid ``dropout_*`` entry counted by the estimator and states
        refused by the controller; None when the car never reached the dropout window),
        ``dropout_reached`` (the car's time got to the window's start: the latest body
        accelerometer stamp recorded, else the car's final ``t_sim``; None when neither is
        known; only with a dropout window), ``car_time_end_s`` (that time),
        ``estimation_error`` (:func:`estimation_errors`).

    """
    est = status.get('estimator') or {}
    ctrl = status.get('controller') or {}
    out = {'estimator': {k: est.get(k) for k in (
        'steps', 'invalid_steps', 'invalid_entries', 'samples_missing', 'readings_received',
        'readings_replaced', 'readings_lost', 'predict_steps', 'stale_ticks', 'rebases',
        'no_model_entries', 'no_model_steps', 'nis_mean', 'valid', 'reason', 'dropped')},
        'controller': {k: ctrl.get(k) for k in (
            'state_rejected', 'failsafe_entries', 'failsafe_s', 'commands',
            'commands_normal', 'safe_current_a')},
        'car_sensors': (car_status or {}).get('sensing')}
    window = (out['car_sensors'] or {}).get('dropout_window_s')
    data = read_estimates(parts, window) if parts else None
    if data is not None:
        out.update(estimate_runs=data['runs'], dropout_seen=data['dropout_seen'],
                   estimates=data['estimates'],
                   valid_estimates=data['valid'], estimates_not_compared=data['truncated'],
                   estimation_error=estimation_errors(data['est'], data['true']))
    entries = out['estimator'].get('invalid_entries') or {}
    refused = ((out['controller'].get('state_rejected') or {}).get('non_finite') or 0)
    out['dropout_failsafe'] = bool(any(k.startswith('dropout_') and v for k, v in
                                       entries.items()) and refused > 0)
    if window:
        end = data.get('imu_last_stamp_s') if data is not None else None
        if end is None:
            end = (car_status or {}).get('t_sim')
        reached = (None if not isinstance(end, (int, float)) or end != end
                   else bool(end >= float(window[0])))
        out.update(dropout_reached=reached, car_time_end_s=end)
        if reached is False:            # nothing to count: the car never got there
            out['dropout_failsafe'] = None
    return out


def format_sensing(s):
    """Return the summary lines of the ``sensing`` section."""
    est, ctrl = s.get('estimator') or {}, s.get('controller') or {}
    lines = [f'sensing vehicle: estimator {est.get("steps")} steps, '
             f'{est.get("invalid_steps")} invalid, entries {est.get("invalid_entries") or {}}, '
             f'no model {est.get("no_model_entries")}x; controller refused states '
             f'{ctrl.get("state_rejected")}, fail-safe entries {ctrl.get("failsafe_entries")}']
    cs = s.get('car_sensors') or {}
    if cs.get('dropout_window_s'):
        head = (f'  injected dropout {cs["dropout_sensors"]} at {cs["dropout_window_s"][0]:g}'
                f' s for {cs["dropout_window_s"][1]:g} s: ')
        if s.get('dropout_reached') is False:
            lines.append(head + f'not reached (the car\'s time ended at '
                                f'{s["car_time_end_s"]:.2f} s)')
        else:
            lines.append(head + 'counted as fail-safe '
                         f'{"yes" if s.get("dropout_failsafe") else "NO"}')
    err = s.get('estimation_error')
    if err:
        lines.append(f'  estimation error (RMS, {err["pairs"]} valid estimates, lag '
                     f'{1e3 * err["lag_s"]:.2f} ms): ' + ', '.join(
                         f'{k} {v:.3g} ({100 * (err["rel_error"][k] or 0):.0f} %)'
                         for k, v in err['rms_error'].items()))
    return lines
