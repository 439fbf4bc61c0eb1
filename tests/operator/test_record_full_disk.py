"""Records survive: when the recording cannot be written, `lanewarden run --record` says so once
while running, goes on (the recording is not part of what keeps the robot safe), ends with its
normal exit code and prints its summary; `replay` then says the recording is incomplete. A
recording that cannot keep up drops frames, says so once, and replay says it is not exact.

A full disk for real, without root: the run is a process of its own whose file-size limit
(RLIMIT_FSIZE, with SIGXFSZ ignored so the kernel answers the write with an error instead of
killing the process) is far below what the run records. The kernel's EFBIG takes the very path
ENOSPC takes (an OSError from a write of run.mcap); nothing of ours is mocked. The folder removed
during the run is the other way a recording is lost without a write ever failing. A disk that
fills for one write and has room again after is a file object failing once at the OS boundary
(the only stand-in here: no filesystem does that on demand)."""

from __future__ import annotations

import errno
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from lanewarden.actuation.base import VelocityCommand
from lanewarden.cli import main
from lanewarden.config import LanewardenConfig
from lanewarden.recording import RunRecorder, create_run_folder
from lanewarden.ros_bag import McapFile
from lanewarden.run_record import StepInput
from lanewarden.supervisor.loop import Frame, StepRecord
from tests.operator.clips import lane_end_frames
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
    # the run's own exit code: 0 for its --duration; 3 only when a loaded machine starved the
    # camera into a safety stop (FRAME_STALE), which stderr names; never the recording's
    assert done.returncode in (0, 3), done.stderr
    # stderr: the recording's warning, one line (it had been on stdout only), and the stop
    errors = done.stderr.splitlines()
    assert len(errors) == (1 if done.returncode == 0 else 2), done.stderr
    assert errors[0].startswith("warning: the recording stopped: ") and \
        "File too large" in errors[0], done.stderr
    if done.returncode == 3:
        assert errors[1].startswith("lanewarden: safety stop: FRAME"), done.stderr
    assert "Traceback" not in done.stderr and "Traceback" not in done.stdout
    warnings = [line for line in done.stdout.splitlines()
                if "warning: the recording stopped" in line]
    assert len(warnings) == 1, done.stdout
    assert "File too large" in warnings[0] and "the run goes on unrecorded" in warnings[0]
    assert "the recording stopped early" in done.stdout  # in the summary
    assert "\nrun ended" in done.stdout
    assert (record / "run.mcap").stat().st_size <= LIMIT_BYTES
    summary = json.loads((record / "summary.json").read_text())  # small: it still fit
    assert summary["complete"] is False and "File too large" in summary["recording_stopped"]
    assert summary["exit_code"] == done.returncode

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
    out, err = capsys.readouterr()
    assert code in (0, 3)  # 3: a loaded machine starved the camera (see the test above)
    warnings = [line for line in out.splitlines() if "warning: the recording stopped" in line]
    assert len(warnings) == 1 and "deleted while recording" in warnings[0], out
    # on stderr too, one line (it had been on stdout only, lost to whoever reads stderr)
    assert [line for line in err.splitlines() if "recording" in line] == warnings, err
    assert "not written: summary.json" in out
    assert "\nrun ended" in out


def test_a_recording_that_cannot_keep_up(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """No room for a single waiting frame (as when the writer falls far behind): every frame
    is dropped and counted, said once while running, and replay says it cannot be exact."""
    import lanewarden.recording as recording

    monkeypatch.setattr(recording, "FRAME_QUEUE_FRAMES", 0)
    clip = long_lane_images(tmp_path, seconds=1.0)
    record = tmp_path / "run"
    code = main(["run", "--camera", str(clip), "--base", "sim", "--record", str(record),
                 "--duration", "1.0"])
    out = capsys.readouterr().out
    assert code in (0, 3)  # 3: a loaded machine starved the camera (see the first test)
    warnings = [line for line in out.splitlines() if "drops frames" in line]
    assert len(warnings) == 1 and "cannot be replayed exactly" in warnings[0], out
    summary = json.loads((record / "summary.json").read_text())
    assert summary["frames_written"] == 0 and summary["frames_dropped"] > 0
    assert summary["steps_written"] == summary["steps"]
    code = main(["replay", str(record), "--check", "--no-video", "--out", str(tmp_path / "r")])
    captured = capsys.readouterr()
    assert code == 2 and "the recording is not exact" in captured.err


class _DiskFillsOnce:
    """A file whose `failing`-th write fails with ENOSPC (part of it written, as a real short
    write leaves it) and whose later writes succeed again (space freed meanwhile)."""

    def __init__(self, inner: Any, failing: int) -> None:
        self._inner = inner
        self._writes = 0
        self._failing = failing

    def write(self, data: bytes) -> int:
        self._writes += 1
        if self._writes == self._failing:
            self._inner.write(bytes(data)[: len(data) // 2])
            self._inner.flush()
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return int(self._inner.write(data))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


def test_after_one_failed_write_nothing_more_is_written(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """A write that failed half-way leaves run.mcap a readable prefix: the recording stops there
    (writing on after the space came back would put whole records after half of one)."""
    real_open = Path.open

    def open_filling(self: Path, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        stream = real_open(self, mode, *args, **kwargs)
        return _DiskFillsOnce(stream, failing=20) if self.name == "run.mcap" else stream

    folder = create_run_folder(tmp_path / "run")
    monkeypatch.setattr(Path, "open", open_filling)
    recorder = RunRecorder(folder)
    monkeypatch.setattr(Path, "open", real_open)
    recorder.write_header({"camera": "clip"}, LanewardenConfig().model_dump(mode="json"), None)
    frames = lane_end_frames(start_m=1.0, end_m=1.5, speed_m_s=0.6)
    for i, image in enumerate(frames):
        record = StepRecord(i, float(i), None, None, None, "HALT", (), VelocityCommand(), None)
        recorder.record(record, StepInput(t=float(i), frame=(i, float(i))),
                        Frame(image, i, float(i)))
    summary = recorder.close({})
    assert summary.problem is not None and "No space left on device" in summary.problem
    mcap = McapFile(folder / "run.mcap")
    steps = [m for m in mcap.messages() if m.topic.name == "/lanewarden/step"]
    assert mcap.cut_short is not None, "the file ends where the failed write did"
    assert 0 < len(steps) < len(frames)
