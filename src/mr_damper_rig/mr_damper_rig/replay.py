"""
Recorded damper measurements for replay: DAQ CSV files and rosbag2 directories.

Both readers load and check the *whole* file before anything is published, so a bad file fails
up front with one :class:`~mr_damper_model.data.DataError` line naming the file and the problem
(a replay never stops half-way through a file it already started to publish).

Bags are read with `rosbags` (pure Python, no ROS install needed): rosbag2 directories in the
sqlite3 or MCAP storage format, or a single ``.db3`` / ``.mcap`` file.  The measurement topic
carries ``sensor_msgs/msg/JointState`` in the suite's measurement layout (see
``mr_damper_model.messages``); the sample time is the message's ``header.stamp``.

This module does not import rclpy.
"""
import math
from pathlib import Path

import numpy as np

from mr_damper_model.data import check_samples, COIL_JOINT, DamperData, DataError, PISTON_JOINT, \
    read_csv

MEASUREMENT_TOPIC = '/mr_damper/measurement'
JOINTSTATE_TYPE = 'sensor_msgs/msg/JointState'


def check_stream(data, *, name='', min_samples=2):
    """
    Check a record is publishable as a measurement stream; return it unchanged.

    Parameters
    ----------
    data : DamperData
        Record to replay.
    name : str
        Label for messages (default ``data.source``).
    min_samples : int
        Fewer samples is an error.

    Raises
    ------
    DataError
        Too few samples, NaN/inf values, negative or non-increasing time stamps.

    """
    check_samples(data, min_samples=min_samples, name=name)
    label = f'{name or data.source}: ' if (name or data.source) else ''
    if data.t[0] < 0:
        raise DataError(f'{label}negative time stamp {data.t[0]:.6g} s (not a valid ROS stamp)')
    return data


def read_csv_stream(path):
    """
    Read and check a ``t,x,v,f,i`` DAQ CSV file for replay.

    Parameters
    ----------
    path : str or Path
        CSV file (see ``mr_damper_model.data.read_csv`` for the format).

    Returns
    -------
    DamperData
        The record; ``t`` is the file's time column [s].

    Raises
    ------
    DataError
        Unreadable or malformed file (message names the file and the problem).

    """
    return check_stream(read_csv(path), name=str(path))


def _bag_paths(path):
    path = Path(path)
    if not path.exists():
        raise DataError(f'{path}: bag not found')
    if path.is_dir():
        if not (path / 'metadata.yaml').exists():
            raise DataError(f'{path}: not a rosbag2 directory (no metadata.yaml)')
    elif path.suffix not in ('.db3', '.mcap'):
        raise DataError(f'{path}: not a rosbag2 directory or a .db3/.mcap file')
    return path


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

    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    path = _bag_paths(path)
    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_KILTED)) as reader:
            return {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
    except DataError:
        raise
    except Exception as exc:  # rosbags raises several unrelated types for broken bags
        raise DataError(f'{path}: cannot open bag ({type(exc).__name__}: {exc})') from None


def read_bag(path, topic=MEASUREMENT_TOPIC):
    """
    Read and check the measurement topic of a rosbag2 for replay.

    Parameters
    ----------
    path : str or Path
        rosbag2 directory (sqlite3 or MCAP), or a single ``.db3`` / ``.mcap`` file.
    topic : str
        Measurement topic (``sensor_msgs/msg/JointState``, suite layout).

    Returns
    -------
    DamperData
        Samples in bag order; ``t`` is each message's ``header.stamp`` [s].

    Raises
    ------
    DataError
        Missing bag or topic, wrong message type, wrong joint names, NaN/inf values,
        non-increasing stamps, unreadable storage.

    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    path = _bag_paths(path)
    name = str(path)
    rows = []
    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_KILTED)) as reader:
            conns = [c for c in reader.connections if c.topic == topic]
            if not conns:
                have = ', '.join(sorted({c.topic for c in reader.connections})) or 'none'
                raise DataError(f'{name}: no topic {topic} in the bag (topics: {have})')
            types = {c.msgtype for c in conns}
            if types != {JOINTSTATE_TYPE}:
                raise DataError(f'{name}: topic {topic} has type {", ".join(sorted(types))}, '
                                f'expected {JOINTSTATE_TYPE}')
            for k, (conn, _, raw) in enumerate(reader.messages(connections=conns)):
                msg = reader.deserialize(raw, conn.msgtype)
                rows.append(_row(msg, k, name))
    except DataError:
        raise
    except Exception as exc:  # rosbags raises several unrelated types for broken bags
        raise DataError(f'{name}: cannot read bag ({type(exc).__name__}: {exc})') from None
    if not rows:
        raise DataError(f'{name}: topic {topic} has no messages')
    t, x, v, f, i = np.array(rows, dtype=float).T
    return check_stream(DamperData(t, x, v, f, i, source=name), name=name)


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


def read_stream(mode, path, topic=MEASUREMENT_TOPIC):
    """
    Read a replay source by mode.

    Parameters
    ----------
    mode : {'csv', 'bag'}
        Source kind.
    path : str or Path
        CSV file or bag.
    topic : str
        Bag topic (``bag`` mode only).

    Returns
    -------
    DamperData
        Checked record.

    """
    if mode == 'csv':
        return read_csv_stream(path)
    if mode == 'bag':
        return read_bag(path, topic)
    raise ValueError(f"`mode` must be 'csv' or 'bag', got {mode!r}")


def write_bag(path, data, *, topic=MEASUREMENT_TOPIC, storage='sqlite3'):
    """
    Write a record as a rosbag2 of measurement messages (used by tests and examples).

    Parameters
    ----------
    path : str or Path
        Bag directory to create (must not exist).
    data : DamperData
        Samples; ``t`` becomes header stamp and log time.
    topic : str
        Topic name.
    storage : {'sqlite3', 'mcap'}
        rosbag2 storage plugin.

    """
    writer = BagWriter(path, topic=topic, storage=storage)
    with writer:
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

    """

    def __init__(self, path, *, topic=MEASUREMENT_TOPIC, storage='sqlite3'):
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
        plugins = {'sqlite3': StoragePlugin.SQLITE3, 'mcap': StoragePlugin.MCAP}
        if storage not in plugins:
            raise ValueError(f"`storage` must be 'sqlite3' or 'mcap', got {storage!r}")
        self.path = Path(path)
        if self.path.exists():
            raise ValueError(f'`path`: {self.path} already exists')
        self._ts = get_typestore(Stores.ROS2_KILTED)
        self._writer = Writer(self.path, version=9, storage_plugin=plugins[storage])
        self._topic = topic
        self._conn = None
        types = self._ts.types
        self._JointState = types[JOINTSTATE_TYPE]
        self._Header = types['std_msgs/msg/Header']
        self._Time = types['builtin_interfaces/msg/Time']
        self.count = 0

    def __enter__(self):
        self._writer.open()
        self._conn = self._writer.add_connection(self._topic, JOINTSTATE_TYPE,
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
            Sample time [s] (header stamp).
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

    def write_raw(self, raw, log_time_ns):
        """Write one already serialised (CDR) JointState with the bag time ``log_time_ns``."""
        self._writer.write(self._conn, int(log_time_ns), bytes(raw))
        self.count += 1


class ArraySource:
    """
    Recorded samples with their own timing, optionally looped.

    Sample ``k`` of a looped record is sample ``k % n`` stamped ``t + (k // n) * period`` with
    ``period`` = record duration + one median sample interval, so stamps keep increasing.
    """

    def __init__(self, data, loop=False, offset_s=0.0):
        self.t = data.t + offset_s
        self.cols = np.column_stack([data.x, data.v, data.f, data.i])
        self.rel = data.t - data.t[0]
        self.n = data.n
        dt = float(np.median(np.diff(data.t))) if data.n > 1 else 1e-3
        self.period = float(self.rel[-1]) + dt
        self.loop = loop

    def count_due(self, elapsed_s):
        """Return how many samples are due after ``elapsed_s`` seconds of record time."""
        if self.loop:
            laps = math.floor(elapsed_s / self.period)
            return laps * self.n + int(np.searchsorted(self.rel, elapsed_s - laps * self.period,
                                                       side='right'))
        return int(np.searchsorted(self.rel, elapsed_s, side='right'))

    def total(self):
        """Return the number of samples (None when looping)."""
        return None if self.loop else self.n

    def sample(self, k):
        """Return sample ``k`` as ``(t, x, v, f, i)``."""
        lap, j = divmod(k, self.n)
        x, v, f, i = self.cols[j]
        return self.t[j] + lap * self.period, x, v, f, i


class SimSource:
    """Samples of the virtual rig, stamped ``t0 + t_sim``."""

    def __init__(self, rig, rate_hz, t0_s, duration_s):
        self.rig = rig
        self.rate_hz = rate_hz
        self.t0 = t0_s
        self.duration_s = duration_s

    def count_due(self, elapsed_s):
        """Return how many samples are due after ``elapsed_s`` seconds of simulated time."""
        return int(math.floor(elapsed_s * self.rate_hz + 1e-9)) + 1

    def total(self):
        """Return the number of samples to publish (None: unlimited)."""
        if self.duration_s > 0:
            return int(round(self.duration_s * self.rate_hz))
        return None

    def sample(self, k):
        """Return the next recorded sample; ``k`` must count up by one."""
        t, x, v, f, i = self.rig.sample()
        return self.t0 + t, x, v, f, i
