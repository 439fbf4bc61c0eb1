"""Crafted MCAP files, SQLite bags and rosbag2 folders that cost time or memory out of proportion
to their size, or that the reader did not expect: each is one line naming the file and what is
wrong, exit code 2, before the work is done (asserted by outcome, never by timing).

The MCAP files are written byte by byte here (the `mcap` library's writer would not write them),
the bags with SQLite itself."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
import zstandard

from lanewarden import ros_bag
from lanewarden.cli import main
from lanewarden.errors import InputFileError
from lanewarden.ros_bag import McapFile

MAGIC = b"\x89MCAP0\r\n"


def _text(value: bytes) -> bytes:
    return struct.pack("<I", len(value)) + value


def record(opcode: int, body: bytes) -> bytes:
    return struct.pack("<BQ", opcode, len(body)) + body


def zstd_chunk(records: bytes) -> bytes:
    """A chunk record of these records, zstd-compressed, without a CRC (as MCAP allows)."""
    data = zstandard.ZstdCompressor().compress(records)
    return record(0x06, struct.pack("<QQQI", 0, 0, len(records), 0) + _text(b"zstd")
                  + struct.pack("<Q", len(data)) + data)


def mcap_file(path: Path, *records: bytes) -> Path:
    """Magic, a header and these records: no footer (a file cut short is read as far as it
    goes, so what is refused is refused for what it holds)."""
    path.write_bytes(MAGIC + record(0x01, _text(b"ros2") + _text(b"test")) + b"".join(records))
    return path


def replay(source: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["replay", str(source), "--no-video", "--out", str(tmp_path / "out")])
    return code, capsys.readouterr().err


def read_all(path: Path) -> None:
    for _ in McapFile(path).messages():
        pass


# ---- decompression bombs: work out of proportion to the file's size --------------------------
def test_a_chunk_of_more_records_than_the_file_has_bytes(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    """200 000 empty records (of an opcode nobody defined) compress to a few hundred bytes;
    128 MiB of them, 15 million, took 30 s to walk, per chunk of 11 kB."""
    bomb = mcap_file(tmp_path / "bomb.mcap", zstd_chunk(record(0x80, b"") * 200_000))
    size = bomb.stat().st_size
    assert size < 2000
    code, err = replay(bomb, tmp_path, capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert (f"{bomb}: chunks holding more than {size} records in all (one per byte of the "
            "file: a decompression bomb?) at byte ") in err


def test_chunks_that_decompress_to_much_more_than_the_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Chunks of zeros (one record each) that decompress within MAX_CHUNK_BYTES one by one but,
    together, to more than MAX_EXPANSION times the file's size: each chunk had cost its
    decompression and a copy, 128 MiB per 4 kB of file. Here with chunks of 1 MiB at most, so
    the bomb is small."""
    monkeypatch.setattr(ros_bag, "MAX_CHUNK_BYTES", 1 << 20)
    zeros = record(0x80, bytes((1 << 20) - 9))
    bomb = mcap_file(tmp_path / "bomb.mcap", *[zstd_chunk(zeros)] * 3)
    size = bomb.stat().st_size
    budget = max(1 << 20, 1000 * size)
    assert 3 << 20 > budget
    with pytest.raises(InputFileError) as refused:
        read_all(bomb)
    assert str(refused.value).startswith(
        f"{bomb}: chunks decompressing to more than {budget} bytes in all (1000 times the "
        f"file's {size} bytes, or {1 << 20}: a decompression bomb?) at byte ")
