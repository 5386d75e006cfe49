"""
Read an MCAP file front to back, also one whose writer was killed (no footer, cut chunk).

rosbags (and every indexed MCAP reader) opens a file from its footer: a recording whose writer
was killed has none ("File end magic is invalid") and reads as nothing. The MCAP format is a
sequence of records, and the writer of the suite (rosbags) appends each chunk of about 1 MiB
whole to the file as it fills, so every chunk written before the kill is complete on disk.
:class:`McapScan` reads the records in file order with the ``mcap`` package's stream reader
(each chunk only once it is complete) and stops cleanly at the first record that is cut or
broken: it yields every message of the complete chunks and says whether the file was complete
and, if not, where it ends (messages read, last log time, the reason). A complete file (one
whose footer and index rosbags can read) is read with rosbags instead, in log-time order: about
twice as fast as the stream reader on a suite recording.

No ROS import; deserialisation with a rosbags type store (types named by the file's schemas are
registered from them when the store does not know them).
"""
from collections import namedtuple
from pathlib import Path
import struct

#: One channel of the file: topic name, message type (``pkg/msg/Name``), messages read.
Channel = namedtuple('Channel', 'topic msgtype')


class McapScan:
    """
    The messages of one MCAP file in file order, up to its last complete record.

    Parameters
    ----------
    path : str or Path
        The ``.mcap`` file.

    Attributes
    ----------
    complete : bool or None
        After a full pass of :meth:`messages`: True if the file ends with its footer (closed
        properly), False if it was cut (None before).
    count : int
        Messages read in the last pass.
    first_log_time_ns, last_log_time_ns : int or None
        Log times of the first and last message read.
    error : str or None
        Why the pass stopped before the footer (a cut record, a broken chunk).
    channels : dict
        Channel id -> :data:`Channel` (topic, message type), as met so far.

    """

    def __init__(self, path):
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f'{self.path}: no such MCAP file')
        self.complete = None
        self.count = 0
        self.first_log_time_ns = None
        self.last_log_time_ns = None
        self.error = None
        self.channels = {}
        self.schemas = {}          # type name -> (encoding, text)

    def messages(self, topics=None):
        """
        Yield ``(topic, msgtype, log_time_ns, data)`` for every message read.

        A complete file is read through its index (rosbags, log-time order), a cut one front to
        back (file order). ``count`` and the log times cover every topic either way.

        Parameters
        ----------
        topics : collection of str, optional
            Only these topics (default: all).

        """
        reader = self._indexed()
        if reader is None:
            yield from self._stream(topics)
            return
        self.complete, self.error = True, None
        try:
            conns = reader.connections
            self.channels = {k: Channel(c.topic, c.msgtype) for k, c in enumerate(conns)}
            for c in conns:
                self.schemas.setdefault(c.msgtype, (
                    'ros2msg' if c.msgdef.format.name == 'MSG' else 'ros2idl', c.msgdef.data))
            self.count = sum(c.msgcount for c in conns)
            self.first_log_time_ns = reader.start_time if self.count else None
            self.last_log_time_ns = reader.end_time - 1 if self.count else None
            wanted = [c for c in conns if topics is None or c.topic in topics]
            for conn, t_ns, raw in reader.messages(connections=wanted):
                yield conn.topic, conn.msgtype, t_ns, raw
        finally:
            reader.close()

    def _indexed(self):
        """Return an opened rosbags reader if the file is complete (footer, index), else None."""
        from rosbags.highlevel import AnyReader
        reader = AnyReader([self.path])
        try:
            reader.open()
        except Exception:  # noqa: B902 - any failure: read it front to back instead
            return None
        return reader

    def _stream(self, topics):
        """Yield the messages of :meth:`messages` front to back (the mcap stream reader)."""
        from mcap.exceptions import McapError
        from mcap.records import Channel as ChannelRecord, Footer, Message, Schema
        from mcap.stream_reader import StreamReader
        self.complete, self.count, self.error = False, 0, None
        self.first_log_time_ns = self.last_log_time_ns = None
        schema_names = {}
        with open(self.path, 'rb') as f:
            records = StreamReader(f, validate_crcs=True).records
            while True:
                try:
                    rec = next(records)
                except StopIteration:
                    break
                except (McapError, struct.error, ValueError, EOFError, MemoryError) as exc:
                    self.error = (f'{type(exc).__name__}: {exc}' if str(exc)
                                  else f'{type(exc).__name__}: the file ends before its footer')
                    break
                if isinstance(rec, Message):
                    ch = self.channels.get(rec.channel_id)
                    if ch is None:
                        continue
                    self.count += 1
                    if self.first_log_time_ns is None:
                        self.first_log_time_ns = rec.log_time
                    self.last_log_time_ns = rec.log_time
                    if topics is None or ch.topic in topics:
                        yield ch.topic, ch.msgtype, rec.log_time, rec.data
                elif isinstance(rec, Schema):
                    schema_names[rec.id] = rec.name
                    self.schemas.setdefault(rec.name, (rec.encoding, rec.data.decode()))
                elif isinstance(rec, ChannelRecord):
                    self.channels[rec.id] = Channel(rec.topic, schema_names.get(rec.schema_id,
                                                                                ''))
                elif isinstance(rec, Footer):
                    self.complete = True

    def topics(self):
        """Return ``{topic: (msgtype, messages)}`` from one pass over the file."""
        out = {}
        for topic, msgtype, _, _ in self.messages():
            out[topic] = (msgtype, out.get(topic, (msgtype, 0))[1] + 1)
        for ch in self.channels.values():
            out.setdefault(ch.topic, (ch.msgtype, 0))
        return out

    def deserialize(self, data, msgtype, typestore):
        """Deserialise one CDR message with ``typestore`` (types from the file's schemas)."""
        if msgtype not in typestore.fielddefs and msgtype in self.schemas:
            from rosbags.typesys import get_types_from_idl, get_types_from_msg
            encoding, text = self.schemas[msgtype]
            typestore.register(get_types_from_msg(text, msgtype) if encoding == 'ros2msg'
                               else get_types_from_idl(text))
        return typestore.deserialize_cdr(data, msgtype)

    def where(self):
        """Return where the last pass ended, in words (for a cut file)."""
        if self.complete:
            return f'{self.path}: complete, {self.count} messages'
        span = ''
        if self.first_log_time_ns is not None:
            span = (f', log time {self.first_log_time_ns * 1e-9:.3f}..'
                    f'{self.last_log_time_ns * 1e-9:.3f} s'
                    f' ({(self.last_log_time_ns - self.first_log_time_ns) * 1e-9:.1f} s)')
        return (f'{self.path}: truncated (no footer; its writer did not close it): '
                f'{self.count} messages read up to the last complete chunk{span}'
                f'{"; " + self.error if self.error else ""}')

    def summary(self):
        """Return the last pass as a dict: file, complete, messages, log times, error."""
        return {'file': str(self.path), 'complete': bool(self.complete),
                'messages': self.count,
                'first_log_time_s': (None if self.first_log_time_ns is None
                                     else self.first_log_time_ns * 1e-9),
                'last_log_time_s': (None if self.last_log_time_ns is None
                                    else self.last_log_time_ns * 1e-9),
                'error': self.error}
