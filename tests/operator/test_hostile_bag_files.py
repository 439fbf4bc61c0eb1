"""Crafted MCAP files, SQLite bags and rosbag2 folders that cost time or memory out of proportion
to their size, or that the reader did not expect: each is one line naming the file and what is
wrong, exit code 2, before the work is done (asserted by outcome, never by timing).

The MCAP files are written byte by byte (tests/operator/mcap_bytes.py: the `mcap` library's
writer would not write them), the bags with SQLite itself."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from lanewarden import ros_bag
from lanewarden.cli import main
from lanewarden.errors import InputFileError
from lanewarden.ros_bag import McapFile
from lanewarden.run_mcap import IMAGE, IMAGE_DEF
from tests.operator.mcap_bytes import (
    channel,
    mcap_file,
    metadata,
    record,
    schema,
    text,
    zstd_chunk,
)


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


# ---- what a file can make the reader keep -----------------------------------------------------
@pytest.mark.parametrize("records, what", [
    (schema(1, b"x" * 1001), "a schema name of 1001 bytes"),
    (channel(1, b"/" + b"x" * 1000), "a topic name of 1001 bytes"),
    (channel(1, b"/camera", encoding=b"c" * 5000), "a message encoding of 5000 bytes"),
], ids=["schema", "topic", "encoding"])
def test_a_name_longer_than_any_is_refused_before_it_is_read(
        tmp_path: Path, records: bytes, what: str) -> None:
    """Every schema and channel record is noted, and a chunk can repeat them: 12 chunks of 4 kB
    (zstd), each a schema whose name is 120 MB, took 2 GB."""
    bomb = mcap_file(tmp_path / "names.mcap", zstd_chunk(records))
    with pytest.raises(InputFileError) as refused:
        read_all(bomb)
    assert str(refused.value) == (f"{bomb}: {what} (at most 1000) at byte 33; not a readable "
                                  "MCAP recording")


def test_more_topics_than_any_bag_has(tmp_path: Path) -> None:
    bomb = mcap_file(tmp_path / "topics.mcap", zstd_chunk(b"".join(
        channel(i % 60000 + 1, b"/t%d" % i) for i in range(10_001))))
    with pytest.raises(InputFileError) as refused:
        read_all(bomb)
    assert str(refused.value) == (f"{bomb}: more than 10000 topics at byte 33; not a readable "
                                  "MCAP recording")


def test_only_a_recordings_own_metadata_is_kept_and_only_outside_chunks(tmp_path: Path) -> None:
    """Metadata and attachments belong outside chunks (MCAP): one inside a chunk is skipped, so a
    few kB of zstd can no longer make a dict of millions of entries (1.2 MB of them took 3.6 GB
    and 90 s); outside, only the names a replay reads are kept, each within 1 MB."""
    entries = b"".join(text(b"%06d" % i) + text(b"") for i in range(1000))
    path = mcap_file(tmp_path / "meta.mcap", zstd_chunk(metadata(b"lanewarden", entries)),
                     metadata(b"rosbag2", entries), metadata(b"lanewarden.summary", entries),
                     record(0x02, bytes(20)))
    mcap = McapFile(path)
    for _ in mcap.messages():
        pass
    assert list(mcap.metadata) == ["lanewarden.summary"]
    assert len(mcap.metadata["lanewarden.summary"]) == 1000
    big = b"".join(text(b"%07d" % i) + text(b"") for i in range(70_000))  # 1.05 MB
    mcap_file(path, metadata(b"rosbag2", big))
    read_all(path)  # not kept: not read
    mcap_file(path, metadata(b"lanewarden", big))
    with pytest.raises(InputFileError) as refused:
        read_all(path)
    assert str(refused.value) == (f"{path}: a metadata record of {len(big) + 18} bytes (more "
                                  "than 1000000) at byte 33; not a readable MCAP recording")


# ---- SQLite bags: what the file is made of, and each value's type ------------------------------
def db3(path: Path, *statements: str) -> Path:
    """A rosbag2 SQLite file of one CompressedImage topic and one message (not a valid image:
    what is checked comes before), changed by `statements`."""
    connection = sqlite3.connect(path)
    connection.executescript("""
        CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT, type TEXT,
                            serialization_format TEXT, offered_qos_profiles TEXT);
        CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER,
                              data BLOB);
        INSERT INTO topics VALUES (1, '/camera/image_raw/compressed',
                                   'sensor_msgs/msg/CompressedImage', 'cdr', '');
        INSERT INTO messages VALUES (1, 1, 1790000000000000000, x'00010000');""")
    for statement in statements:
        connection.execute(statement)
    connection.commit()
    connection.close()
    return path


@pytest.mark.parametrize("statement, problem", [
    ("UPDATE messages SET timestamp = 'abc'", "/camera/image_raw/compressed message 0 (counted "
     "from 0): timestamp = 'abc': expected an integer (nanoseconds)"),
    ("UPDATE messages SET timestamp = NULL", "/camera/image_raw/compressed message 0 (counted "
     "from 0): timestamp = None: expected an integer (nanoseconds)"),
    ("UPDATE messages SET timestamp = 1e999", "/camera/image_raw/compressed message 0 (counted "
     "from 0): timestamp = inf: expected an integer (nanoseconds)"),
    ("UPDATE messages SET data = 'text'", "/camera/image_raw/compressed message 0 (counted from "
     "0): data is str, expected a BLOB"),
    ("UPDATE topics SET name = x'ff00'", "topic 1: name, type and serialization_format = "
     "[b'\\xff\\x00', 'sensor_msgs/msg/CompressedImage', 'cdr']: expected texts of at most "
     "1000 bytes; not a rosbag2 SQLite file lanewarden reads"),
], ids=["timestamp-text", "timestamp-null", "timestamp-inf", "data-text", "name-blob"])
def test_a_value_of_the_wrong_type_in_a_sqlite_bag(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str],
                                                   statement: str, problem: str) -> None:
    """Each but the last was a traceback (ValueError, TypeError, OverflowError); the topic's
    name had been read as the text "b'\\xff\\x00'"."""
    bag = db3(tmp_path / "bag.db3", statement)
    code, err = replay(bag, tmp_path, capsys)
    assert code == 2, err
    assert err == f"lanewarden: error: {bag}: {problem}\n"


@pytest.mark.parametrize("statements, problem", [
    (["ALTER TABLE messages RENAME TO stored",
      "CREATE VIEW messages AS SELECT * FROM stored"], "'messages' is a view, not a table"),
    (["ALTER TABLE topics RENAME TO stored",
      "CREATE VIRTUAL TABLE topics USING fts5(id, name, type, serialization_format)",
      "INSERT INTO topics SELECT id, name, type, serialization_format FROM stored"],
     "'topics' is a virtual table, not a table"),
    (["ALTER TABLE messages RENAME TO stored",
      "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, "
      "raw BLOB, data BLOB GENERATED ALWAYS AS (zeroblob(1000)) VIRTUAL)",
      "INSERT INTO messages(id, topic_id, timestamp, raw) SELECT * FROM stored"],
     "'messages' has computed columns (data)"),
], ids=["view", "virtual-table", "generated-column"])
def test_a_sqlite_bag_whose_tables_are_computed_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], statements: list[str],
        problem: str) -> None:
    """Read as they were, a recursive view never ended (or took 5 GB before a MemoryError) and a
    generated column of zeroblob(10**9) made a gigabyte per row: the work a view or a computed
    column makes is not bounded by the file. These are small and harmless, and refused all the
    same."""
    bag = db3(tmp_path / "bag.db3", *statements)
    code, err = replay(bag, tmp_path, capsys)
    assert code == 2, err
    assert err == (f"lanewarden: error: {bag}: {problem}; not a rosbag2 SQLite file lanewarden "
                   "reads\n")


# ---- rosbag2 folders ---------------------------------------------------------------------------
@pytest.mark.parametrize("listed, problem", [
    (["a.mcap", "a.mcap"], "lists 'a.mcap' twice"),
    (["a.mcap", "b.mcap"], "lists 'b.mcap' and 'a.mcap', the same file"),
], ids=["a-name-twice", "a-link-to-one-listed"])
def test_a_rosbag2_folder_listing_one_file_twice(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str],
                                                 listed: list[str], problem: str) -> None:
    """A metadata.yaml listing one file (or links to it) again and again read it again and
    again, all before the first check of its images' times: a 16 MB recording listed 100 times
    read 1.6 GB (3 s); a list of 150 kB can name it 10 000 times."""
    bag = tmp_path / "bag"
    bag.mkdir()
    mcap_file(bag / "a.mcap", record(0x02, bytes(20)))
    (bag / "b.mcap").symlink_to("a.mcap")
    (bag / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  relative_file_paths: [" + ", ".join(listed) + "]\n")
    code, err = replay(bag, tmp_path, capsys)
    assert code == 2, err
    assert err == (f"lanewarden: error: {bag / 'metadata.yaml'}: {problem}; expected each of the "
                   "bag's files once\n")


# ---- image messages ----------------------------------------------------------------------------
def test_a_yuv422_image_of_an_odd_width(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    """Two pixels of YUV 4:2:2 share their U and V: OpenCV's conversion of an odd width was a
    traceback (cv2.error, an assertion) when the frame was decoded."""
    from mcap_ros2._dynamic import serialize_dynamic

    encode = serialize_dynamic(IMAGE, IMAGE_DEF)[IMAGE]
    data = encode({"header": {"stamp": {"sec": 1_790_000_000, "nanosec": 0}, "frame_id": "c"},
                   "height": 2, "width": 161, "encoding": "yuv422_yuy2", "is_bigendian": 0,
                   "step": 322, "data": bytes(644)})
    bag = db3(tmp_path / "bag.db3", f"UPDATE messages SET data = x'{data.hex()}'",
              f"UPDATE topics SET type = '{IMAGE}', name = '/camera/image_raw'")
    code, err = replay(bag, tmp_path, capsys)
    assert code == 2, err
    assert err == (f"lanewarden: error: {bag}: /camera/image_raw message 0 (counted from 0): a "
                   "161x2 yuv422_yuy2 image: expected an even width (two pixels share one U and "
                   "V)\n")
