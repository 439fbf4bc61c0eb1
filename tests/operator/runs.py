"""Helpers for the end-to-end runs: rendered clips on disk, reading a run folder, waiting on a
condition (never sleeping a fixed time), and starting `lanewarden run` as a process."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from lanewarden.ros_bag import McapFile, decode
from lanewarden.run_mcap import STEP_TOPIC
from tests.operator.clips import lane_end_frames, write_images, write_video

PROJECT_ROOT = Path(__file__).resolve().parents[2]


def wait_until(condition: Callable[[], bool], timeout_s: float = 20.0,
               poll_s: float = 0.02) -> bool:
    """Re-check `condition` until it holds or `timeout_s` passed (a generous bound, not a
    timing assertion)."""
    deadline = time.monotonic() + timeout_s
    pause = threading.Event()
    while time.monotonic() < deadline:
        if condition():
            return True
        pause.wait(poll_s)
    return condition()


def free_port() -> int:
    """A loopback port nobody listens on now (for --view)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def moving(packets: list[Any]) -> bool:
    """The Kobuki stand-in received a non-zero base-control command."""
    return any(p.base_control not in (None, (0, 0)) for p in packets)


def steps(folder: Path) -> list[dict[str, Any]]:
    """The recorded steps so far (the steps of run.mcap's chunks written so far; a chunk being
    written is not read yet)."""
    path = folder / "run.mcap"
    if not path.exists() or path.stat().st_size < 8:
        return []  # not there yet, or created and its first bytes still in the writer's buffer
    out = []
    for message in McapFile(path).messages(lambda topic: topic.name == STEP_TOPIC):
        out.append(json.loads(decode(message, str(path)).record))
    return out


def lane_then_end_video(folder: Path) -> Path:
    """About 2.5 s: the lane, its end leaving the view, then only tile seams."""
    return write_video(lane_end_frames(start_m=2.0, end_m=3.5, speed_m_s=0.6),
                       folder / "lane-ends.mp4")


def lane_gap_lane_images(folder: Path, lane_after_s: float = 3.0) -> Path:
    """A lane (1.5 s), no lane (1 s: seams only), then the lane again (`lane_after_s`): a
    LANE_LOST halt the operator can resume from."""
    frames: list[np.ndarray] = []
    frames += lane_end_frames(start_m=1.0, end_m=1.75, speed_m_s=0.5)
    frames += lane_end_frames(start_m=5.0, end_m=5.5, speed_m_s=0.5, seed=1)
    frames += lane_end_frames(start_m=1.0, end_m=1.0 + 0.5 * lane_after_s, speed_m_s=0.5, seed=2)
    return write_images(frames, folder / "gap")


def long_lane_images(folder: Path, seconds: float = 6.0) -> Path:
    """A straight lane for `seconds` (the tape never ends within the clip)."""
    return write_images(lane_end_frames(start_m=0.3, end_m=0.3 + 0.4 * seconds,
                                        speed_m_s=0.4), folder / "long")


def run_beside(operator: Callable[[], None], args: list[str]) -> int:
    """`lanewarden run ARGS` in this thread (its signal handlers need the main thread) while
    `operator` acts from another one; the run's exit code."""
    from lanewarden.cli import main

    helper = threading.Thread(target=operator, daemon=True)
    helper.start()
    try:
        return main(["run", *args])
    finally:
        helper.join(10)


def start_run(args: list[str], **popen: Any) -> subprocess.Popen[str]:
    """`lanewarden run ...` as its own process (for signals, the dead-man, a terminal)."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "lanewarden", "run", *args], text=True,
                            cwd=PROJECT_ROOT, env=env, **popen)
