"""
Damper measurements in rosbag2 bags: reading and writing without ROS (one home for both).

Bags are read and written with `rosbags` (pure Python, no ROS install needed): rosbag2
directories in the sqlite3 or MCAP storage format, or a single ``.db3`` / ``.mcap`` file.  The
measurement topic carries either the rig's batches, ``mr_damper_interfaces/msg/DamperSamples``
(what ``mr-damper-record`` records: arrays of samples, the time of each is ``header.stamp`` +
``t_offset_s``), or one ``sensor_msgs/msg/JointState`` per sample in the suite's single-sample
layout (see ``mr_damper_common.messages``): joints ``mr_damper_piston`` (position = displacement
[m], velocity [m/s], effort = force [N]) and ``mr_damper_coil`` (effort = coil current [A]);
the sample time is the message's ``header.stamp`` [s].

Every problem raises :class:`~mr_damper_model.io.data.DataError` with one line naming the bag and
the problem (missing bag or topic, wrong message type or joint names, truncated or corrupt
storage).  Users: ``mr-damper-identify`` (bags as input) and the rig's replay and recorder.

This module imports rosbags only, never rclpy or message packages.
"""
from pathlib import Path

import numpy as np

from mr_damper_common.contract import COIL_JOINT, PISTON_JOINT
from mr_damper_common.recording.mcap_scan import Channel, McapScan
from mr_damper_model.io.data import DamperData, DataError

#: Topic of the rig's measurements (the rig node publishes and the recorder records it).
MEASUREMENT_TOPIC = '/mr_damper/measurement'
JOINTSTATE_TYPE = 'sensor_msgs/msg/JointState'
SAMPLES_TYPE = 'mr_damper_interfaces/msg/DamperSamples'
#: Message types a measurement topic may carry.
MEASUREMENT_TYPES = (SAMPLES_TYPE, JOINTSTATE_TYPE)
#: Suffixes of single-file bags.
BAG_SUFFIXES = ('.db3', '.mcap')


def is_bag(path):
    """
    Tell whether ``path`` names a bag (by its form, without opening it).

    Parameters
    ----------
    path : str or Path
        Candidate path.

    Returns
    -------
    bool
        True for a directory holding ``metadata.yaml`` (rosbag2) or a ``.db3`` / ``.mcap`` path.

    """
    path = Path(path)
    if path.is_dir():
        return (path / 'metadata.yaml').exists()
    return path.suffix in BAG_SUFFIXES


def _bag_path(path):
    path = Path(path)
    if not path.exists():
        raise DataError(f'{path}: bag not found')
    if path.is_dir():
        if not (path / 'metadata.yaml').exists():
            raise DataError(f'{path}: not a rosbag2 directory (no metadata.yaml)')
    elif path.suffix not in BAG_SUFFIXES:
        raise DataError(f'{path}: not a rosbag2 directory or a .db3/.mcap file')
    return path


def _typestore():
    """Return the kilted type store with the suite's messages (without them if not installed)."""
    from rosbags.typesys import get_typestore, Stores
    from mr_damper_model.io.bag_types import BagTypesError, suite_typestore  # lazy: rosbags
    try:
        return suite_typestore()
    except BagTypesError:
        return get_typestore(Stores.ROS2_KILTED)


def _open(path):
    from rosbags.highlevel import AnyReader
    return AnyReader([path], default_typestore=_typestore())


def bag_topics(path):
    """
    List the topics of a rosbag2.

    Parameters
    ----------
    path : str or Path
        rosbag2 directory (sqlite3 or MCAP), or a single ``.db3`` / ``.mcap`` file.

    Returns
    -------
    dict[str, tuple[str, int]]
        Topic -> (message type, message count).

    Raises
    ------
    DataError
        Missing, unreadable or corrupt bag.

    """
    path = _bag_path(path)
    try:
        with _open(path) as reader:
            return {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
    except Exception as exc:  # rosbags raises several unrelated types for broken bags
        raise DataError(f'{path}: cannot open bag ({type(exc).__name__}: {exc})') from None


def _choose_topic(connections, topic, name):
    """Return the connections of the measurement topic (see :func:`read_bag` for the rule)."""
    topics = sorted({c.topic for c in connections})
    if topic is None:
        joint = sorted({c.topic for c in connections if c.msgtype in MEASUREMENT_TYPES})
        if MEASUREMENT_TOPIC in topics:
            topic = MEASUREMENT_TOPIC
        elif len(joint) == 1:
            topic = joint[0]
        else:
            which = ('several measurement topics' if joint else
                     'no DamperSamples or JointState topic')
            raise DataError(f'{name}: no topic {MEASUREMENT_TOPIC} and {which} in the bag '
                            f'(topics: {", ".join(topics) or "none"}); choose one with --topic')
    conns = [c for c in connections if c.topic == topic]
    if not conns:
        raise DataError(f'{name}: no topic {topic} in the bag '
                        f'(topics: {", ".join(topics) or "none"})')
    types = {c.msgtype for c in conns}
    if len(types) != 1 or not types <= set(MEASUREMENT_TYPES):
        raise DataError(f'{name}: topic {topic} has type {", ".join(sorted(types))}, '
                        f'expected {" or ".join(MEASUREMENT_TYPES)}')
    return topic, conns


def read_bag(path, topic=None, *, recovery=None):
    """
    Read the measurement samples of a rosbag2.

    A single ``.mcap`` file that rosbags cannot open (no footer: its writer was killed) is read
    up to its last complete chunk (:class:`~mr_damper_common.recording.mcap_scan.McapScan`).

    Parameters
    ----------
    path : str or Path
        rosbag2 directory (sqlite3 or MCAP), or a single ``.db3`` / ``.mcap`` file.
    topic : str, optional
        Measurement topic (``DamperSamples`` batches or ``sensor_msgs/msg/JointState``, suite
        layout). Default: :data:`MEASUREMENT_TOPIC` if the bag has it, else the bag's only
        topic of either type.
    recovery : dict, optional
        Filled for a truncated MCAP file that was read in part: ``complete`` (False),
        ``messages``, ``first_log_time_s``, ``last_log_time_s``, ``error`` and ``note`` (one
        line saying where the file ends).

    Returns
    -------
    DamperData
        Samples in bag order; ``t`` is each sample's stamp [s]; ``source`` is the path. Values
        are returned as recorded: check them with ``data.check_samples`` or ``data.validate``.

    Raises
    ------
    DataError
        Missing bag or topic, no unique JointState topic, wrong message type, wrong joint names,
        short arrays, empty topic, truncated or corrupt storage.

    """
    path = _bag_path(path)
    name = str(path)
    blocks = []
    try:
        with _open(path) as reader:
            topic, conns = _choose_topic(reader.connections, topic, name)
            for k, (conn, _, raw) in enumerate(reader.messages(connections=conns)):
                blocks.append(_block(reader.deserialize(raw, conn.msgtype), conn.msgtype, k,
                                     name))
    except DataError:
        raise
    except Exception as exc:  # rosbags raises several unrelated types for broken bags
        if path.suffix != '.mcap' or path.is_dir():
            raise DataError(f'{name}: cannot read bag ({type(exc).__name__}: {exc})') from None
        topic, blocks = _read_cut_mcap(path, topic, name, exc, recovery)
    if not blocks:
        raise DataError(f'{name}: topic {topic} has no messages')
    t, x, v, f, i = np.concatenate(blocks).T
    return DamperData(t, x, v, f, i, source=name)


def _read_cut_mcap(path, topic, name, exc, recovery):
    """Read the measurements of an MCAP file rosbags refused (``exc``) up to its last chunk."""
    scan = McapScan(path)
    conns = [Channel(t, m) for t, (m, _) in scan.topics().items()]
    if scan.complete or not scan.count:
        raise DataError(f'{name}: cannot read bag ({type(exc).__name__}: {exc}); '
                        f'{scan.where()}') from None
    topic, _ = _choose_topic(conns, topic, name)
    ts = _typestore()
    blocks = [_block(scan.deserialize(raw, msgtype, ts), msgtype, k, name)
              for k, (_, msgtype, _, raw) in enumerate(scan.messages({topic}))]
    if recovery is not None:
        recovery.update(scan.summary(), note=scan.where())
    return topic, blocks


def _block(msg, msgtype, k, name):
    """Rows ``(t, x, v, f, i)`` of one measurement message of either layout."""
    return (_batch(msg, k, name) if msgtype == SAMPLES_TYPE
            else np.array([_row(msg, k, name)], dtype=float))


def _batch(msg, k, name):
    """Rows ``(t, x, v, f, i)`` of one ``DamperSamples`` message (a rosbags dataclass)."""
    cols = [np.asarray(a, dtype=float) for a in (msg.t_offset_s, msg.x_m, msg.v_m_s, msg.f_n,
                                                 msg.i_a)]
    n = cols[0].size
    if n == 0 or any(c.size != n for c in cols):
        raise DataError(f'{name}: message {k} has sample arrays of lengths '
                        f'{[c.size for c in cols]} (empty or unequal)')
    cols[0] = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 + cols[0]
    return np.column_stack(cols)


def _row(msg, k, name):
    names = list(msg.name)
    try:
        ip, ic = names.index(PISTON_JOINT), names.index(COIL_JOINT)
    except ValueError:
        raise DataError(f'{name}: message {k} has joints {names}, expected '
                        f'[{PISTON_JOINT}, {COIL_JOINT}]') from None
    try:
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        return (stamp, float(msg.position[ip]), float(msg.velocity[ip]), float(msg.effort[ip]),
                float(msg.effort[ic]))
    except IndexError:
        raise DataError(f'{name}: message {k} has fewer position/velocity/effort values than '
                        'joints') from None


def write_bag(path, data, *, topic=MEASUREMENT_TOPIC, storage='sqlite3', samples_per_message=0):
    """
    Write a record as a rosbag2 of measurement messages.

    Parameters
    ----------
    path : str or Path
        Bag directory to create (must not exist).
    data : DamperData
        Samples; ``t`` [s] becomes header stamp and log time.
    topic : str
        Topic name.
    storage : {'sqlite3', 'mcap'}
        rosbag2 storage plugin.
    samples_per_message : int
        0: one ``sensor_msgs/JointState`` per sample (single-sample layout); n > 0:
        ``DamperSamples`` batches of n samples, as the rig publishes them.

    """
    msgtype = SAMPLES_TYPE if samples_per_message > 0 else JOINTSTATE_TYPE
    with BagWriter(path, topic=topic, storage=storage, msgtype=msgtype) as writer:
        if samples_per_message > 0:
            for k in range(0, data.n, samples_per_message):
                part = slice(k, k + samples_per_message)
                writer.write_batch(data.t[part], data.x[part], data.v[part], data.f[part],
                                   data.i[part], sequence=k // samples_per_message,
                                   first_index=k)
        else:
            for row in zip(data.t, data.x, data.v, data.f, data.i):
                writer.write(*row)


class BagWriter:
    """
    rosbag2 writer of measurement samples (context manager).

    Parameters
    ----------
    path : str or Path
        Bag directory to create (must not exist).
    topic : str
        Topic name.
    storage : {'sqlite3', 'mcap'}
        rosbag2 storage plugin.
    msgtype : str
        :data:`JOINTSTATE_TYPE` (write with :meth:`write`, one sample per message) or
        :data:`SAMPLES_TYPE` (write with :meth:`write_batch`).

    """

    def __init__(self, path, *, topic=MEASUREMENT_TOPIC, storage='sqlite3',
                 msgtype=JOINTSTATE_TYPE):
        from rosbags.rosbag2 import StoragePlugin, Writer
        plugins = {'sqlite3': StoragePlugin.SQLITE3, 'mcap': StoragePlugin.MCAP}
        if storage not in plugins:
            raise ValueError(f"`storage` must be 'sqlite3' or 'mcap', got {storage!r}")
        self.path = Path(path)
        if self.path.exists():
            raise ValueError(f'`path`: {self.path} already exists')
        self._ts = _typestore()
        self._writer = Writer(self.path, version=9, storage_plugin=plugins[storage])
        if msgtype not in MEASUREMENT_TYPES or msgtype not in self._ts.types:
            raise ValueError(f'`msgtype` must be one of {MEASUREMENT_TYPES} (known to the type '
                             f'store), got {msgtype!r}')
        self._msgtype = msgtype
        self._topic = topic
        self._conn = None
        types = self._ts.types
        self._JointState = types[JOINTSTATE_TYPE]
        self._Header = types['std_msgs/msg/Header']
        self._Time = types['builtin_interfaces/msg/Time']
        self.count = 0

    def __enter__(self):
        self._writer.open()
        self._conn = self._writer.add_connection(self._topic, self._msgtype,
                                                 typestore=self._ts)
        return self

    def __exit__(self, *exc):
        self._writer.close()
        return False

    def write(self, t, x, v, f, i, log_time_ns=None):
        """
        Write one sample.

        Parameters
        ----------
        t : float
            Sample time [s] (header stamp), >= 0.
        x, v, f, i : float
            Displacement [m], velocity [m/s], force [N], current [A].
        log_time_ns : int, optional
            Bag receive time [ns] (default: the stamp).

        """
        ns = int(round(t * 1e9))
        sec, nsec = divmod(ns, 1_000_000_000)
        nan = float('nan')
        msg = self._JointState(
            header=self._Header(stamp=self._Time(sec=sec, nanosec=nsec), frame_id='mr_damper'),
            name=[PISTON_JOINT, COIL_JOINT],
            position=np.array([x, nan]), velocity=np.array([v, nan]),
            effort=np.array([f, i]))
        self.write_raw(self._ts.serialize_cdr(msg, JOINTSTATE_TYPE),
                       ns if log_time_ns is None else log_time_ns)

    def write_batch(self, t, x, v, f, i, *, sequence, first_index, log_time_ns=None):
        """
        Write one ``DamperSamples`` batch (arrays of shape (n,), SI units).

        The layout is :func:`mr_damper_common.messages.samples_to_msg`'s.

        ``log_time_ns`` defaults to the newest sample's stamp (when a rig would publish it).
        """
        t, x, v, f, i = (np.ascontiguousarray(a, dtype=float) for a in (t, x, v, f, i))
        ns = int(round(t[0] * 1e9))
        sec, nsec = divmod(ns, 1_000_000_000)
        step = np.diff(t)
        period = float(np.median(step)) if step.size else 0.0
        msg = self._ts.types[SAMPLES_TYPE](
            header=self._Header(stamp=self._Time(sec=sec, nanosec=nsec), frame_id='mr_damper'),
            sequence=int(sequence), first_index=int(first_index), sample_period_s=period,
            t_offset_s=t - t[0], x_m=x, v_m_s=v, f_n=f, i_a=i)
        self.write_raw(self._ts.serialize_cdr(msg, SAMPLES_TYPE),
                       int(round(t[-1] * 1e9)) if log_time_ns is None else log_time_ns)

    def write_raw(self, raw, log_time_ns):
        """Write one already serialised (CDR) message with the bag time ``log_time_ns``."""
        self._writer.write(self._conn, int(log_time_ns), bytes(raw))
        self.count += 1
