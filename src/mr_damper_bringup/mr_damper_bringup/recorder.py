"""
One MCAP file of a suite run: the writer behind ``mr-damper-record``, without ROS.

:class:`SuiteRecorder` writes messages still serialised (CDR, as the subscription delivers them)
with the rosbags ``Writer`` into ONE ``.mcap`` file, one channel per row of the topic table
(:data:`mr_damper_bringup.topics.SUITE_TOPICS`) with the full ``ros2msg`` schema of its type
from ``mr_damper_model.io.bag_types.suite_typestore()`` (which knows the ``mr_damper_interfaces``
messages), so Foxglove, PlotJuggler, ``ros2 bag`` and rosbags open it with named fields.

Memory stays flat for runs of any length: rosbags streams chunks of at most 1 MiB to the file
and keeps only a chunk index (tens of bytes per chunk). While recording, the file is
``<stem>.recording/<stem>.recording.mcap`` next to the target (a rosbag2 folder); :meth:`close`
moves the finished file to the target path and removes the folder.

A recorder killed before :meth:`close` leaves that folder with an MCAP file without its footer;
every chunk written before the kill is complete in it and
``mr_damper_common.recording.mcap_scan`` reads them. rosbags writes a chunk whole once it
exceeds 1 MiB (a size it does not let you set: many seconds of a batched measurement stream);
the recorder also closes and flushes the open chunk once it spans ``chunk_s`` of log time
(1 s), so a kill loses about the last second. A recorder restarted by the launcher writes a new
part, ``<stem>.1.mcap``, ``<stem>.2.mcap``, ... (:func:`part_path`), never over an earlier one;
:func:`recording_parts` lists the parts of a run in order, finished or left by a killed writer.
"""
from pathlib import Path
import re

from mr_damper_common.sequence_gaps import SequenceGaps

from .topics import CONFIG_TOPIC, NODE_PARAMETERS_TOPIC, STATUS_KEYS, topic_table


def part_path(path, k):
    """Return the file of part ``k`` of recording ``path``: ``path``, then ``stem.k.mcap``."""
    path = Path(path)
    return path if k == 0 else path.with_name(f'{path.stem}.{int(k)}{path.suffix}')


def work_file(path):
    """Return the file a recorder writes into until it closes ``path`` (see the module doc)."""
    path = Path(path)
    work = path.parent / f'{path.stem}.recording'
    return work / f'{work.name}.mcap'


def _part_number(path, name):
    """Return ``k`` if ``name`` names part ``k`` of recording ``path`` (file or work folder)."""
    stem = re.escape(Path(path).stem)
    m = re.fullmatch(rf'{stem}(?:\.(\d+))?(\.mcap|\.recording)', name)
    return None if m is None else int(m.group(1) or 0)


def recording_parts(path):
    """
    Return the parts of recording ``path`` in order, as ``[(k, file)]``.

    Part ``k`` is :func:`part_path` if its recorder closed it, else the file its killed
    recorder left (:func:`work_file` of it, no footer); parts with neither are left out.
    """
    path = Path(path)
    found = set()
    if path.parent.is_dir():
        for entry in path.parent.iterdir():
            k = _part_number(path, entry.name)
            if k is not None:
                found.add(k)
    out = []
    for k in sorted(found):
        done, left = part_path(path, k), work_file(part_path(path, k))
        if done.is_file():
            out.append((k, done))
        elif left.is_file():
            out.append((k, left))
    return out


def remove_recording(path):
    """Delete every part of recording ``path`` (a new run starts a new recording)."""
    import shutil
    path = Path(path)
    if not path.parent.is_dir():
        return
    for entry in path.parent.iterdir():
        if _part_number(path, entry.name) is not None:
            if entry.is_dir():
                shutil.rmtree(entry)
            else:
                entry.unlink()


def _is_measurement(key):
    """Tell whether ``key`` is the measurement topic of any namespace (``[NS/]measurement``)."""
    return key.rpartition('/')[2] == 'measurement'


class SuiteRecorder:
    """
    Writer of one suite recording (context manager).

    Parameters
    ----------
    path : str or Path
        The ``.mcap`` file to create (must not exist).
    topics : dict, optional
        ``key -> Topic`` rows to record (default: every topic of
        :data:`~mr_damper_bringup.topics.SUITE_TOPICS`).
    config_text : str, optional
        The suite's parameter YAML, written once on :data:`~mr_damper_bringup.topics.
        CONFIG_TOPIC` at the start (stamped ``start_ns``).
    typestore : rosbags Typestore, optional
        Default: ``mr_damper_model.io.bag_types.suite_typestore()``.
    start_ns : int, optional
        Log time [ns] of the config message (default: 0).
    chunk_s : float, optional
        Close the open chunk (and flush it to the file) after a message logged this long [s]
        after the chunk's first one (default 1; 0: only when rosbags closes it at 1 MiB): a
        killed recorder loses about this much, not a whole MiB (many seconds of a batched
        measurement stream).

    Attributes
    ----------
    counts : dict
        Messages written per topic key.
    lost : dict
        Measurement messages that never reached the recorder, per measurement key, counted from
        the batches' ``sequence`` (:class:`~mr_damper_common.sequence_gaps.SequenceGaps`; a
        per-sample ``JointState`` stream has no sequence: its gaps are in its stamps).
    undecodable : dict
        Measurement (and status) messages per key written as received but not readable here
        (their samples are not counted; the report counts them as bad messages too).
    statuses : dict
        Status entries written per status name (the node's fully qualified name without the
        leading slash, ``'fl/quarter_car_node'``), from the status topics
        (:data:`~mr_damper_bringup.topics.STATUS_KEYS`): which nodes the recording has heard.

    """

    def __init__(self, path, topics=None, *, config_text=None, typestore=None, start_ns=0,
                 chunk_s=1.0):
        self.path = Path(path)
        if self.path.suffix != '.mcap':
            raise ValueError(f'`path`: {self.path} must end in .mcap')
        self.work = self.path.parent / f'{self.path.stem}.recording'
        for p in (self.path, self.work):
            if p.exists():
                raise ValueError(f'`path`: {p} already exists')
        self.topics = topic_table() if topics is None else dict(topics)
        if typestore is None:
            from mr_damper_model.io.bag_types import suite_typestore
            typestore = suite_typestore()
        self.typestore = typestore
        for key, row in self.topics.items():
            if row.type not in typestore.fielddefs:
                raise ValueError(f'topic {key} ({row.name}): type {row.type} is not in the '
                                 'type store')
        self.config_text = config_text
        self.start_ns = int(start_ns)
        self.counts = {key: 0 for key in self.topics}
        #: samples written per measurement key (a DamperSamples message holds many)
        self.samples = {key: 0 for key in self.topics if _is_measurement(key)}
        self.lost = dict.fromkeys(self.samples, 0)
        self._gaps = {key: SequenceGaps() for key in self.samples}
        self.undecodable = {}
        self.statuses = {}
        self._writer = None
        self._conns = {}
        if not chunk_s >= 0:
            raise ValueError(f'`chunk_s` must be >= 0, got {chunk_s}')
        self.chunk_ns = int(round(chunk_s * 1e9))
        self._chunk_t0 = None

    def open(self):
        """Create the file and one channel per topic; write the config message."""
        from rosbags.rosbag2 import StoragePlugin, Writer
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = Writer(self.work, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        for key, row in self.topics.items():
            self._conns[key] = self._writer.add_connection(row.name, row.type,
                                                           typestore=self.typestore)
        for row in (CONFIG_TOPIC, NODE_PARAMETERS_TOPIC):
            self._conns[row.name] = self._writer.add_connection(row.name, row.type,
                                                                typestore=self.typestore)
        if self.config_text is not None:
            self.write_text(CONFIG_TOPIC, self.config_text, self.start_ns)
        return self

    def write_text(self, row, text, log_time_ns):
        """
        Write a text record of the recorder itself (not from DDS) on ``row``.

        Parameters
        ----------
        row : Topic
            :data:`~mr_damper_bringup.topics.CONFIG_TOPIC` or
            :data:`~mr_damper_bringup.topics.NODE_PARAMETERS_TOPIC`.
        text : str
            The YAML text (a ``std_msgs/String``).
        log_time_ns : int
            Record time [ns].

        """
        msg = self.typestore.types[row.type](data=str(text))
        self._writer.write(self._conns[row.name], int(log_time_ns),
                           self.typestore.serialize_cdr(msg, row.type))

    def measurements(self):
        """Return the measurement samples written, of every namespace (``[NS/]measurement``)."""
        return sum(self.samples.values())

    def _measurement_in(self, key, raw):
        """Return (samples in, messages lost before) one serialised measurement message."""
        row = self.topics[key]
        try:
            msg = self.typestore.deserialize_cdr(bytes(raw), row.type)
        except Exception:  # noqa: B902 - rosbags' SerdeError: one bad message, counted
            self.undecodable[key] = self.undecodable.get(key, 0) + 1
            return 0, 0
        if not hasattr(msg, 't_offset_s'):
            return 1, 0                 # a JointState: one sample, no sequence
        return len(msg.t_offset_s), self._gaps[key].offer(msg.sequence, msg.header.frame_id)

    def _status_in(self, key, raw):
        """Count the status names of one serialised ``DiagnosticArray``."""
        try:
            msg = self.typestore.deserialize_cdr(raw, self.topics[key].type)
        except Exception:  # noqa: B902 - rosbags' SerdeError: one bad message, counted
            self.undecodable[key] = self.undecodable.get(key, 0) + 1
            return
        for st in msg.status:
            name = str(st.name).split(':')[0].strip()
            self.statuses[name] = self.statuses.get(name, 0) + 1

    def write(self, key, raw, log_time_ns):
        """
        Write one serialised message.

        Parameters
        ----------
        key : str
            Topic key (a key of ``topics``).
        raw : bytes-like
            The CDR payload as the subscription delivered it (``raw=True``).
        log_time_ns : int
            Receive time [ns] (the recorder's clock).

        Returns
        -------
        int
            Messages of a measurement stream lost before this one (0 for other topics).

        """
        raw = bytes(raw)
        self._writer.write(self._conns[key], int(log_time_ns), raw)
        self._end_chunk_after(int(log_time_ns))
        self.counts[key] += 1
        if key in STATUS_KEYS:
            self._status_in(key, raw)
        if key not in self.samples:
            return 0
        samples, lost = self._measurement_in(key, raw)
        self.samples[key] += samples
        self.lost[key] += lost
        return lost

    def _end_chunk_after(self, log_time_ns):
        """Close and flush the open chunk once it spans ``chunk_s`` (rosbags 0.11.9 MCAP)."""
        if not self.chunk_ns:
            return
        if self._chunk_t0 is None:
            self._chunk_t0 = log_time_ns
        elif log_time_ns - self._chunk_t0 >= self.chunk_ns:
            storage = self._writer.storage       # rosbags' McapWriter (pinned version)
            if storage.chunk.bio.tell():
                storage.close_chunk()
                storage.bio.flush()
            self._chunk_t0 = None

    def close(self):
        """Finish the file (footer, index), move it to ``path``; return ``path``."""
        if self._writer is None:
            return self.path
        writer, self._writer = self._writer, None
        writer.close()
        inner = self.work / f'{self.work.name}.mcap'
        inner.replace(self.path)
        for leftover in self.work.iterdir():
            leftover.unlink()
        self.work.rmdir()
        return self.path

    def __enter__(self):
        return self.open()

    def __exit__(self, *exc):
        self.close()
        return False
