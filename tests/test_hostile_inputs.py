"""Hostile files: each is refused with one line and exit 2 before it costs time or memory.

Asserted by outcome, not by timing: every case runs through the real CLI (`main`) in one child
process whose address space is capped (RLIMIT_AS) a few hundred MB above what the interpreter and
Lanewarden's imports take, so a case that expanded a YAML bomb, recursed 50k levels, read a 10 MB
file, sampled a 1e9 m lane, painted a huge floor or decoded a 20000x20000 image would die with a
MemoryError (a traceback) instead of the expected one line. The cases share one child because the
imports take seconds; each case's stderr and exit code are captured separately.
"""

from __future__ import annotations

import gzip
import json
import os
import re
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from lanewarden.perception.calibration import CameraCalibration, save_calibration
from lanewarden.scenarios.campaign.cases import case_yaml, draw_case, load_campaign_spec
from tests.conftest import PROJECT_ROOT
from tests.operator.mcap_bytes import channel, mcap_file, metadata, record, schema, zstd_chunk

#: Address space the child may use above its baseline after the imports, bytes.
HEADROOM_BYTES = 400 * 1024 * 1024

CHILD = r"""
import contextlib, io, json, resource, sys
from lanewarden.cli import main

def vm_bytes():
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize")

limit = vm_bytes() + int(sys.argv[1])
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
results = {}
for name, argv in json.loads(sys.argv[2]).items():
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except BaseException as exc:  # a MemoryError, RecursionError, ... is a failed case
            code = f"{type(exc).__name__}: {str(exc)[:200]}"
    results[name] = [code, err.getvalue()]
print(json.dumps(results))
"""


def yaml_bomb(indent: str = "") -> str:
    """A "billion laughs": 9 levels of 9 aliases, 9^9 strings once expanded, ~450 bytes."""
    lines = [f"{indent}l0: &l0 [" + ", ".join(['"lol"'] * 9) + "]"]
    for level in range(1, 9):
        lines.append(f"{indent}l{level}: &l{level} [" + ", ".join([f"*l{level - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


SCENARIO_HEAD = "name: hostile\nlane:\n  segments:\n"


def many_entries(count: int) -> bytes:
    """An MCAP string map of `count` distinct 7-digit keys with empty values (15 bytes each)."""
    entries = np.zeros((count, 15), np.uint8)
    entries[:, 0] = 7
    numbers = np.arange(count)
    for digit in range(7):
        entries[:, 4 + digit] = 48 + numbers // 10 ** (6 - digit) % 10
    return entries.tobytes()


def big_png(width: int, height: int) -> bytes:
    """A valid 1-bit grayscale PNG, all black: ~220 kB on disk for 20000x20000, 1.2 GB decoded."""

    def chunk(tag: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(tag + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", crc)

    compressor = zlib.compressobj(1)
    rows = bytes(width // 8 + 1) * 1000
    idat = b"".join([compressor.compress(rows) for _ in range(height // 1000)])
    idat += compressor.flush()
    header = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", idat)
            + chunk(b"IEND", b""))


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[object, str]]:
    folder = tmp_path_factory.mktemp("hostile")

    def write(name: str, text: str) -> str:
        (folder / name).write_text(text, encoding="utf-8")
        return str(folder / name)

    def gzipped(name: str, text: str) -> str:
        (folder / name).write_bytes(gzip.compress(text.encode()))
        return str(folder / name)

    square_loop = "".join("    - {straight_m: 20}\n    - {arc_radius_m: 1, turn_deg: 90}\n"
                          for _ in range(4))
    (folder / "huge.png").write_bytes(big_png(20000, 20000))
    save_calibration(
        CameraCalibration(np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]), np.zeros(5),
                          (640, 480)),
        folder / "camera.yaml",
    )
    sim = ["--no-video", "--quiet", "--out", str(folder / "out")]
    calibration = (folder / "camera.yaml").read_text(encoding="utf-8")
    write("h20k.yaml", re.sub(r"image_height: \d+", "image_height: 20000",
                              re.sub(r"image_width: \d+", "image_width: 20000", calibration)))
    (folder / "small.png").write_bytes(big_png(640, 480))
    spec, spec_path = load_campaign_spec("default")
    case = case_yaml(draw_case(spec, spec_path, 0, 0, {}, 0.15))
    write("negative-seed.yaml", re.sub(r"(?m)^seed: \d+$", "seed: -5", case))
    write("evil-controller.yaml", re.sub(r"(?m)^controller: \w+$", "controller: evil", case))
    (folder / "views").mkdir()
    (folder / "dup").mkdir()
    (folder / "dup" / "small.png").write_bytes(big_png(640, 480))
    (folder / "views" / "huge.png").write_bytes(big_png(20000, 20000))
    # a 1x1 PNG header in front of 3 GB (sparse: no disk used): only reading it costs
    with open(folder / "sparse.png", "wb") as sparse:
        sparse.write(big_png(8, 1))
        sparse.truncate(3 << 30)
    os.mkfifo(folder / "fifo.yaml")
    os.mkfifo(folder / "fifo.png")
    os.mkfifo(folder / "fifo-calibration.yaml")
    os.mkfifo(folder / "fifo-labels.csv")
    (folder / "fifo-survey" / "lane").mkdir(parents=True)
    (folder / "fifo-survey" / "no-lane").mkdir()
    (folder / "fifo-survey" / "lane" / "a.png").write_bytes(big_png(640, 480))
    os.mkfifo(folder / "fifo-survey" / "no-lane" / "b.png")
    # MCAP chunks of a few kB (zstd) that the reader had kept or parsed whole: 480 MB of schema
    # names, a dict of 6 million channel metadata entries, one of a metadata record's
    mcap_file(folder / "names.mcap", *[zstd_chunk(schema(i, b"x" * 120_000_000))
                                       for i in range(1, 5)])
    entries = many_entries(6_000_000)
    mcap_file(folder / "channel-map.mcap", zstd_chunk(channel(1, b"/t", metadata=entries)),
              record(0x02, bytes(20)))
    mcap_file(folder / "metadata-map.mcap", zstd_chunk(metadata(b"lanewarden", entries)),
              record(0x02, bytes(20)))
    replay = ["--no-video", "--out", str(folder / "replay-out")]
    cases = {
        "config bomb": ["config", "show", "--config", write("bomb.yaml", yaml_bomb())],
        "scenario bomb": ["sim", "--scenario", write(
            "bomb-scenario.yaml",
            SCENARIO_HEAD + "    - {straight_m: 1}\nconfig:\n" + yaml_bomb("  ")), *sim],
        "config nested 50k deep": ["config", "show", "--config", write(
            "deep.yaml", "perception: " + "[" * 50_000 + "]" * 50_000 + "\n")],
        "scenario nested 50k deep": ["sim", "--scenario", write(
            "deep-scenario.yaml", SCENARIO_HEAD + "    - " + "{a: " * 50_000 + "1"
            + "}" * 50_000 + "\n"), *sim],
        "10 MB config": ["config", "show", "--config", write(
            "big.yaml", "# padding\n" * 1_000_000)],
        "1e9 m straight": ["sim", "--scenario", write(
            "long.yaml", SCENARIO_HEAD + "    - {straight_m: 1.0e+9}\n"), *sim],
        "1e6 segments": ["sim", "--scenario", write(
            "segments.yaml", SCENARIO_HEAD + "    - {straight_m: 0.01}\n" * 1_000_000), *sim],
        "1e4 segments": ["sim", "--scenario", write(
            "segments-1e4.yaml", SCENARIO_HEAD + "    - {straight_m: 0.001}\n" * 10_000), *sim],
        "floor too large": ["sim", "--scenario", write(
            "square.yaml", SCENARIO_HEAD + square_loop), *sim],
        "texture too fine": ["sim", "--scenario", "lecture", "--config", write(
            "fine.yaml", "simulation:\n  texture_mm_per_px: 1.0\n"), *sim],
        "20000x20000 PNG detect": ["detect", str(folder / "huge.png")],
        "20000x20000 PNG undistort": ["undistort", str(folder / "huge.png"), "--calibration",
                                      str(folder / "camera.yaml"), "--out", str(folder / "u")],
        "config with a repeated key": ["config", "show", "--config", write(
            "twice.yaml", "supervisor:\n  lane_lost_halt_s: 0.2\n  lane_lost_halt_s: 0.9\n")],
        "config with a 5000-digit number": ["config", "show", "--config", write(
            "digits.yaml", "supervisor: {lane_lost_halt_s: " + "9" * 5000 + "}\n")],
        "config that is a FIFO": ["config", "show", "--config", str(folder / "fifo.yaml")],
        "image that is a FIFO": ["detect", str(folder / "fifo.png")],
        "calibration that is a FIFO": ["detect", str(folder / "small.png"), "--calibration",
                                       str(folder / "fifo-calibration.yaml")],
        "calibration nested 40k deep": ["detect", str(folder / "small.png"), "--calibration",
                                        write("deep-calibration.yaml", "a: " + "[" * 40_000)],
        "calibration with closers before 40k openers": [
            "detect", str(folder / "small.png"), "--calibration",
            write("closers-calibration.yaml", "# " + "]" * 40_000 + "\na: " + "[" * 40_000)],
        "gzip-compressed calibration": ["detect", str(folder / "small.png"), "--calibration",
                                        gzipped("packed.yaml.gz", "a: " + "[" * 40_000)],
        "calibration of 1400 block levels": [
            "detect", str(folder / "small.png"), "--calibration",
            write("block-calibration.yaml", "%YAML:1.0\n" + "".join(
                " " * k + "a:\n" for k in range(1400)) + " " * 1400 + "1\n")],
        "labels that are a FIFO": ["survey", str(folder / "dup"), "--labels",
                                   str(folder / "fifo-labels.csv")],
        "photo that is a FIFO": ["survey", str(folder / "fifo-survey"), "--out",
                                 str(folder / "fifo-survey-out")],
        "3 GB behind a 1x1 PNG header": ["detect", str(folder / "sparse.png")],
        "20000x20000 PNG calibrate": ["calibrate", "--images", str(folder / "views"),
                                      "--pattern", "9x6", "--square", "0.025", "--out",
                                      str(folder / "c.yaml")],
        "20000x20000 PNG calibrate ground": [
            "calibrate", "ground", "--image", str(folder / "huge.png"), "--calibration",
            str(folder / "camera.yaml"), "--pattern", "9x6", "--square", "0.025",
            "--board-center-m", "0.5,0", "--out", str(folder / "g.yaml")],
        "calibration claiming 20000x20000": ["detect", str(folder / "small.png"),
                                             "--calibration", str(folder / "h20k.yaml")],
        "camera index beyond any": ["run", "--camera", "99999999999999999999"],
        "check picture not a picture": [
            "calibrate", "ground", "--height-m", "0.3", "--pitch-deg", "40", "--calibration",
            str(folder / "camera.yaml"), "--check-image", str(folder / "x.txt"), "--out",
            str(folder / "g.yaml")],
        "board centre 1e308 m away": [
            "calibrate", "ground", "--image", str(folder / "small.png"), "--calibration",
            str(folder / "camera.yaml"), "--pattern", "9x6", "--square", "0.025",
            "--board-center-m", "1e308,0", "--out", str(folder / "g.yaml")],
        "case with a negative seed": ["sim", "--case", str(folder / "negative-seed.yaml"), *sim],
        "case with an unknown controller": ["sim", "--case",
                                            str(folder / "evil-controller.yaml"), *sim],
        "two detect overlays of one name": ["detect", str(folder / "small.png"),
                                            str(folder / "dup" / "small.png"), "--out",
                                            str(folder / "d")],
        "two undistorted pictures of one name": [
            "undistort", str(folder / "small.png"), str(folder / "dup" / "small.png"),
            "--calibration", str(folder / "camera.yaml"), "--out", str(folder / "u2")],
        "camera clip over the run's report": [
            "sim", "--scenario", "straight", "--out", str(folder / "clash"), "--camera-out",
            str(folder / "clash" / "report.html"), "--no-video", "--quiet"],
        "lane_lost_halt_s inf": ["sim", "--scenario", "lane-ends", "--check", "--config", write(
            "inf.yaml", "supervisor:\n  lane_lost_halt_s: .inf\n"), *sim],
        "MCAP chunks of 120 MB schema names": ["replay", str(folder / "names.mcap"), *replay],
        "MCAP channel of 6 million metadata entries": [
            "replay", str(folder / "channel-map.mcap"), *replay],
        "MCAP metadata of 6 million entries in a chunk": [
            "replay", str(folder / "metadata-map.mcap"), *replay],
    }
    child = subprocess.run(
        [sys.executable, "-c", CHILD, str(HEADROOM_BYTES), json.dumps(cases)],
        capture_output=True, text=True, cwd=PROJECT_ROOT, timeout=300, check=False,
    )
    assert child.returncode == 0, child.stderr[-2000:]
    results = json.loads(child.stdout.strip().splitlines()[-1])
    return {name: (code, err) for name, (code, err) in results.items()}


EXPECTED: dict[str, str | tuple[str, ...]] = {
    "config bomb": "bomb.yaml: expands to more than 100000 values (aliases count as what they "
                   "point to), refusing to read it",
    "scenario bomb": "bomb-scenario.yaml: expands to more than 100000 values",
    # LibYAML's scanner (when PyYAML has it) may stop flow nesting at its own limit of 1000 first
    "config nested 50k deep": ("deep.yaml: nested deeper than 32 levels, refusing to read it",
                               "deep.yaml: not valid YAML at line 1, column 1012: exceeded "
                               "maximum nesting depth"),
    "scenario nested 50k deep": "deep-scenario.yaml: nested deeper than 32 levels",
    "10 MB config": "big.yaml: config file is larger than 1000 kB, refusing to read it",
    "1e9 m straight": "long.yaml: lane.segments.0.straight_m = 1000000000.0: expected a finite "
                      "number with 0 < value <= 100",
    "1e6 segments": "segments.yaml: scenario file is larger than 1000 kB, refusing to read it",
    "1e4 segments": "segments-1e4.yaml: lane.segments = a list of 10000 items: list should have "
                    "at most 200 items after validation, not 10000",
    "floor too large": "square.yaml: the lane and its 2.5 m margins cover",
    "texture too fine": "lecture: the floor texture would be",
    "20000x20000 PNG detect": "huge.png: image has 400000000 pixels, more than "
                              "perception.max_image_pixels (10000000)",
    "20000x20000 PNG undistort": "huge.png: image has 400000000 pixels, more than "
                                 "perception.max_image_pixels (10000000)",
    "config with a repeated key": "twice.yaml: not valid YAML at line 3, column 3: key "
                                  "'lane_lost_halt_s' appears twice in one mapping",
    "config with a 5000-digit number": "digits.yaml: a value YAML cannot read (Exceeds the "
                                       "limit",
    "config that is a FIFO": "fifo.yaml: not a regular file (a FIFO, socket or device), "
                             "expected a config YAML file",
    "image that is a FIFO": "fifo.png: not a regular file (a FIFO, socket or device)",
    "calibration that is a FIFO": "fifo-calibration.yaml: not a regular file (a FIFO, socket or "
                                  "device), expected a calibration YAML file",
    # OpenCV's parser recursed once per level: a segmentation fault, exit 139, not a word
    "calibration nested 40k deep": "deep-calibration.yaml: 40000 characters that open a nesting "
                                   "level ([, {, <, -), more than any calibration holds",
    # walking its nodes was a RecursionError traceback
    "calibration of 1400 block levels": "block-calibration.yaml: nested deeper than 32 levels",
    # each got past a scan of the nesting and crashed OpenCV's parser (a reviewer's bypasses;
    # OpenCV decompressed the .gz itself)
    "calibration with closers before 40k openers": "closers-calibration.yaml: 40000 characters "
                                                   "that open a nesting level",
    "gzip-compressed calibration": "packed.yaml.gz: not UTF-8 text",
    "labels that are a FIFO": "fifo-labels.csv': not a regular file (a FIFO, socket or device), "
                              "expected a labels file",
    # its header was read before it was looked at: the survey waited for a writer forever
    "photo that is a FIFO": "no-lane/b.png: not a regular file (a FIFO, socket or device)",
    "3 GB behind a 1x1 PNG header": "sparse.png: file is larger than 81048576 bytes, more than "
                                    "any image within perception.max_image_pixels (10000000)",
    # the view is refused from its header, not decoded (2.7 GB)
    "20000x20000 PNG calibrate": "views': none of the 1 matching files is a readable image",
    "20000x20000 PNG calibrate ground": "huge.png': image has 400000000 pixels, more than "
                                        "perception.max_image_pixels (10000000)",
    # refused before its 20000x20000 undistortion tables are built (5.6 GB)
    "calibration claiming 20000x20000": "h20k.yaml: image size 20000x20000 is larger than any "
                                        "camera image taken",
    # each of these four was a traceback (cv2.error, ValueError)
    "camera index beyond any": "--camera '99999999999999999999': expected a camera index from "
                               "0 to 9999",
    "check picture not a picture": "x.txt': expected a .png or .jpg file name",
    "board centre 1e308 m away": "expected a board on the floor in view, within 10 m",
    "case with a negative seed": "negative-seed.yaml: seed = -5: expected an integer with 0 <= "
                                 "value",
    # the second had silently overwritten the first (exit 0)
    "two detect overlays of one name": "dup/small.png would both write small_detect.png",
    "two undistorted pictures of one name": "dup/small.png would both write "
                                            "small_compare.png",
    # was exit 1, blaming the --controller flag
    "case with an unknown controller": "evil-controller.yaml: controller = 'evil': input should "
                                       "be 'supervised' or 'lecture'",
    # found before simulating (it had failed at the end, 'Is a directory', exit 1)
    "camera clip over the run's report": "report.html is one of the run's own outputs in --out",
    "lane_lost_halt_s inf": "inf.yaml: supervisor.lane_lost_halt_s = inf: expected a finite "
                            "number with 0 < value <= 1",
    # each was a MemoryError: what the reader kept or parsed of a chunk had no bound
    "MCAP chunks of 120 MB schema names": "names.mcap: a schema name of 120000000 bytes (at "
                                          "most 1000) at byte 33",
    "MCAP channel of 6 million metadata entries": "channel-map.mcap: no sensor_msgs/msg/Image "
                                                  "or CompressedImage messages (topics: /t)",
    "MCAP metadata of 6 million entries in a chunk": "metadata-map.mcap: no sensor_msgs/msg/"
                                                     "Image or CompressedImage messages",
}


@pytest.mark.parametrize("case", list(EXPECTED))
def test_hostile_input_is_one_line_exit_2_without_large_memory(
    outcomes: dict[str, tuple[object, str]], case: str
) -> None:
    code, err = outcomes[case]
    assert code == 2, (code, err[-500:])
    lines = err.strip().splitlines()
    assert len(lines) == 1, lines[:5]
    expected = EXPECTED[case]
    assert any(text in lines[0] for text in ((expected,) if isinstance(expected, str)
                                             else expected)), lines[0]
    assert len(lines[0]) < 400


def test_output_that_cannot_be_written_is_one_line(tmp_path: Path) -> None:
    """`lanewarden config show > /dev/full`: was an OSError traceback."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full on this system")
    with open("/dev/full", "w") as full:
        done = subprocess.run([sys.executable, "-m", "lanewarden", "config", "show"],
                              stdout=full, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                              check=False)
    assert done.returncode == 1
    assert done.stderr.splitlines() == [
        "lanewarden: error: cannot write the output (No space left on device)"]
