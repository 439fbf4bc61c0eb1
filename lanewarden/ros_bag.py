"""Reading ROS 2 recordings within bounds: MCAP files (a Lanewarden run.mcap or anyone's),
rosbag2 folders (metadata.yaml + .mcap or .db3 files) and bare .db3 files.

A recording is input like any other file, so nothing in one may crash the reader, make it
allocate without bound or run for long:
- MCAP records are walked one by one (opcode, length), each length checked against what is left
  of the file and against `MAX_RECORD_BYTES` before anything is read; a chunk's uncompressed size
  is checked against `MAX_CHUNK_BYTES` and decompressed with that bound (a zstd or lz4 "bomb"
  stops there); all chunks of a file decompress to at most `MAX_EXPANSION` times its size and
  hold at most one record per byte of it, so a pass costs about what an uncompressed file of
  its size would. Of the records, only what is used is read and kept: a chunk's schema, channel
  and message records (MCAP puts nothing else in one), names within `MAX_NAME_BYTES`, at most
  `MAX_TOPICS` topics, and of the metadata and attachments those of a Lanewarden recording
  (`KEPT_NAMES`); messages, metadata and attachments are parsed by the `mcap` library's record
  classes.
- A chunk's and an attachment's CRC-32, when the writer computed one (0: none), is checked: a
  byte altered inside a chunk (every message Lanewarden records, its steps and frames) or an
  attachment (the config and calibration) is one line naming the byte offset of the damaged
  record, never data replayed as if a program had changed. MCAP gives metadata records (the
  run's meta and summary) no CRC of their own, and Lanewarden's recorder writes no CRC of the
  whole data section, so damage there is found only where it breaks the record.
- A file that ends before MCAP's footer was cut short (a run killed, a full disk): every whole
  record before the cut is read and `McapFile.cut_short` says where it ended, so a replay can
  use what there is and say the recording is incomplete.
- Messages are CDR-decoded by `mcap-ros2-support` with the definitions this project knows
  (lanewarden.run_mcap.DEFINITIONS: the two image types and Lanewarden's own), whatever text a
  file embeds for them (a .db3 of ROS 2 Humble embeds none); a message that does not decode is
  one line (`InputFileError`) naming the file, topic and message number (`message_name`:
  counted from 0 on its topic, as replay counts frames and steps).
- .db3 files are SQLite databases, read through Python's own sqlite3 module, read-only; their
  `topics` and `messages` must be stored tables (a view, a virtual table or a generated column
  makes work the file does not hold: a recursive view never ends), no value larger than
  `MAX_MESSAGE_BYTES` is fetched, and every value is checked for its type.

Never prints, never reads a clock. Errors are `InputFileError` (exit code 2), one line each.
"""

from __future__ import annotations

import io
import sqlite3
import struct
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import lz4.frame
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Attachment, Chunk, Metadata, Schema
from mcap.records import Message as McapMessage
from mcap_ros2.decoder import DecoderFactory

from lanewarden.documents import MAX_DOCUMENT_BYTES, read_yaml_document, shorten, shown_value
from lanewarden.errors import InputFileError
from lanewarden.run_mcap import (
    CALIBRATION_ATTACHMENT,
    CONFIG_ATTACHMENT,
    DEFINITIONS,
    META_NAME,
    SUMMARY_NAME,
)
from lanewarden.sqlite_tables import computed_table

MCAP_MAGIC = b"\x89MCAP0\r\n"
#: Largest MCAP record read into memory (a chunk, an attachment, a message outside chunks).
MAX_RECORD_BYTES = 128 * 1024 * 1024
#: Largest chunk once decompressed.
MAX_CHUNK_BYTES = 128 * 1024 * 1024
#: A file's chunks may decompress to this many times its size in all (and to MAX_CHUNK_BYTES
#: whatever its size); it may hold at most one record per byte. So reading a file costs about
#: what reading an uncompressed file of its size costs: without these bounds a few kB of zstd or
#: lz4 per chunk made seconds of work each (128 MiB of zeros, or 15 million empty records).
MAX_EXPANSION = 1000
#: Largest single message (a raw 4K colour image is 25 MB).
MAX_MESSAGE_BYTES = 64 * 1024 * 1024
#: Attachments are kept up to this size, plus one byte (the config and calibration a run used
#: are a few kB; their readers refuse anything larger).
MAX_ATTACHMENT_BYTES = MAX_DOCUMENT_BYTES
#: Longest schema (message type), topic, encoding, metadata or attachment name read: a ROS 2
#: name is far shorter. Each schema and channel record of a file is noted (a few kB of zstd
#: can repeat them by the million), so these bound the memory a file can make the reader keep.
MAX_NAME_BYTES = 1000
#: Most topics a file may have.
MAX_TOPICS = 10_000
#: The metadata and attachments kept: what replay reads of a Lanewarden recording (its meta,
#: summary, config and calibration); others are skipped unread.
KEPT_NAMES = frozenset({META_NAME, SUMMARY_NAME, CONFIG_ATTACHMENT, CALIBRATION_ATTACHMENT})
#: What a chunk may hold (MCAP: a batch of schema, channel and message records); anything else
#: in one is skipped unread.
_IN_CHUNKS = (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE)
_RECORD_HEAD = struct.Struct("<BQ")
#: `McapFile.cut_short` of a file of 0 bytes.
EMPTY = "is empty (0 bytes)"
_CRC = struct.Struct("<I")
#: Which topics to read (None: all).
TopicFilter = Callable[["BagTopic"], bool] | None


@dataclass(frozen=True)
class BagTopic:
    name: str
    type: str  # the schema (message type) name, e.g. sensor_msgs/msg/Image
    encoding: str  # the message encoding, "cdr" for ROS 2


@dataclass(frozen=True)
class BagMessage:
    topic: BagTopic
    number: int  # per topic, in file order, counted from 0 (as frames): for error messages
    sequence: int  # MCAP's sequence field (0 where the file has none)
    log_time_ns: int
    data: bytes


def message_name(topic: str, number: int) -> str:
    """'/camera message 4 (counted from 0)': a message by its number on its topic, counted from 0
    as replay counts frames and steps (an image topic's message 4 is frame 4); they had been
    counted from 1 here alone."""
    return f"{topic} message {number} (counted from 0)"


def _problem(path: Path, offset: int, what: str) -> InputFileError:
    return InputFileError(f"{path}: {what} at byte {offset}; not a readable MCAP recording")


@dataclass
class _Cost:
    """What one pass over an MCAP file of `size` bytes has cost so far: the bytes its chunks
    decompressed to and the records they held, each refused past its bound (MAX_EXPANSION)."""

    path: Path
    size: int
    expanded: int = 0
    records: int = 0

    def expand(self, chunk_bytes: int, offset: int) -> None:
        self.expanded += chunk_bytes
        budget = max(MAX_CHUNK_BYTES, MAX_EXPANSION * self.size)
        if self.expanded > budget:
            raise _problem(self.path, offset, f"chunks decompressing to more than {budget} "
                           f"bytes in all ({MAX_EXPANSION} times the file's {self.size} bytes, "
                           f"or {MAX_CHUNK_BYTES}: a decompression bomb?)")

    def record(self, offset: int) -> None:
        self.records += 1
        if self.records > self.size:
            raise _problem(self.path, offset, f"chunks holding more than {self.size} records "
                           "in all (one per byte of the file: a decompression bomb?)")


def _decompress(chunk: Chunk, path: Path, offset: int, cost: _Cost) -> bytes:
    size = chunk.uncompressed_size
    if size > MAX_CHUNK_BYTES:
        raise _problem(path, offset, f"a chunk of {size} bytes uncompressed (more than "
                       f"{MAX_CHUNK_BYTES})")
    cost.expand(size, offset)
    try:
        if chunk.compression == "":
            data = chunk.data
        elif chunk.compression == "zstd":
            with zstandard.ZstdDecompressor().stream_reader(io.BytesIO(chunk.data)) as reader:
                data = reader.read(size + 1)
        elif chunk.compression == "lz4":
            data = lz4.frame.LZ4FrameDecompressor().decompress(chunk.data, max_length=size + 1)
        else:
            raise _problem(path, offset, f"chunk compression {chunk.compression!r} (expected "
                           "none, zstd or lz4)")
    except (zstandard.ZstdError, RuntimeError) as exc:
        raise _problem(path, offset, f"a damaged compressed chunk ({shorten(str(exc))})") from None
    if len(data) != size:
        raise _problem(path, offset, f"a chunk of {len(data)} bytes where its header says "
                       f"{size}")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise _problem(path, offset, "a chunk whose CRC does not match its data (the file is "
                       "damaged)")
    return bytes(data)


def _read_chunk(body: bytes, path: Path, offset: int) -> Chunk:
    """A chunk record's fields; its header damaged (a length past its end, a compression name
    that is not UTF-8) is one line."""
    try:
        return Chunk.read(ReadDataStream(io.BytesIO(body)))
    except Exception as exc:  # EndOfFile, struct.error, UnicodeDecodeError, OverflowError
        raise _problem(path, offset, f"a damaged chunk record ({type(exc).__name__})") from None


def _check_attachment_crc(body: bytes, path: Path, offset: int) -> None:
    """An attachment record ends with the CRC-32 of the body before it (0: none written)."""
    if len(body) < _CRC.size:
        return  # too short to hold one: its reader says it is damaged
    (crc,) = _CRC.unpack_from(body, len(body) - _CRC.size)
    if crc and zlib.crc32(body[:-_CRC.size]) != crc:
        raise _problem(path, offset, "an attachment whose CRC does not match its data (the "
                       "file is damaged)")


def _records(data: bytes, path: Path, base: int, cost: _Cost) -> Iterator[tuple[int, bytes, int]]:
    """(opcode, body, offset) of every schema, channel and message record in `data` (a chunk's
    content); a record running past the end is a damaged chunk."""
    position = 0
    while position < len(data):
        cost.record(base)
        if position + _RECORD_HEAD.size > len(data):
            raise _problem(path, base, "a damaged chunk (a record header cut short)")
        opcode, length = _RECORD_HEAD.unpack_from(data, position)
        start = position + _RECORD_HEAD.size
        if length > len(data) - start:
            raise _problem(path, base, f"a damaged chunk (a record of {length} bytes with "
                           f"{len(data) - start} left)")
        if opcode in _IN_CHUNKS:
            yield opcode, data[start:start + length], base
        position = start + length


@dataclass
class McapFile:
    """One MCAP file, read front to back by `messages()` (call it again for another pass).
    After a complete pass: `topics`, `metadata` (name -> key/values) and `attachments` (name ->
    bytes, cut one byte past MAX_ATTACHMENT_BYTES) of the names in KEPT_NAMES, and `cut_short`
    (None when the file ended with MCAP's footer, else where and how it ended)."""

    path: Path
    topics: dict[str, BagTopic] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    cut_short: str | None = None

    def messages(self, keep: TopicFilter = None) -> Iterator[BagMessage]:
        """Every message (on the topics `keep` keeps, when given) in file order."""
        schemas: dict[int, str] = {}
        channels: dict[int, BagTopic] = {}
        counts: dict[str, int] = {}
        self.cut_short = None
        try:
            stream = self.path.open("rb")
        except OSError as exc:
            raise InputFileError(f"{self.path}: cannot read ({exc.strerror or exc})") from None
        with stream:
            size = self.path.stat().st_size
            magic = stream.read(len(MCAP_MAGIC))
            if magic != MCAP_MAGIC:
                if not magic:
                    self.cut_short = EMPTY
                    return
                if len(magic) < len(MCAP_MAGIC) and MCAP_MAGIC.startswith(magic):
                    self.cut_short = f"ends at byte {len(magic)}, before MCAP's first record"
                    return  # written by nothing yet, or cut before its first bytes
                raise InputFileError(f"{self.path}: not an MCAP file (no MCAP magic at its "
                                     "start)")
            offset = len(MCAP_MAGIC)
            cost = _Cost(self.path, size)
            while True:
                head = stream.read(_RECORD_HEAD.size)
                if len(head) < _RECORD_HEAD.size:
                    self.cut_short = f"ends at byte {offset} without MCAP's footer"
                    return
                opcode, length = _RECORD_HEAD.unpack(head)
                if length > MAX_RECORD_BYTES:
                    raise _problem(self.path, offset, f"a record of {length} bytes (more than "
                                   f"{MAX_RECORD_BYTES})")
                if length > size - offset - _RECORD_HEAD.size:
                    self.cut_short = (f"ends at byte {size} inside a record that starts at "
                                      f"byte {offset}")
                    return
                body = stream.read(length)
                if opcode == Opcode.FOOTER:
                    return  # complete: the summary section and the footer were read
                if opcode == Opcode.CHUNK:
                    chunk = _read_chunk(body, self.path, offset)
                    inner = _records(_decompress(chunk, self.path, offset, cost), self.path,
                                     offset, cost)
                else:
                    inner = iter([(opcode, body, offset)])
                for code, record, where in inner:
                    message = self._record(code, record, where, schemas, channels)
                    if message is None:
                        continue
                    topic = channels.get(message.channel_id)
                    if topic is None:
                        raise _problem(self.path, where, f"a message on unknown channel "
                                       f"{message.channel_id}")
                    if keep is not None and not keep(topic):
                        continue
                    if len(message.data) > MAX_MESSAGE_BYTES:
                        raise _problem(self.path, where, f"a message of {len(message.data)} "
                                       f"bytes on {topic.name} (more than {MAX_MESSAGE_BYTES})")
                    number = counts.get(topic.name, 0)
                    counts[topic.name] = number + 1
                    yield BagMessage(topic, number, message.sequence, message.log_time,
                                     message.data)
                offset += _RECORD_HEAD.size + length

    def _record(self, opcode: int, body: bytes, offset: int, schemas: dict[int, str],
                channels: dict[int, BagTopic]) -> McapMessage | None:
        """Note a schema, channel, metadata or attachment record; return a message record.
        Only what is used is read and kept (see `_name`, MAX_TOPICS, KEPT_NAMES): a schema's
        text and a channel's metadata are skipped unread."""
        if opcode == Opcode.ATTACHMENT:  # damage is said as such, not as a damaged record
            _check_attachment_crc(body, self.path, offset)
        stream = ReadDataStream(io.BytesIO(body))
        try:
            if opcode == Opcode.MESSAGE:
                return McapMessage.read(stream, len(body))
            if opcode == Opcode.SCHEMA:
                schema_id = stream.read2()
                schemas[schema_id] = self._name(stream, "schema name", offset)
            elif opcode == Opcode.CHANNEL:
                channel_id, schema_id = stream.read2(), stream.read2()
                name = self._name(stream, "topic name", offset)
                topic = BagTopic(name, schemas.get(schema_id, ""),
                                 self._name(stream, "message encoding", offset))
                if name not in self.topics and len(self.topics) >= MAX_TOPICS:
                    raise _problem(self.path, offset, f"more than {MAX_TOPICS} topics")
                channels[channel_id] = self.topics.setdefault(name, topic)
            elif opcode == Opcode.METADATA:
                if self._name(stream, "metadata name", offset) in KEPT_NAMES:
                    if len(body) > MAX_DOCUMENT_BYTES:  # Lanewarden's are a few kB
                        raise _problem(self.path, offset, f"a metadata record of {len(body)} "
                                       f"bytes (more than {MAX_DOCUMENT_BYTES})")
                    metadata = Metadata.read(ReadDataStream(io.BytesIO(body)))
                    self.metadata[metadata.name] = dict(metadata.metadata)
            elif opcode == Opcode.ATTACHMENT:
                stream.read(16)  # its log and create times
                if self._name(stream, "attachment name", offset) in KEPT_NAMES:
                    attachment = Attachment.read(ReadDataStream(io.BytesIO(body)))
                    # kept up to one byte past the limit: enough for its reader to refuse it
                    self.attachments[attachment.name] = \
                        attachment.data[:MAX_ATTACHMENT_BYTES + 1]
        except InputFileError:
            raise
        except Exception as exc:  # struct.error, EndOfFile, UnicodeDecodeError, ...: damaged
            raise _problem(self.path, offset, f"a damaged {_opcode_name(opcode)} record "
                           f"({type(exc).__name__})") from None
        return None


    def _name(self, stream: ReadDataStream, what: str, offset: int) -> str:
        """The next string of a record, refused past MAX_NAME_BYTES before it is read."""
        length = stream.read4()
        if length > MAX_NAME_BYTES:
            raise _problem(self.path, offset, f"a {what} of {length} bytes (at most "
                           f"{MAX_NAME_BYTES})")
        return str(stream.read(length), "utf-8")


def _opcode_name(opcode: int) -> str:
    try:
        return Opcode(opcode).name.lower()
    except ValueError:
        return f"opcode {opcode}"


@dataclass
class Db3File:
    """One rosbag2 SQLite (.db3) file, read-only. Its `topics` and `messages` must be tables,
    without computed columns: a view or a virtual table (a recursive one never ends) or a
    generated column (computed on every read) would make work without bound that the file does
    not hold; no value read may be larger than MAX_MESSAGE_BYTES; every value read is checked
    for its type."""

    path: Path
    topics: dict[str, BagTopic] = field(default_factory=dict)
    cut_short: str | None = None

    def _connect(self) -> sqlite3.Connection:
        try:
            connection = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro&immutable=1",
                                         uri=True)
        except sqlite3.Error as exc:
            raise InputFileError(f"{self.path}: cannot open the SQLite bag ({exc})") from None
        connection.setlimit(sqlite3.SQLITE_LIMIT_LENGTH, MAX_MESSAGE_BYTES)
        return connection

    def _refuse(self, what: str) -> InputFileError:
        return InputFileError(f"{self.path}: {what}; not a rosbag2 SQLite file lanewarden reads")

    def _check_tables(self, connection: sqlite3.Connection) -> None:
        for table in ("topics", "messages"):
            problem = computed_table(connection, table)
            if problem is not None:
                raise self._refuse(problem)

    def _topics(self, connection: sqlite3.Connection) -> dict[object, BagTopic]:
        rows = connection.execute("SELECT id, name, type, serialization_format FROM topics "
                                  "LIMIT ?", (MAX_TOPICS + 1,)).fetchall()
        if len(rows) > MAX_TOPICS:
            raise self._refuse(f"more than {MAX_TOPICS} topics")
        by_id = {}
        for topic_id, *texts in rows:
            if not all(isinstance(t, str) and len(t.encode()) <= MAX_NAME_BYTES for t in texts):
                raise self._refuse(f"topic {shown_value(topic_id)}: name, type and "
                                   f"serialization_format = {shown_value(texts)}: expected texts "
                                   f"of at most {MAX_NAME_BYTES} bytes")
            name, kind, encoding = texts
            by_id[topic_id] = self.topics.setdefault(name, BagTopic(name, kind, encoding))
        return by_id

    def messages(self, keep: TopicFilter = None) -> Iterator[BagMessage]:
        connection = self._connect()
        try:
            self._check_tables(connection)
            for topic_id, topic in self._topics(connection).items():
                if keep is not None and not keep(topic):
                    continue
                cursor = connection.execute(
                    "SELECT timestamp, length(data), CASE WHEN length(data) <= ? THEN data END "
                    "FROM messages WHERE topic_id = ? ORDER BY timestamp, id",
                    (MAX_MESSAGE_BYTES, topic_id))
                for number, (stamp, length, data) in enumerate(cursor):
                    where = f"{self.path}: {message_name(topic.name, number)}"
                    if data is None and isinstance(length, int):
                        raise InputFileError(
                            f"{where} is {length} bytes (more than {MAX_MESSAGE_BYTES}); not a "
                            "recording lanewarden can read")
                    if not isinstance(data, bytes):
                        raise InputFileError(f"{where}: data is {type(data).__name__}, "
                                             "expected a BLOB")
                    if isinstance(stamp, bool) or not isinstance(stamp, int):
                        raise InputFileError(f"{where}: timestamp = {shown_value(stamp)}: "
                                             "expected an integer (nanoseconds)")
                    yield BagMessage(topic, number, 0, stamp, data)
        except sqlite3.Error as exc:
            raise InputFileError(f"{self.path}: not a readable rosbag2 SQLite file "
                                 f"({shorten(str(exc))})") from None
        finally:
            connection.close()


BagFile = McapFile | Db3File


@dataclass
class Bag:
    """A recording of one or more files, read in their order (a rosbag2 folder's files in
    metadata.yaml's order)."""

    path: Path
    files: list[BagFile]

    @property
    def topics(self) -> dict[str, BagTopic]:
        merged: dict[str, BagTopic] = {}
        for bag_file in self.files:
            merged.update(bag_file.topics)
        return merged

    def messages(self, keep: TopicFilter = None) -> Iterator[BagMessage]:
        numbers: dict[str, int] = {}
        for bag_file in self.files:
            for message in bag_file.messages(keep):
                number = numbers.get(message.topic.name, 0)
                numbers[message.topic.name] = number + 1
                yield BagMessage(message.topic, number, message.sequence, message.log_time_ns,
                                 message.data)


def _folder_files(folder: Path) -> list[BagFile]:
    info = read_yaml_document(folder / "metadata.yaml", "rosbag2 metadata", InputFileError)
    bag = info.get("rosbag2_bagfile_information") if isinstance(info, dict) else None
    if not isinstance(bag, dict):
        raise InputFileError(f"{folder / 'metadata.yaml'}: no 'rosbag2_bagfile_information' "
                             "mapping; not a rosbag2 folder")
    if bag.get("compression_mode") not in (None, "", "NONE"):
        raise InputFileError(
            f"{folder / 'metadata.yaml'}: compression_mode = {bag.get('compression_mode')!r}: "
            "compressed bags are not read; decompress it first (ros2 bag convert)")
    names = bag.get("relative_file_paths")
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names) or not names:
        raise InputFileError(f"{folder / 'metadata.yaml'}: relative_file_paths: expected a "
                             "list of the bag's files")
    files: list[BagFile] = []
    seen: dict[tuple[int, int], str] = {}
    for name in names:
        path = folder / Path(name).name  # the bag's own folder only
        if not path.is_file():
            raise InputFileError(f"{folder / 'metadata.yaml'}: lists {name!r}, which is not in "
                                 f"{folder}")
        # each file once: a list naming one file again and again (or links to it) would read
        # it again and again
        facts = path.stat()
        key = (facts.st_dev, facts.st_ino)
        if key in seen:
            again = "twice" if seen[key] == name else f"and {seen[key]!r}, the same file"
            raise InputFileError(f"{folder / 'metadata.yaml'}: lists {name!r} {again}; expected "
                                 "each of the bag's files once")
        seen[key] = name
        files.append(_bag_file(path))
    return files


def _bag_file(path: Path) -> BagFile:
    if path.suffix == ".mcap":
        return McapFile(path)
    if path.suffix == ".db3":
        return Db3File(path)
    raise InputFileError(f"{path}: not a .mcap or .db3 bag file")


def is_bag(path: Path) -> bool:
    """A rosbag2 folder (metadata.yaml), an .mcap or a .db3 file."""
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.is_file() and path.suffix in (".mcap", ".db3")


def open_bag(path: Path) -> Bag:
    """The recording at `path` (see `is_bag`); InputFileError when it is none."""
    if path.is_dir():
        return Bag(path, _folder_files(path))
    return Bag(path, [_bag_file(path)])


_DECODERS = DecoderFactory()
_SCHEMAS = {name: Schema(id=i, name=name, encoding="ros2msg", data=text.encode())
            for i, (name, text) in enumerate(DEFINITIONS.items(), start=1)}


def decode(message: BagMessage, where: str) -> Any:
    """The message decoded as its type (one of DEFINITIONS); InputFileError naming `where`,
    the topic and the message number when it does not decode."""
    kind = message.topic.type
    if kind not in _SCHEMAS or message.topic.encoding != "cdr":
        raise InputFileError(f"{where}: {message.topic.name} is {kind or 'untyped'} "
                             f"({message.topic.encoding}), not a CDR message lanewarden reads")
    decoder = _DECODERS.decoder_for("cdr", _SCHEMAS[kind])
    assert decoder is not None
    try:
        return decoder(message.data)
    except Exception as exc:  # a hostile payload can fail anywhere in a generic decoder
        named = message_name(message.topic.name, message.number)
        raise InputFileError(f"{where}: {named} is not a valid CDR {kind} "
                             f"({type(exc).__name__})") from None
