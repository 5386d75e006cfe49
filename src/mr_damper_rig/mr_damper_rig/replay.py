"""
Recorded damper measurements for replay: DAQ CSV files and rosbag2 directories.

Both readers load and check the *whole* file before anything is published, so a bad file fails
up front with one :class:`~mr_damper_model.io.data.DataError` line naming the file and the problem
(a replay never stops half-way through a file it already started to publish).

Bags are read and written by ``mr_damper_model.io.bag_io`` (rosbags, no ROS install needed):
rosbag2 directories in the sqlite3 or MCAP storage format, or a single ``.db3`` / ``.mcap`` file
with ``sensor_msgs/msg/JointState`` measurements; the sample time is the message's
``header.stamp``.

This module does not import rclpy.
"""
import math

import numpy as np

from mr_damper_model.io import bag_io
# the bag names live in mr_damper_model.io.bag_io; re-exported for the rig's modules and scripts
from mr_damper_model.io.bag_io import (  # noqa: F401
    bag_topics, BagWriter, JOINTSTATE_TYPE, MEASUREMENT_TOPIC, write_bag)
from mr_damper_model.io.data import check_samples, DataError, read_csv


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
        CSV file (see ``mr_damper_model.io.data.read_csv`` for the format).

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


def read_bag(path, topic=MEASUREMENT_TOPIC):
    """
    Read and check the measurement topic of a rosbag2 for replay.

    Parameters
    ----------
    path : str or Path
        rosbag2 directory (sqlite3 or MCAP), or a single ``.db3`` / ``.mcap`` file.
    topic : str or None
        Measurement topic (``sensor_msgs/msg/JointState``, suite layout); None: the rig's topic
        if present, else the bag's only JointState topic (see ``bag_io.read_bag``).

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
    data = bag_io.read_bag(path, topic)
    return check_stream(data, name=data.source)


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

    def samples(self, k, n):
        """Return samples ``k .. k+n-1`` as five arrays ``t, x, v, f, i``."""
        lap, j = np.divmod(np.arange(k, k + n), self.n)
        cols = self.cols[j]
        return (self.t[j] + lap * self.period, cols[:, 0], cols[:, 1], cols[:, 2], cols[:, 3])


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
