"""MCAP files written byte by byte, for tests of what the reader does with files no MCAP writer
would write (lanewarden.ros_bag): records, chunks compressed with zstd, a file of them."""

from __future__ import annotations

import struct
from pathlib import Path

import zstandard

MAGIC = b"\x89MCAP0\r\n"


def text(value: bytes) -> bytes:
    return struct.pack("<I", len(value)) + value


def record(opcode: int, body: bytes) -> bytes:
    return struct.pack("<BQ", opcode, len(body)) + body


def zstd_chunk(records: bytes) -> bytes:
    """A chunk record of these records, zstd-compressed, without a CRC (as MCAP allows)."""
    data = zstandard.ZstdCompressor().compress(records)
    return record(0x06, struct.pack("<QQQI", 0, 0, len(records), 0) + text(b"zstd")
                  + struct.pack("<Q", len(data)) + data)


def mcap_file(path: Path, *records: bytes) -> Path:
    """Magic, a header and these records: no footer (a file cut short is read as far as it
    goes, so what is refused is refused for what it holds)."""
    path.write_bytes(MAGIC + record(0x01, text(b"ros2") + text(b"test")) + b"".join(records))
    return path


def schema(schema_id: int, name: bytes) -> bytes:
    return record(0x03, struct.pack("<H", schema_id) + text(name) + text(b"ros2msg")
                  + text(b""))


def channel(channel_id: int, topic: bytes, encoding: bytes = b"cdr",
            metadata: bytes = b"") -> bytes:
    return record(0x04, struct.pack("<HH", channel_id, 1) + text(topic) + text(encoding)
                  + text(metadata))


def metadata(name: bytes, entries: bytes) -> bytes:
    return record(0x0C, text(name) + text(entries))
