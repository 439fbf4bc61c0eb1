"""Records survive: when the recording cannot be written, `lanewarden run --record` says so once
while running, goes on (the recording is not part of what keeps the robot safe), ends with its
normal exit code and prints its summary; `replay` then says the recording is incomplete.

A full disk for real, without root: the run is a process of its own whose file-size limit
(RLIMIT_FSIZE, with SIGXFSZ ignored so the kernel answers the write with an error instead of
killing the process) is far below what the run records. The kernel's EFBIG takes the very path
ENOSPC takes (an OSError from a write of run.mcap); nothing of ours is mocked. The folder removed
during the run is the other way a recording is lost without a write ever failing."""

from __future__ import annotations

import json
import os
import resource
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from lanewarden.cli import main
from tests.operator.runs import PROJECT_ROOT, long_lane_images, run_beside, wait_until

LIMIT_BYTES = 400_000  # about 10 frames of the 320x240 clip


def _small_disk() -> None:
    """In the child, before exec: files may not grow past LIMIT_BYTES."""
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # ignored signals stay ignored across exec
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))


def test_a_full_disk_while_recording(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    clip = long_lane_images(tmp_path, seconds=3.0)
    record = tmp_path / "run"
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONDONTWRITEBYTECODE": "1"}
    done = subprocess.run(
        [sys.executable, "-m", "lanewarden", "run", "--camera", str(clip), "--base", "sim",
         "--record", str(record), "--duration", "2.5"],
        cwd=PROJECT_ROOT, env=env, preexec_fn=_small_disk, capture_output=True, text=True,
        timeout=120, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "Traceback" not in done.stdout
    warnings = [line for line in done.stdout.splitlines()
                if "warning: the recording stopped" in line]
    assert len(warnings) == 1, done.stdout
    assert "File too large" in warnings[0] and "the run goes on unrecorded" in warnings[0]
    assert "the recording stopped early" in done.stdout  # in the summary
    assert "run ended: --duration 2.5 s reached" in done.stdout
    assert (record / "run.mcap").stat().st_size <= LIMIT_BYTES
    summary = json.loads((record / "summary.json").read_text())  # small: it still fit
    assert summary["complete"] is False and "File too large" in summary["recording_stopped"]
    assert summary["exit_code"] == 0

    code = main(["replay", str(record), "--check", "--no-video", "--out", str(tmp_path / "r")])
    captured = capsys.readouterr()
    assert code == 2
    assert "the recording is incomplete: run.mcap was cut short" in captured.out
    assert captured.err.count("\n") == 1 and "incomplete" in captured.err


def test_the_folder_removed_while_recording(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    clip = long_lane_images(tmp_path, seconds=3.0)
    record = tmp_path / "run"

    def remove_the_folder() -> None:
        assert wait_until(lambda: (record / "run.mcap").exists()
                          and (record / "run.mcap").stat().st_size > 200_000)
        shutil.rmtree(record)

    code = run_beside(remove_the_folder, ["--camera", str(clip), "--base", "sim", "--record",
                                          str(record), "--duration", "2.5"])
    out = capsys.readouterr().out
    assert code == 0
    warnings = [line for line in out.splitlines() if "warning: the recording stopped" in line]
    assert len(warnings) == 1 and "deleted while recording" in warnings[0], out
    assert "not written: summary.json" in out
    assert "run ended: --duration 2.5 s reached" in out
