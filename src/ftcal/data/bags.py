"""ROS 1 and ROS 2 bags (docs/formats.md §9), read with the pure-Python ``rosbags`` package.

A bag is a ROS 1 ``.bag`` file, a ROS 2 bag folder (``metadata.yaml`` plus
``.db3`` or ``.mcap`` storage), or a single ``.db3``/``.mcap`` file; no ROS
install is needed. :func:`read_bag` turns the topics named in a
:class:`BagTopics` into a :class:`~ftcal.data.recording.Recording`:

==============================  =================================================
``--wrench-topic``              ``geometry_msgs/WrenchStamped`` or ``Wrench`` →
                                F/T stream ``u1..u6`` (force N, torque N m)
``--joints-topic``              ``sensor_msgs/JointState`` → joint positions by name
``--temperature-topic``         ``sensor_msgs/Temperature`` or ``std_msgs/Float64``
                                → ``T`` (°C)
``--imu-topic``                 ``sensor_msgs/Imu`` → orientation ``qx,qy,qz,qw``
                                (when the IMU reports one), ``wx,wy,wz``, ``ax,ay,az``
``--tf BASE:SENSOR_FRAME``      ``tf2_msgs/TFMessage`` on ``/tf`` and ``/tf_static``
                                → orientation ``qx,qy,qz,qw`` of SENSOR_FRAME in BASE
==============================  =================================================

Stamps are the messages' ``header.stamp`` when the type has a header and the
stamps are set (not all zero), else (or with ``receive_time``) the bag's receive time; each stream's
:attr:`~ftcal.data.recording.Stream.clock` says which. Times are seconds since
the Unix epoch.

Wrench messages are decoded straight from their serialized bytes: the stamp
sits 4 bytes into the message and the six float64 of the wrench are its last
48 bytes, in both the ROS 1 layout and little-endian CDR (whatever the length
of ``frame_id``). Every other type goes through rosbags' deserializer.
"""

from __future__ import annotations

import reprlib
import struct
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from itertools import chain, islice
from pathlib import Path

import numpy as np

from ..core.limits import MAX_BAG_TIMESTAMP_NS, MAX_TEXT_FILE_BYTES
from ..runtime.errors import FtcalError, ParameterError, FtcalWarning
from ..runtime.inputs import check_folder_files, check_input_file
from .recording import Recording, Stream
from .tf_chain import QUATERNION_COLUMNS, TransformTree, check_unit_quaternions

WRENCH_TYPES = ("geometry_msgs/msg/WrenchStamped", "geometry_msgs/msg/Wrench")
JOINT_TYPES = ("sensor_msgs/msg/JointState",)
IMU_TYPES = ("sensor_msgs/msg/Imu",)
TEMPERATURE_TYPES = ("sensor_msgs/msg/Temperature", "std_msgs/msg/Float64")
TF_TYPES = ("tf2_msgs/msg/TFMessage",)
TF_TOPICS = ("/tf", "/tf_static")
HEADER_STAMPS = "header stamps"
RECEIVE_TIME = "receive time"
WRENCH_COLUMNS = ("u1", "u2", "u3", "u4", "u5", "u6")
# Messages decoded per numpy batch (bounds the memory of the raw bytes held at once).
BATCH = 1 << 16


@dataclass(frozen=True)
class BagTopics:
    """Which topics of a bag make up a recording.

    wrench : topic of the F/T sensor (WrenchStamped or Wrench); its clock is the dataset's
    joints, temperature, imu : optional topics
    tf : optional (base frame, sensor frame): the sensor's orientation from /tf and /tf_static; a sensor
        frame of None means the wrench messages' ``header.frame_id``
    receive_time : use the bag's receive time even where messages carry header stamps
    """

    wrench: str
    joints: str | None = None
    temperature: str | None = None
    imu: str | None = None
    tf: tuple[str, str | None] | None = None
    receive_time: bool = False


@dataclass(frozen=True)
class TopicSummary:
    """One topic of a bag: message type, message count and mean rate (Hz, receive time)."""

    name: str
    msgtype: str
    count: int
    rate: float | None


@contextmanager
def open_bag(path: str | Path) -> Iterator:
    """An open ``rosbags.highlevel.AnyReader`` on ``path``, errors as :class:`FtcalError`."""
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag1 import ReaderError as Ros1ReaderError
    from rosbags.rosbag2 import ReaderError as Ros2ReaderError
    from rosbags.typesys import Stores, TypesysError, get_typestore

    path = check_input_file(path, "bag (file or ROS 2 bag folder)", folder_ok=True)
    if path.is_dir():
        check_folder_files(path, "bag file")
    if path.is_dir() and (path / "metadata.yaml").is_file():
        check_bag_metadata(path / "metadata.yaml")
    for database in sorted(path.glob("*.db3")) if path.is_dir() else [path] if path.suffix == ".db3" else []:
        check_sqlite_bag(database)
    # What a damaged bag makes rosbags raise, opening (its index, in the file's summary) or reading: a flipped size
    # or offset gives ValueError, KeyError or struct.error ("unpack requires a buffer of 10 bytes", an MCAP record cut
    # short), which AnyReader passes through unwrapped.
    broken = (AnyReaderError, Ros1ReaderError, Ros2ReaderError, TypesysError, struct.error, MemoryError,
              *_storage_errors())
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.LATEST))
        reader.open()
    except (*broken, OSError, KeyError, ValueError) as exc:
        raise FtcalError(f"Bag {path}: cannot open it as a ROS 1 .bag, ROS 2 bag folder, .db3 or .mcap "
                         f"({type(exc).__name__}: {_one_line(exc)}).") from None
    try:
        yield reader
    except broken as exc:
        raise FtcalError(f"Bag {path}: cannot read it; it may be truncated or corrupt "
                         f"({type(exc).__name__}: {_one_line(exc)}).") from None
    finally:
        reader.close()


# Each table rosbags reads from a ROS 2 ``.db3``: (column, SQLite type it must hold, extra SQL condition
# every value must meet, what the condition means). SQLite stores any type in any column (its
# declared types are affinities), so a hostile or damaged file can hold text where rosbags reads an
# integer; every field is checked once, in SQL, before rosbags or ftcal reads it.
_SQLITE_FIELDS = {
    "topics": (("id", "integer", "id >= 0", "a non-negative integer"),
               ("name", "text", "length(name) > 0", "a non-empty topic name"),
               ("type", "text", "length(type) > 0", "a non-empty message type"),
               ("serialization_format", "text", None, "text"),
               ("offered_qos_profiles", "text", None, "text"),
               ("type_description_hash", "text", None, "text")),
    "message_definitions": (("topic_type", "text", None, "text"),
                            ("encoding", "text", "encoding IN ('ros2msg', 'ros2idl')", "'ros2msg' or 'ros2idl'"),
                            ("encoded_message_definition", "text", None, "text"),
                            ("type_description_hash", "text", None, "text")),
    "messages": (("id", "integer", None, "an integer"),
                 ("topic_id", "integer", "topic_id IN (SELECT id FROM topics)", "the id of a row of topics"),
                 ("timestamp", "integer", f"timestamp BETWEEN 0 AND {MAX_BAG_TIMESTAMP_NS}",
                  f"nanoseconds in [0, {MAX_BAG_TIMESTAMP_NS}]"),
                 ("data", "blob", None, "serialized message bytes")),
    "schema": (("schema_version", "integer", "schema_version >= 0", "a non-negative integer"),),
}


def _count(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= MAX_BAG_TIMESTAMP_NS


def _text(value) -> bool:
    return isinstance(value, str)


def _optional_text(value) -> bool:
    return value is None or isinstance(value, str)


# What rosbags reads from a ROS 2 bag folder's metadata.yaml (under rosbag2_bagfile_information):
# field path -> (check, what it must be). "[]" marks each item of a list.
_METADATA_FIELDS = (
    (("version",), _count, "a non-negative integer"),
    (("storage_identifier",), _text, "text (sqlite3 or mcap)"),
    (("relative_file_paths",), lambda v: isinstance(v, list) and all(map(_text, v)), "a list of file names"),
    (("compression_format",), _optional_text, "text"),
    (("compression_mode",), _optional_text, "text"),
    (("duration", "nanoseconds"), _count, "a non-negative integer (ns)"),
    (("starting_time", "nanoseconds_since_epoch"), _count, "a non-negative integer (ns)"),
    (("message_count",), _count, "a non-negative integer"),
    (("ros_distro",), _optional_text, "text"),
    (("custom_data",), lambda v: v is None or isinstance(v, dict), "a mapping"),
    (("topics_with_message_count",), lambda v: isinstance(v, list) and all(isinstance(x, dict) for x in v),
     "a list of mappings"),
    (("topics_with_message_count", "[]", "message_count"), _count, "a non-negative integer"),
    (("topics_with_message_count", "[]", "topic_metadata"), lambda v: isinstance(v, dict), "a mapping"),
    (("topics_with_message_count", "[]", "topic_metadata", "name"), lambda v: _text(v) and v != "",
     "a non-empty topic name"),
    (("topics_with_message_count", "[]", "topic_metadata", "type"), lambda v: _text(v) and v != "",
     "a non-empty message type"),
    (("topics_with_message_count", "[]", "topic_metadata", "serialization_format"), _text, "text"),
    (("topics_with_message_count", "[]", "topic_metadata", "type_description_hash"), _optional_text, "text"),
    (("topics_with_message_count", "[]", "topic_metadata", "offered_qos_profiles"),
     lambda v: v is None or isinstance(v, (str, list)), "a list or text"),
    (("files",), lambda v: v is None or (isinstance(v, list) and all(isinstance(x, dict) for x in v)),
     "a list of mappings"),
)
_MISSING = object()


def check_bag_metadata(path: Path) -> None:
    """Refuse a ROS 2 bag folder's ``metadata.yaml`` holding a field of the wrong type.

    rosbags reads these fields into arithmetic and string operations; a number where text
    belongs, text where a count belongs, or a mapping where a list belongs ends in a TypeError
    deep inside it. Each field it reads (:data:`_METADATA_FIELDS`) is checked first; a field
    that is absent is left to rosbags, which names it.

    Raises
    ------
    FtcalError
        Naming the file, the field (``topics_with_message_count[0].topic_metadata.name``), the value
        found and what it must be; or if the file is not YAML.
    """
    import yaml

    check_input_file(path, "bag metadata file", max_bytes=MAX_TEXT_FILE_BYTES)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise FtcalError(f"Bag {path.parent}: cannot read {path.name} as YAML ({type(exc).__name__}).") from None
    info = doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    if not isinstance(info, dict):
        raise FtcalError(f"Bag {path.parent}: {path.name} has no rosbag2_bagfile_information mapping.")

    def walk(node, keys: tuple, where: str):
        if not keys:
            yield where, node
            return
        if keys[0] == "[]":
            for k, item in enumerate(node if isinstance(node, list) else ()):
                yield from walk(item, keys[1:], f"{where}[{k}]")
            return
        if isinstance(node, dict):
            yield from walk(node.get(keys[0], _MISSING), keys[1:], f"{where}.{keys[0]}" if where else keys[0])

    for keys, check, meaning in _METADATA_FIELDS:
        for where, value in walk(info, keys, ""):
            if value is not _MISSING and not check(value):
                shown = reprlib.repr(value)  # bounded: YAML aliases can nest a value exponentially
                raise FtcalError(f"Bag {path.parent}: {path.name}: {where} is {shown}; it must be {meaning}.")


def check_sqlite_bag(path: Path) -> None:
    """Refuse a ROS 2 ``.db3`` whose tables hold a value of the wrong type or out of range.

    Every column of ``topics``, ``messages``, ``message_definitions`` and ``schema`` that
    rosbags or ftcal reads is checked for its SQLite storage type (``typeof``) and range (see
    ``_SQLITE_FIELDS``), in one SQL query per column, so no value of the wrong kind reaches Python.

    Raises
    ------
    FtcalError
        Naming the file, table, row id, column, the type found and what the column must hold;
        or if the file is not a readable SQLite database.
    """
    import sqlite3

    try:
        connection = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro&immutable=1", uri=True)
    except sqlite3.Error as exc:
        raise FtcalError(f"Bag {path}: cannot open it as an SQLite database ({exc}).") from None
    try:
        tables = {row[0] for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        for table, fields in _SQLITE_FIELDS.items():
            if table not in tables:
                continue
            columns = {row[1] for row in connection.execute(f"PRAGMA table_info({table})")}
            for column, kind, condition, meaning in fields:
                if column not in columns:
                    continue
                bad = f"typeof({column}) != '{kind}'" + (f" OR NOT ({condition})" if condition else "")
                row = connection.execute(f"SELECT rowid, typeof({column}), quote({column}) FROM {table} "
                                         f"WHERE {bad} LIMIT 1").fetchone()
                if row is not None:
                    rowid, found, value = row
                    shown = value if len(str(value)) <= 40 else f"{str(value)[:40]}..."
                    held = "NULL" if found == "null" else f"{found} {shown}"
                    raise FtcalError(f"Bag {path}: table {table}, row {rowid}: column {column} holds {held}; "
                                     f"it must be {meaning}.")
        if "topics" in tables and connection.execute(
                "SELECT COUNT(id) != COUNT(DISTINCT id) FROM topics").fetchone()[0]:
            raise FtcalError(f"Bag {path}: table topics: two rows share an id.")
    except sqlite3.Error as exc:
        raise FtcalError(f"Bag {path}: cannot read it as a ROS 2 SQLite bag; it may be truncated or corrupt "
                         f"({type(exc).__name__}: {exc}).") from None
    finally:
        connection.close()
def _one_line(exc: BaseException, limit: int = 300) -> str:
    """A library's error text on one line (rosbags quotes whole message definitions), at most ``limit`` characters."""
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[:limit] + " …"


def _storage_errors() -> tuple[type[BaseException], ...]:
    """What the storage libraries raise on a corrupt file: sqlite (``.db3``, through apsw or sqlite3)."""
    import sqlite3

    errors: list[type[BaseException]] = [sqlite3.Error]
    try:
        import apsw
    except ImportError:  # rosbags reads .db3 through apsw when it is installed
        pass
    else:
        errors.append(apsw.Error)
    return tuple(errors)


def list_topics(path: str | Path) -> list[TopicSummary]:
    """Every topic of the bag at ``path`` with its type, count and mean receive rate.

    Returns
    -------
    list of TopicSummary, sorted by topic name

    Raises
    ------
    FtcalError
        If the bag cannot be opened.
    """
    with open_bag(path) as reader:
        spans = _indexed_spans(reader)
        if spans is None:  # no index rosbags exposes: read every message's receive time
            spans = {}
            for connection, stamp, _ in reader.messages():
                first, _ = spans.get(connection.topic, (stamp, stamp))
                spans[connection.topic] = (first, stamp)
        out = []
        for name, info in sorted(reader.topics.items()):
            count = int(info.msgcount)
            first, last = spans.get(name, (0, 0))
            span = (last - first) * 1e-9
            rate = (count - 1) / span if count > 1 and span > 0 else None
            out.append(TopicSummary(name, info.msgtype or "(mixed types)", count, rate))
    return out


def _indexed_spans(reader) -> dict[str, tuple[int, int]] | None:
    """(first, last) receive time (ns) per topic from the bag's indexes, without reading message data.

    ROS 1: rosbags' per-connection index; sqlite3: one SQL query; MCAP: the message index records
    after each chunk. None when rosbags does not expose them as expected.
    """
    spans: dict[str, tuple[int, int]] = {}

    def widen(topic: str, first: int, last: int) -> None:
        old = spans.get(topic, (first, last))
        spans[topic] = (min(old[0], first), max(old[1], last))

    if len(reader.readers) != 1:
        return None
    bag = reader.readers[0]
    if not reader.is2:
        if not hasattr(bag, "indexes"):
            return None
        for connection in bag.connections:
            index = bag.indexes[connection.id]
            if index:
                widen(connection.topic, index[0].time, index[-1].time)
        return spans
    storage = getattr(bag, "storage", None)
    storages = getattr(storage, "storages", [storage])
    if storages and all(getattr(s, "dbconn", None) for s in storages):
        for s in storages:
            for topic, first, last in s.dbconn.execute(
                    "SELECT topics.name, MIN(messages.timestamp), MAX(messages.timestamp) FROM messages "
                    "JOIN topics ON messages.topic_id = topics.id GROUP BY topics.name"):
                widen(topic, first, last)
        return spans
    if not (storages and all(getattr(s, "chunks", None) and hasattr(s, "bio") for s in storages)):
        return None
    for s in storages:
        topic_of = {c.id: c.topic for c in s.connections}
        for chunk in s.chunks:
            for channel, offset in chunk.message_index_offsets.items():
                s.bio.seek(offset)
                head = s.bio.read(15)  # opcode 0x07, record length, channel id, byte length of the entries
                if len(head) != 15 or head[0] != 0x07:
                    return None
                size = int.from_bytes(head[11:15], "little")
                data = s.bio.read(size)
                if len(data) != size or size % 16:  # a damaged index: read the messages instead
                    return None
                entries = np.frombuffer(data, "<u8")[::2]  # (log_time, offset) pairs
                if entries.size and channel in topic_of:
                    widen(topic_of[channel], int(entries.min()), int(entries.max()))
    return spans


def read_bag(path: Path, topics: BagTopics | None = None) -> Recording:
    """Read the topics named in ``topics`` from the bag at ``path``.

    Parameters
    ----------
    path : Path
        ROS 1 ``.bag``, ROS 2 bag folder, ``.db3`` or ``.mcap`` file.
    topics : BagTopics
        The wrench topic (required) and the optional joints, temperature, IMU and tf selections.

    Returns
    -------
    Recording
        ``ft`` / ``temperature`` / ``accelerometers`` / ``gyros`` / ``orientations`` keyed by
        topic (orientation from tf keyed ``tf:BASE:SENSOR``), ``joints`` by joint name.

    Raises
    ------
    FtcalError
        A missing topic (the message lists the bag's topics), a topic of the wrong message type,
        non-unit quaternions, or a tf chain that does not connect the two frames.
    """
    if topics is None:
        raise ParameterError('wrench_topic', f"Bag {path}: name the F/T topic ({{wrench_topic}}); see 'ftcal topics {path}'.")
    path = Path(path)
    with open_bag(path) as reader:
        by_topic = reader.topics
        wanted = {"wrench_topic": (topics.wrench, WRENCH_TYPES), "joints_topic": (topics.joints, JOINT_TYPES),
                  "temperature_topic": (topics.temperature, TEMPERATURE_TYPES),
                  "imu_topic": (topics.imu, IMU_TYPES)}
        for option, (topic, types) in wanted.items():
            if topic is not None:
                _check_topic(path, by_topic, topic, types, option)
        receive_time = topics.receive_time
        ft = _read_wrench(path, reader, by_topic[topics.wrench], receive_time)
        extra: dict = {}
        if topics.temperature is not None:
            extra["temperature"] = {topics.temperature: _read_temperature(path, reader, by_topic[topics.temperature],
                                                                              receive_time)}
        if topics.joints is not None:
            extra["joints"] = _read_joints(path, reader, by_topic[topics.joints], receive_time)
        orientations = {}
        if topics.imu is not None:
            acc, gyro, orientation = _read_imu(path, reader, by_topic[topics.imu], receive_time)
            extra["accelerometers"] = {topics.imu: acc}
            extra["gyros"] = {topics.imu: gyro}
            if orientation is not None:
                orientations[topics.imu] = orientation
        if topics.tf is not None:
            base, frame = _tf_frames(path, topics, ft)
            tree = _read_tf(path, reader, by_topic, receive_time)
            orientations[tf_key(topics.tf)] = tree.orientation_stream(base, frame, ft.time,
                                                                      f"{path.name}:tf {base}->{frame}")
    return Recording(path, {topics.wrench: ft}, orientations=orientations, **extra)


def tf_key(frames: tuple[str, str | None]) -> str:
    """Key of the orientation from the tf chain ``frames`` = (base, sensor) in ``Recording.orientations``."""
    return f"tf:{frames[0]}:{frames[1] or ''}"


def _tf_frames(path: Path, topics: BagTopics, ft: Stream) -> tuple[str, str]:
    """(base, sensor) frames of the tf chain; the sensor frame defaults to the wrench's ``header.frame_id``."""
    base, frame = (None if f is None else f.lstrip("/") for f in topics.tf)  # tf2 ids have no leading slash
    wrench_frame = ft.frame.lstrip("/") if ft.frame else None
    if frame is None:
        if not wrench_frame:
            raise ParameterError('tf', f"Bag {path}: topic {topics.wrench!r} names no frame (header.frame_id); "
                             f"give the sensor frame as {{tf}} {base}:SENSOR_FRAME.")
        return base, wrench_frame
    if wrench_frame and wrench_frame != frame:
        warnings.warn(f"Bag {path}: {topics.wrench} is expressed in frame {wrench_frame!r} (header.frame_id) but "
                      f"the tf chain ends at {frame!r}; the orientation is that of {frame!r}.",
                      FtcalWarning, stacklevel=3)
    return base, frame


def _check_topic(path: Path, by_topic: dict, topic: str, types: tuple[str, ...], parameter: str) -> None:
    if topic not in by_topic:
        have = ", ".join(sorted(by_topic)) or "none"
        raise ParameterError(parameter, f"Bag {path}: no topic {topic!r} ({{{parameter}}}); the bag has: {have}.")
    msgtype = by_topic[topic].msgtype
    if msgtype not in types:
        raise ParameterError(parameter, f"Bag {path}: topic {topic!r} has type {msgtype}; {{{parameter}}} needs "
                             f"{' or '.join(types)}.")
    if by_topic[topic].msgcount == 0:
        raise ParameterError(parameter, f"Bag {path}: topic {topic!r} ({{{parameter}}}) has no messages.")


def _stamps(header_ns: np.ndarray | None, receive_ns: np.ndarray, receive_time: bool) -> tuple[np.ndarray, str]:
    """Header stamps when present, set and not overridden by ``receive_time``, else receive times (float s)."""
    if header_ns is not None and not receive_time and np.any(header_ns != 0):
        return header_ns * 1e-9, HEADER_STAMPS
    return np.asarray(receive_ns, dtype=np.float64) * 1e-9, RECEIVE_TIME


def _read_wrench(path: Path, reader, info, receive_time: bool) -> Stream:
    """Decode every wrench message of the topic from its bytes, one numpy batch at a time."""
    topic = info.connections[0].topic
    stamped = info.msgtype == WRENCH_TYPES[0]
    cdr = reader.is2
    receives, headers, wrenches = [], [], []
    frame_id = None
    done = 0
    for batch_receive, buffer, starts, lengths in _fastest_batches(path, reader, info):
        _check_wrench_layout(path, topic, buffer, starts, lengths, stamped, cdr, done)
        receives.append(batch_receive)
        wrenches.append(_gather(buffer, starts + lengths - 48, 48).view("<f8"))
        if stamped:
            stamp = _gather(buffer, starts + 4, 8)
            sec = stamp[:, :4].copy().view("<i4" if cdr else "<u4")[:, 0].astype(np.int64)
            nsec = stamp[:, 4:].copy().view("<u4")[:, 0].astype(np.int64)
            headers.append(sec * 1_000_000_000 + nsec)
            if frame_id is None:
                at = int(starts[0]) + 16
                strlen = int(buffer[at - 4:at].view("<u4")[0])
                frame_id = bytes(buffer[at:at + strlen]).rstrip(b"\0").decode("utf-8", "replace")
        done += starts.size
    if not done:
        raise FtcalError(f"Bag {path}: topic {topic!r} has no messages.")
    receive, wrench = np.concatenate(receives), np.concatenate(wrenches)
    header = np.concatenate(headers) if stamped else None
    order = np.argsort(receive, kind="stable")  # the bag's order, as rosbags' loop yields it
    time, clock = _stamps(None if header is None else header[order], receive[order], receive_time)
    return Stream(f"{path.name}:{topic}", time, wrench[order], WRENCH_COLUMNS, clock=clock, frame=frame_id)


Batch = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # receive ns, bytes, message starts, lengths


def _fastest_batches(path: Path, reader, info) -> Iterator[Batch]:
    """Straight from the storage when rosbags exposes it as expected (ROS 1, MCAP, sqlite3), else its loop."""
    if len(reader.readers) == 1:
        if not reader.is2 and hasattr(reader.readers[0], "indexes"):
            return _ros1_batches(path, reader, info)
        storage = getattr(reader.readers[0], "storage", None)
        storages = getattr(storage, "storages", [storage])
        if storages and all(getattr(s, "chunks", None) and hasattr(s, "bio") for s in storages):
            return _mcap_batches(storages, info)
        if storages and all(getattr(s, "dbconn", None) for s in storages):
            return _sqlite_batches(storages, info)
    return _batches(reader, info)


def _batches(reader, info) -> Iterator[Batch]:
    """Any bag: ``BATCH`` messages at a time from rosbags' message loop, joined into one buffer."""
    messages = reader.messages(info.connections)
    while batch := list(islice(messages, BATCH)):
        raws = [m[2] for m in batch]
        lengths = np.fromiter(map(len, raws), np.int64, len(raws))
        yield (np.fromiter((m[1] for m in batch), np.int64, len(batch)), np.frombuffer(b"".join(raws), np.uint8),
               np.cumsum(lengths) - lengths, lengths)


def _ros1_batches(path: Path, reader, info) -> Iterator[Batch]:
    """ROS 1: one batch per chunk, message records located from rosbags' chunk index with numpy.

    rosbags' own loop parses every record header in Python, which caps it near 200k messages/s.
    The chunk index already gives each message record's offset in its (decompressed) chunk; a
    record is ``header_len, header, data_len, data``, and every message-data record header holds
    the same three fields (op, conn, time), hence the same size.
    """
    (bag,) = reader.readers
    entries = [bag.indexes[c.id] for c in info.connections]
    count = sum(map(len, entries))
    table = np.fromiter(chain.from_iterable(chain.from_iterable(entries)), np.int64, 3 * count).reshape(-1, 3)
    table = table[np.argsort(table[:, 0], kind="stable")]  # columns: time, chunk position, offset
    runs = np.flatnonzero(np.r_[True, table[1:, 1] != table[:-1, 1], True])
    for a, b in zip(runs[:-1], runs[1:]):
        chunk = bag.chunks[int(table[a, 1])]
        bag.bio.seek(chunk.datapos)
        buffer = np.frombuffer(chunk.decompressor(bag.bio.read(chunk.datasize)), np.uint8)
        offsets = table[a:b, 2]
        size = int(buffer[offsets[0]:offsets[0] + 4].view("<u4")[0]) if offsets[0] + 4 <= buffer.size else -1
        op = bytes(buffer[offsets[0] + 4:offsets[0] + 4 + size]).find(b"op=") if size > 0 else -1
        ok = op >= 0 and offsets.max() + 8 + size <= buffer.size
        ok = ok and np.all(_gather(buffer, offsets, 4).view("<u4")[:, 0] == size)
        ok = ok and np.all(buffer[offsets + 4 + op + 3] == 2)  # 2: message data record
        if ok:
            lengths = _gather(buffer, offsets + 4 + size, 4).view("<u4")[:, 0].astype(np.int64)
            starts = offsets + 8 + size
            ok = bool(np.all(starts + lengths <= buffer.size))
        if not ok:
            raise FtcalError(f"Bag {path}: chunk at byte {int(table[a, 1])} does not hold the message records its "
                             f"index points to (corrupt bag?).")
        yield table[a:b, 0], buffer, starts, lengths


def _sqlite_batches(storages: list, info) -> Iterator[Batch]:
    """ROS 2 sqlite3: the messages table read straight from the database cursor, ``BATCH`` rows at a time."""
    for storage in storages:
        ids = sorted({c.id for c in storage.connections if c.topic == info.connections[0].topic})
        if not ids:
            continue
        cursor = storage.dbconn.execute(f"SELECT timestamp, data FROM messages WHERE topic_id IN "
                                        f"({','.join('?' * len(ids))}) ORDER BY timestamp", ids)
        while rows := list(islice(cursor, BATCH)):
            raws = [r[1] for r in rows]
            lengths = np.fromiter(map(len, raws), np.int64, len(raws))
            yield (np.fromiter((r[0] for r in rows), np.int64, len(rows)), np.frombuffer(b"".join(raws), np.uint8),
                   np.cumsum(lengths) - lengths, lengths)


def _mcap_batches(storages: list, info) -> Iterator[Batch]:
    """MCAP: one batch per chunk, message records found by a light walk over the decompressed chunk.

    A record is ``opcode u8, length u64, content``; a message record (opcode 5) holds
    ``channel u16, sequence u32, log_time u64, publish_time u64, data``.
    """
    from rosbags.rosbag2.storage_mcap import decompress

    record = struct.Struct("<BQ").unpack_from
    channel_of = struct.Struct("<H").unpack_from
    for storage in storages:
        channels = {c.id for c in storage.connections if c.topic == info.connections[0].topic}
        for chunk in sorted(storage.chunks, key=lambda c: c.message_start_time):
            if not any(chunk.channel_count.get(c, 0) for c in channels):
                continue
            storage.bio.seek(chunk.chunk_start_offset + 9 + 24)
            crc = int.from_bytes(storage.bio.read(4), "little")
            storage.bio.seek(chunk.chunk_start_offset + 9 + 40 + len(chunk.compression))
            raw = decompress(storage.bio.read(chunk.compressed_size), chunk.compression, chunk.uncompressed_size, crc)
            starts, pos, end = [], 0, len(raw)
            while pos < end:
                op, size = record(raw, pos)
                if op == 5 and channel_of(raw, pos + 9)[0] in channels:
                    starts.append(pos)
                pos += 9 + size
            if not starts:
                continue
            offsets = np.array(starts, dtype=np.int64)
            buffer = np.frombuffer(raw, np.uint8)
            sizes = _gather(buffer, offsets + 1, 8).view("<u8")[:, 0].astype(np.int64)
            log_time = _gather(buffer, offsets + 15, 8).view("<u8")[:, 0].astype(np.int64)
            order = np.argsort(log_time, kind="stable")
            yield log_time[order], buffer, (offsets + 31)[order], (sizes - 22)[order]


def _check_wrench_layout(path: Path, topic: str, buffer: np.ndarray, starts: np.ndarray, lengths: np.ndarray,
                         stamped: bool, cdr: bool, first: int) -> None:
    """Each message's length must match its frame_id length (else the bytes are not what we decode)."""
    if cdr:
        encapsulation = _gather(buffer, starts, 2)
        little = (encapsulation[:, 0] == 0) & (encapsulation[:, 1] == 1)
        if not little.all():
            k = int(np.argmin(little))
            raise FtcalError(f"Bag {path}: topic {topic!r} message {first + k} is not little-endian CDR.")
    if stamped:
        strlen = _gather(buffer, np.minimum(starts + 12, buffer.size - 4), 4).view("<u4")[:, 0].astype(np.int64)
        body = 12 + strlen  # CDR: after the 4-byte encapsulation, aligned to 8 for the float64s
        expected = 4 + ((body + 7) & ~7) + 48 if cdr else 16 + strlen + 48
    else:
        expected = np.full(lengths.shape, 4 + 48 if cdr else 48)
    bad = (lengths != expected) | (lengths < (16 + 48 if stamped else 48))
    if bad.any():
        k = int(np.argmax(bad))
        raise FtcalError(f"Bag {path}: topic {topic!r} message {first + k} has {lengths[k]} bytes, not a "
                         f"serialized {'WrenchStamped' if stamped else 'Wrench'}.")


def _gather(buffer: np.ndarray, offsets: np.ndarray, width: int) -> np.ndarray:
    """Rows ``buffer[o:o + width]`` for each offset, as a contiguous (n, width) uint8 array."""
    return buffer[offsets[:, None] + np.arange(width)]


def _deserialized(reader, info) -> Iterator[tuple[int, object]]:
    for connection, stamp, raw in reader.messages(info.connections):
        yield stamp, reader.deserialize(raw, connection.msgtype)


def _header_ns(msg) -> int:
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _read_temperature(path: Path, reader, info, receive_time: bool) -> Stream:
    topic = info.connections[0].topic
    receive, header, values = [], [], []
    stamped = info.msgtype == TEMPERATURE_TYPES[0]
    for stamp, msg in _deserialized(reader, info):
        receive.append(stamp)
        header.append(_header_ns(msg) if stamped else 0)
        values.append(msg.temperature if stamped else msg.data)
    time, clock = _stamps(np.array(header) if stamped else None, np.array(receive), receive_time)
    return Stream(f"{path.name}:{topic}", time, np.array(values, dtype=np.float64)[:, None], ("T",), clock=clock)


def _read_joints(path: Path, reader, info, receive_time: bool) -> Stream:
    """Joint positions by name; messages that carry different joint sets are merged on the largest set's clock."""
    topic = info.connections[0].topic
    groups: dict[frozenset, tuple[tuple[str, ...], list, list, list]] = {}
    for stamp, msg in _deserialized(reader, info):
        names = tuple(msg.name)
        if len(msg.position) != len(names) or len(set(names)) != len(names):
            raise FtcalError(f"Bag {path}: topic {topic!r}: a JointState message has {len(names)} names "
                             f"({len(set(names))} distinct) but {len(msg.position)} positions.")
        columns, receive, header, rows = groups.setdefault(frozenset(names), (names, [], [], []))
        position = np.asarray(msg.position, dtype=np.float64)
        receive.append(stamp)
        header.append(_header_ns(msg))
        rows.append(position if names == columns else position[[names.index(c) for c in columns]])
    streams = []
    for columns, receive, header, rows in groups.values():
        time, clock = _stamps(np.array(header), np.array(receive), receive_time)
        streams.append(Stream(f"{path.name}:{topic}", time, np.array(rows).reshape(len(rows), len(columns)),
                              columns, clock=clock))
    main = max(streams, key=lambda s: s.n_samples)
    if len(streams) == 1:
        return main
    # Joint sets change within the bag (a gripper's joint appears halfway): merge every message on one
    # clock, so no sample is lost; a joint is interpolated within the span it was published in and is NaN
    # outside it (the table's users then drop that joint, or refuse naming it and the time).
    time = np.unique(np.concatenate([s.time for s in streams]))
    columns = list(dict.fromkeys(name for s in streams for name in s.columns))
    data = np.full((time.size, len(columns)), np.nan)
    for j, name in enumerate(columns):
        t = np.concatenate([s.time for s in streams if name in s.columns])
        v = np.concatenate([s.data[:, s.columns.index(name)] for s in streams if name in s.columns])
        order = np.argsort(t, kind="stable")
        t, v = t[order], v[order]
        inside = (time >= t[0]) & (time <= t[-1])
        data[inside, j] = np.interp(time[inside], t, v)
    return Stream(main.name, time, data, tuple(columns), clock=main.clock)


def _read_imu(path: Path, reader, info, receive_time: bool) -> tuple[Stream, Stream, Stream | None]:
    """Linear acceleration, angular velocity and (when reported) orientation of an IMU topic."""
    topic = info.connections[0].topic
    receive, header, rows, has_orientation = [], [], [], []
    for stamp, msg in _deserialized(reader, info):
        receive.append(stamp)
        header.append(_header_ns(msg))
        o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        rows.append((a.x, a.y, a.z, w.x, w.y, w.z, o.x, o.y, o.z, o.w))
        # REP 145: orientation_covariance[0] == -1 means the IMU does not estimate orientation.
        has_orientation.append(msg.orientation_covariance[0] != -1)
    time, clock = _stamps(np.array(header), np.array(receive), receive_time)
    data = np.array(rows, dtype=np.float64)
    name = f"{path.name}:{topic}"
    acc = Stream(name, time, data[:, 0:3], ("ax", "ay", "az"), clock=clock)
    gyro = Stream(name, time, data[:, 3:6], ("wx", "wy", "wz"), clock=clock)
    quaternions = data[:, 6:10]
    # REP 145 marks a missing orientation with covariance[0] = -1; many drivers just send zeros.
    if not any(has_orientation) or not np.any(quaternions):
        return acc, gyro, None
    check_unit_quaternions(quaternions, time, f"Bag {path}: topic {topic!r}")
    return acc, gyro, Stream(name, time, quaternions, QUATERNION_COLUMNS, clock=clock)


def _read_tf(path: Path, reader, by_topic: dict, receive_time: bool) -> TransformTree:
    present = [t for t in TF_TOPICS if t in by_topic]
    if not present:
        have = ", ".join(sorted(by_topic)) or "none"
        raise ParameterError('tf', f"Bag {path}: {{tf}} needs /tf or /tf_static; the bag has: {have}.")
    tree = TransformTree(f"Bag {path}")
    for topic in present:
        info = by_topic[topic]
        if info.msgtype not in TF_TYPES:
            raise ParameterError('tf', f"Bag {path}: topic {topic!r} has type {info.msgtype}; {{tf}} needs {TF_TYPES[0]}.")
        for stamp, msg in _deserialized(reader, info):
            for t in msg.transforms:
                header = _header_ns(t)
                r = t.transform.rotation
                when = stamp if receive_time else header or stamp
                tree.add(t.header.frame_id.lstrip("/"), t.child_frame_id.lstrip("/"), when * 1e-9,
                         (r.x, r.y, r.z, r.w), static=topic == "/tf_static")
    return tree
