"""How long and how much memory does `lanewarden replay` spend on a damaged or forged recording
before it refuses it? (The issue's bound: one line, exit code 2, within 5 s and 500 MB each.)

Makes each case of tests/operator/test_replay_hostile.py (and a few that are allowed but as large
as the bounds allow: a span of almost 24 hours, a 24-hour bag) from a real recording, then runs
`python -m lanewarden replay CASE --no-video` for each as a process of its own and prints its
exit code, wall time, CPU time and peak memory (the process's own rusage), and the first line of
stderr; the first rows are references (the command's start-up alone; a whole recording). On a
shared machine the times are inflated; the lead re-measures on a quiet one. On demand only:
    python benchmarks/hostile_recordings.py
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mcap_ros2.writer import Writer as Ros2McapWriter  # noqa: E402

from lanewarden.config import LanewardenConfig  # noqa: E402
from lanewarden.run_mcap import COMPRESSED_IMAGE_DEF  # noqa: E402
from tests.operator.clips import lane_end_frames  # noqa: E402
from tests.operator.recordings import (  # noqa: E402
    as_format_1,
    change_step,
    forged_format_1,
    record_run,
    rewrite_mcap,
)

Edit = Callable[[dict[str, Any]], None]


def cases(run: Path, tmp: Path) -> dict[str, Path]:
    steps = json.loads((run / "summary.json").read_text())["steps"]
    made: dict[str, Path] = {}

    def shift(seconds: float) -> Edit:
        return lambda r: r["input"].update(t=r["input"]["t"] + seconds)

    def forge(name: str, number: int, edit: Edit) -> None:
        number = steps if number == -1 else number
        made[f"run.jsonl: {name}"] = forged_format_1(run, tmp / f"j-{len(made)}", number, edit)
        target = tmp / f"m-{len(made)}.mcap"
        rewrite_mcap(run / "run.mcap", target, change_step(number, edit))
        made[f"run.mcap: {name}"] = target

    forge("last step +1e6 s", -1, shift(1e6))
    forge("last step +23.9 h (allowed)", -1, shift(23.9 * 3600))
    forge("NaN time", 5, lambda r: r["input"].update(t=float("nan")))
    forge("backwards time", 5, shift(-1.0))
    forge("string battery", 5, lambda r: r["input"]["feedback"].update(battery_v="15.9"))
    forge("events: 5", 5, lambda r: r.update(events=5))
    forge("input: null", 5, lambda r: r.update(input=None))
    forge("odometry 1e12 m", 5, lambda r: r["input"]["feedback"].update(odometry=[1e12, 0, 0]))
    big = ("# padding\n" * 500_000).encode()
    old = as_format_1(run, tmp / "big-config")
    (old / "config.yaml").write_bytes(big)
    made["run folder: 5 MB config.yaml"] = old
    target = tmp / "big-config.mcap"
    rewrite_mcap(run / "run.mcap", target, lambda topic, n, m: m, attachments={"config.yaml": big})
    made["run.mcap: 5 MB config.yaml attachment"] = target
    data = (run / "run.mcap").read_bytes()
    _, length = struct.unpack_from("<BQ", data, 8)
    prefix = data[: 8 + 9 + length]
    huge = tmp / "huge-record.mcap"
    huge.write_bytes(prefix + struct.pack("<BQ", 0x05, 2**40) + b"\0" * 64)
    made["run.mcap: a 1 TB record"] = huge
    body = struct.pack("<QQQI", 0, 0, 2**40, 0) + struct.pack("<I", 4) + b"zstd" + \
        struct.pack("<Q", 16) + b"\x28\xb5\x2f\xfd" + b"\0" * 12
    bomb = tmp / "bomb.mcap"
    bomb.write_bytes(prefix + struct.pack("<BQ", 0x06, len(body)) + body)
    made["run.mcap: a chunk of 1 TB uncompressed"] = bomb
    cut = tmp / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    made["run.mcap: cut short (--check)"] = cut
    made["bag: stamps 0 s, 1 s, 86000 s (allowed)"] = _bag(tmp / "long.mcap", [0, 1, 86_000])
    made["bag: stamps that go back"] = _bag(tmp / "back.mcap", [0, 2, 1])
    return made


def _bag(path: Path, stamps: list[int]) -> Path:
    frame = lane_end_frames(start_m=2.2, end_m=2.3, speed_m_s=0.6)[0]
    with path.open("wb") as stream:
        writer = Ros2McapWriter(stream)
        schema = writer.register_msgdef("sensor_msgs/msg/CompressedImage", COMPRESSED_IMAGE_DEF)
        for i, sec in enumerate(stamps):
            writer.write_message("/camera", schema, {
                "header": {"stamp": {"sec": 1_790_000_000 + sec, "nanosec": 0}},
                "format": "png", "data": cv2.imencode(".png", frame)[1].tobytes()}, log_time=i)
        writer.finish()
    return path


def measure(source: Path, out: Path, check: bool) -> tuple[int, float, float, float, str]:
    """(exit code, wall s, CPU s, peak MB, first stderr line) of one replay in its own
    process."""
    argv = [sys.executable, "-m", "lanewarden", "replay", str(source), "--no-video", "--out",
            str(out)] + (["--check"] if check else [])
    started = time.perf_counter()
    process = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
    assert process.stderr is not None
    err = process.stderr.read()
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - started
    process.returncode = os.waitstatus_to_exitcode(status)
    first = (err.splitlines() or [""])[0]
    return (process.returncode, wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024,
            first)


def main() -> None:
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        run = tmp / "run"
        record_run(run, lane_end_frames(start_m=2.2, end_m=2.7, speed_m_s=0.6)[:15],
                   LanewardenConfig())
        print(f"{'':48s} exit   wall     CPU    peak")
        reference = {"no such file (the command's start-up alone)": (tmp / "missing", False),
                     "a whole recording (--check)": (run, True)}
        for name, (source, check) in reference.items():
            code, wall, cpu, peak, _ = measure(source, tmp / "out", check)
            print(f"{name:48s} {code:4d} {wall:5.1f} s {cpu:5.1f} s {peak:4.0f} MB")
        for name, source in cases(run, tmp).items():
            code, wall, cpu, peak, first = measure(source, tmp / "out", "--check" in name)
            print(f"{name:48s} {code:4d} {wall:5.1f} s {cpu:5.1f} s {peak:4.0f} MB  "
                  f"{first.removeprefix('lanewarden: error: ')[:100]}")
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} at the end")


if __name__ == "__main__":
    main()
