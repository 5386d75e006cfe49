"""Reading a suite recording back: one streamed pass over its MCAP parts into column logs."""
import math
from pathlib import Path

import numpy as np

from mr_damper_bringup.report.control import ControlWatch
from mr_damper_bringup.topics import (CAN_TOPICS, CONFIG_TOPIC, decode_parameters, decode_status,
                                      namespaced_table, NODE_PARAMETERS_TOPIC, SENSING_TOPICS,
                                      STATUS_KEYS, SUITE_TOPICS)
from mr_damper_common.contract import KWOK_CURRENT_NAMES
from mr_damper_common.recording.batch_index import BatchIndex
from mr_damper_common.recording.columnlog import ColumnWriter, JsonLines


#: file name of the run's recording in the output folder
RECORDING = 'suite.mcap'


MEAS_COLUMNS = ('t', 'x', 'v', 'f', 'i', 'recv_epoch_s')


def read_recording(path, work, *, identifier_starts=(), car_modes_from=None, namespace=None,
                   clock_corners=()):
    """
    Read a suite recording back in one streamed pass (bounded memory).

    Each file is read front to back (``mr_damper_common.recording.McapScan``, messages in
    the order the recorder wrote them), a file whose recorder was killed up to its last complete
    chunk.

    Parameters
    ----------
    path : str or Path, or a list of them
        The ``suite.mcap`` file, or the parts of a recording (a restarted recorder writes a new
        part, ``recorder.recording_parts``), read one after the other.
    work : str or Path
        Folder for the streamed extracts: column log ``measurement`` (:data:`MEAS_COLUMNS`,
        ``recv_epoch_s`` = receive time [s]) and ``parameters.jsonl`` (``[t_s, dict]`` per
        message, ``t_s`` seconds since the recording started, the dict with ``recv_epoch_s``).
    identifier_starts : sequence of float, optional
        Epoch times [s] the identifier was restarted at (the launcher's record): a count after
        one belongs to a new life, even when the recorder missed the new life's first counts.
    car_modes_from : float, optional
        Epoch time [s] from which the car states are decoded into ``car_modes`` (the first
        death of a node; None: not at all, a 1 kHz topic the rest of the report does not need).
    namespace : str, optional
        Read the topics of the nodes in this namespace (a car corner of ``--corners`` or
        ``--config full-car``: ``/fl/mr_damper/measurement``, ...) under the keys of the root
        namespace's; ``status`` then holds the statuses of that namespace's nodes under their
        short names (``rig``, ``identifier``), the other statuses under their own keys.
    clock_corners : sequence of str, optional
        Corners (``'fl'`` ...) whose car states (``/<c>/quarter_car/car_state``, the full car's
        or a corner's quarter car) give ``control`` its clock for them where the recording
        holds too few of their car's statuses (one state a second is decoded).

    Returns
    -------
    dict
        ``config`` (the parameter dict the suite ran with, or None), ``node_parameters``
        (node -> the parameters it reported running with, its defaults included), ``truth``,
        ``truth_spencer`` (decoded true parameters), ``status`` (last status per node),
        ``status_messages``, ``ride_metrics`` (last), ``topic_messages`` (messages per topic
        key), ``parameter_messages``, ``measurements_received``, ``measurement_gaps`` (samples
        missing between consecutive stamps), ``measurement_out_of_order``, ``bad_messages``
        (key -> {reason: count} of what was left out: messages whose payload did not decode,
        ``undecodable`` or the decoder's reason such as ``layout``; measurement samples with a
        NaN or infinite value, ``nonfinite_samples``, or stamped before the newest kept one,
        ``out_of_order_samples``; valid parameter sets with a NaN or infinite parameter,
        ``nonfinite_parameters``), ``start_epoch_s``, ``end_epoch_s``,
        ``parts`` (per file: ``complete``, ``messages``, first and last log time, ``error``;
        ``McapScan.summary``), ``identifier_lives`` (the identifier's ``samples_received``
        counts, one entry per process life: a count after a restart in ``identifier_starts``
        or one that goes down starts a life; ``counts``: its ``(t, count)`` series),
        ``gap_events`` (``(receive time, samples missing)`` of each stamp gap) and
        ``car_modes`` (runs ``[first_s, last_s, fail_safe_mode]`` of the car state, split at a
        mode change or a silence longer than :data:`CAR_STATE_GAP_S`; receive times [s]) and
        ``control`` (:class:`~mr_damper_bringup.report.control.ControlWatch` of the statuses,
        and of one car state a second as the car's clock).

    """
    import yaml

    from mr_damper_model.io.bag_types import suite_typestore
    from mr_damper_common.messages import stamp_to_seconds
    from mr_damper_common.recording.mcap_scan import McapScan
    from mr_damper_bringup.topics import decode_measurement
    work = Path(work)
    tables = {**SUITE_TOPICS, **CAN_TOPICS, **SENSING_TOPICS}
    if namespace:
        tables = {key.rpartition('/')[2]: row
                  for key, row in namespaced_table(tables, [namespace]).items()}
    keys = {row.name: key for key, row in tables.items()}
    keys[CONFIG_TOPIC.name] = 'config'
    keys[NODE_PARAMETERS_TOPIC.name] = 'node_parameters'
    corner_states = {f'/{c}{SUITE_TOPICS["car_state"].name}': c for c in clock_corners}
    keys.update({name: f'{c}/car_state' for name, c in corner_states.items()})
    rec = {'config': None, 'node_parameters': {}, 'truth': None, 'truth_spencer': None,
           'status': {}, 'status_messages': {}, 'ride_metrics': None, 'topic_messages': {},
           'parameter_messages': 0, 'measurements_received': 0, 'measurement_gaps': 0,
           'measurement_out_of_order': 0, 'bad_messages': {}, 'start_epoch_s': None,
           'end_epoch_s': None, 'parts': [], 'identifier_lives': [], 'car_modes': [],
           'gap_events': [], 'control': ControlWatch()}
    meas = ColumnWriter(work / 'measurement', MEAS_COLUMNS, chunk_rows=4096)
    params = JsonLines(work / 'parameters.jsonl')
    gaps = _Gaps()
    typestore = suite_typestore()
    unit = namespace or ''     # the law unit of this namespace's car (ControlWatch)
    # each unit's newest car state not taken as a clock point: its clock's last point at the
    # end (a car that caught up on a backlog drove seconds of road within one clock period)
    newest_state = {}
    try:
        for part in (path if isinstance(path, (list, tuple)) else [path]):
            reader = McapScan(part)
            for topic, msgtype, t_ns, raw in reader.messages(keys):
                key = keys[topic]
                t_rx = t_ns * 1e-9
                if rec['start_epoch_s'] is None:
                    rec['start_epoch_s'] = t_rx
                rec['end_epoch_s'] = t_rx
                rec['topic_messages'][key] = rec['topic_messages'].get(key, 0) + 1
                corner = corner_states.get(topic)
                if corner is not None:       # a corner's car state: its clock, nothing else
                    newest_state[corner] = (t_rx, raw, msgtype, reader, key)
                    if rec['control'].wants_car_state(corner, t_rx):
                        del newest_state[corner]
                        try:
                            msg = reader.deserialize(raw, msgtype, typestore)
                        except Exception:  # noqa: B902 - rosbags' SerdeError: counted
                            _count_bad(rec, key, 'undecodable')
                            continue
                        rec['control'].car_state(corner, t_rx,
                                                 stamp_to_seconds(msg.header.stamp))
                    continue
                # a root car state: the car's clock (one a second) and its mode runs
                clock = key == 'car_state' and rec['control'].wants_car_state(unit, t_rx)
                if key == 'car_state':
                    newest_state[unit] = (t_rx, raw, msgtype, reader, key)
                    if clock:
                        del newest_state[unit]
                modes = (key == 'car_state' and car_modes_from is not None
                         and t_rx >= car_modes_from)
                if key not in ('measurement', 'parameters', 'truth', 'truth_spencer',
                               'config', 'node_parameters', 'samples_received', 'car_state',
                               *STATUS_KEYS) or (key == 'car_state' and not (clock or modes)):
                    continue
                try:
                    msg = reader.deserialize(raw, msgtype, typestore)
                except Exception:  # noqa: B902 - rosbags' SerdeError and others: counted
                    _count_bad(rec, key, 'undecodable')
                    continue
                try:
                    if key == 'measurement':
                        sample = decode_measurement(msg)
                    elif key == 'samples_received':
                        _count_lives(rec['identifier_lives'], t_rx, int(msg.data),
                                     identifier_starts)
                        continue
                    elif key == 'car_state':
                        if clock:
                            rec['control'].car_state(unit, t_rx,
                                                     stamp_to_seconds(msg.header.stamp))
                        if modes:
                            _mode_runs(rec['car_modes'], t_rx, int(msg.fail_safe_mode))
                        continue
                    elif key == 'config':
                        rec['config'] = yaml.safe_load(msg.data)
                        continue
                    elif key == 'node_parameters':
                        for node, section in yaml.safe_load(msg.data).items():
                            rec['node_parameters'][node] = section['ros__parameters']
                        continue
                    elif key in ('parameters', 'truth', 'truth_spencer'):
                        d = decode_parameters(msg)
                    else:
                        statuses = decode_status(key, msg)
                        rec['control'].update(statuses, _sent_at(msg, t_rx))
                        for node, d in statuses.items():
                            rec['status'][node] = d
                            rec['status_messages'][node] = \
                                rec['status_messages'].get(node, 0) + 1
                            if node == 'quarter_car' and d.get('ride_metrics'):
                                rec['ride_metrics'] = d['ride_metrics']
                        continue
                except (ValueError, yaml.YAMLError, AttributeError, KeyError, TypeError) as exc:
                    _count_bad(rec, key, getattr(exc, 'reason', 'undecodable'))
                    continue
                if key == 'parameters' and not _usable_set(d):
                    _count_bad(rec, key, 'nonfinite_parameters')
                    continue
                if key == 'parameters':
                    d['recv_epoch_s'] = t_rx
                    params.append([t_rx - rec['start_epoch_s'], d])
                    rec['parameter_messages'] += 1
                elif key != 'measurement':
                    rec[key] = d
                else:
                    missing = rec['measurement_gaps']
                    _take_measurement(rec, gaps, sample, getattr(msg, 'first_index', None),
                                      meas, t_rx, getattr(msg, 'sample_period_s', 0.0))
                    if rec['measurement_gaps'] > missing:
                        rec['gap_events'].append((t_rx, rec['measurement_gaps'] - missing))
            rec['parts'].append(reader.summary())
        for car, (t_rx, raw, msgtype, reader, key) in newest_state.items():
            try:
                msg = reader.deserialize(raw, msgtype, typestore)
            except Exception:  # noqa: B902 - rosbags' SerdeError: counted
                _count_bad(rec, key, 'undecodable')
                continue
            rec['control'].car_state(car, t_rx, stamp_to_seconds(msg.header.stamp))
    finally:
        meas.close()
        params.close()
    if namespace:
        mine = {k.partition('/')[2]: d for k, d in rec['status'].items()
                if k.startswith(f'{namespace}/')}
        rec['status'] = {**{k: d for k, d in rec['status'].items()
                            if not k.startswith(f'{namespace}/')}, **mine}
    return rec


def _sent_at(msg, t_rx):
    """
    Time [s] a status was sent: its stamp, or the receive time ``t_rx``.

    The stamp is the node's clock: wall time, unless the node runs on a replay's ``/clock``
    (then far from the receive time, which is used instead). A recorder that fell behind
    receives statuses late and in bursts; their stamps keep the nodes' own timing.
    """
    stamp = getattr(getattr(msg, 'header', None), 'stamp', None)
    if stamp is None:
        return t_rx
    t = stamp.sec + stamp.nanosec * 1e-9
    return t if abs(t - t_rx) < STAMP_TRUST_S else t_rx


#: a status stamp further than this from its receive time [s] is not wall time (sim time)
STAMP_TRUST_S = 60.0


#: a silence of the car state longer than this [s] ends a run of its mode (the car was down)
CAR_STATE_GAP_S = 0.5


def _count_lives(lives, t, count, starts=()):
    """
    Add one count of a process's counter at ``t`` to its ``lives``.

    A count that goes down, or the first count after a (re)start time in ``starts``, starts a
    new life.
    """
    if (not lives or count < lives[-1]['last_count']
            or any(lives[-1]['last_s'] < t0 <= t for t0 in starts)):
        lives.append({'first_s': t, 'first_count': count, 'last_s': t, 'last_count': count,
                      'counts': [(t, count)]})
    else:
        lives[-1].update(last_s=t, last_count=count)
        lives[-1]['counts'].append((t, count))


def _received_between(lives, a, b):
    """Return the samples the identifier's lives counted in ``(a, b]`` (count at b less at a)."""
    def at(life, t):
        got = [c for tc, c in life['counts'] if tc <= t]
        return got[-1] if got else 0
    return sum(at(life, b) - at(life, a) for life in lives)


def _mode_runs(runs, t, mode):
    """Add one car state's mode at ``t`` to the runs ``[first_s, last_s, mode]``."""
    if runs and t - runs[-1][1] <= CAR_STATE_GAP_S:
        if runs[-1][2] == mode:
            runs[-1][1] = t
            return
        runs[-1][1] = t                # contiguous: the previous mode lasted until now
    runs.append([t, t, mode])


def _count_bad(rec, key, reason, n=1):
    """Count ``n`` bad recorded items of topic ``key`` by ``reason`` (``bad_messages``)."""
    if n:
        per_key = rec['bad_messages'].setdefault(key, {})
        per_key[reason] = per_key.get(reason, 0) + int(n)


def _usable_set(d):
    """Tell whether a decoded parameter message can be evaluated (or is marked not valid)."""
    return not d.get('valid') or all(
        isinstance(d.get(n), (int, float)) and math.isfinite(d[n]) for n in KWOK_CURRENT_NAMES)


class _Gaps:
    """Samples missing from the recorded measurement stream (see :func:`_take_measurement`)."""

    def __init__(self):
        self.index = BatchIndex()
        self.last_t = None
        self.dt = None


def _take_measurement(rec, gaps, cols, first_index, meas, t_rx, period_s=0.0):
    """
    Append one recorded measurement message (arrays ``t, x, v, f, i``) to the column log.

    Samples with a NaN or infinite value are counted (``bad_messages`` ``nonfinite_samples``)
    and left out, and so are samples not after the newest kept stamp
    (``measurement_out_of_order``, ``out_of_order_samples``). Missing samples
    (``measurement_gaps``) are counted exactly from the batches' stream index (``first_index``,
    judged against the stamps: :class:`~mr_damper_common.recording.batch_index.BatchIndex`); for
    single-sample JointState recordings, from stamp steps longer than 1.5 sample periods (the
    period: the shortest step of the first 20 samples).
    """
    t = cols[0]
    finite = np.all(np.isfinite(np.vstack(cols)), axis=0)
    _count_bad(rec, 'measurement', 'nonfinite_samples', finite.size - np.count_nonzero(finite))
    prev = -np.inf if gaps.last_t is None else gaps.last_t
    stamps = np.where(finite, t, -np.inf)
    keep = finite & (t > np.maximum.accumulate(np.concatenate(([prev], stamps)))[:-1])
    late = int(np.count_nonzero(finite) - np.count_nonzero(keep))
    rec['measurement_out_of_order'] += late
    _count_bad(rec, 'measurement', 'out_of_order_samples', late)
    if first_index is not None and (keep.any() or not late):
        # a batch of bad values still took its place in the stream: no samples lost there
        rec['measurement_gaps'] += gaps.index.update(first_index, t.size, t, period_s)
    if not keep.any():
        return
    if first_index is None:
        t0 = float(t[keep][0])
        if gaps.last_t is not None:
            step = t0 - gaps.last_t
            if gaps.dt is None or rec['measurements_received'] < 20:
                gaps.dt = step if gaps.dt is None else min(gaps.dt, step)
            elif step > 1.5 * gaps.dt:
                rec['measurement_gaps'] += int(round(step / gaps.dt)) - 1
    gaps.last_t = float(t[keep][-1])
    block = np.column_stack([c[keep] for c in cols] + [np.full(np.count_nonzero(keep), t_rx)])
    meas.append_block(block)
    rec['measurements_received'] += int(block.shape[0])


CHUNK_ROWS = 65536


class ParamsLog:
    """
    The parameter messages of a run, read from ``parameters.jsonl`` on each pass (bounded).

    Iterating yields ``(wall_s, dict)``; ``len()`` counts the records (one pass). Lines that are
    not JSON (the last line of a crashed run) are skipped and listed in ``bad_lines``.
    """

    def __init__(self, path):
        self.path = Path(path)
        self.bad_lines = []

    def __iter__(self):
        from mr_damper_common.recording.columnlog import read_json_lines
        if not self.path.exists():
            return
        bad = []
        for rec in read_json_lines(self.path, bad):
            if isinstance(rec, list) and len(rec) == 2 and isinstance(rec[1], dict):
                yield float(rec[0]), rec[1]
        self.bad_lines = bad

    def __len__(self):
        return sum(1 for _ in self)


def recording_state(rec):
    """
    Return how complete the recording is: ``complete``, ``parts``, ``note``.

    ``complete`` is True only for one part closed properly (a restarted recorder leaves parts
    with a gap between them; a killed one a part without its footer, read up to its last
    complete chunk); ``parts`` lists each file read (``McapScan.summary``).
    """
    parts = rec.get('parts') or []
    complete = len(parts) == 1 and parts[0]['complete']
    out = {'complete': complete, 'parts': parts}
    if not parts:
        out['note'] = 'no recording: the summary comes from the nodes\' last statuses'
    elif not complete:
        cut = [p for p in parts if not p['complete']]
        out['note'] = (f'{len(parts)} part(s), {len(cut)} cut short by a killed recorder '
                       '(read up to the last complete chunk); messages between the parts were '
                       'not recorded')
    return out


def _first(d, keys):
    for k in keys:
        if isinstance(d.get(k), (int, float)):
            return d[k]
    return None
