"""A video ffmpeg cannot finish, and a plot that cannot be written, are one line naming the
file, exit 1, with the PARTIAL marker kept.

imageio-ffmpeg's close() never looks at how ffmpeg ended: under a file-size limit `replay` had
exited 0 with a video.mp4 no player opens (no moov box), on a full disk it blamed poster.jpg,
and ffmpeg stopping mid-video had been 7 lines with the ffmpeg command; a full disk under
plot.png had named no file (an attacker's review). The limit is a real RLIMIT_FSIZE in the
command's process, which its ffmpeg inherits."""

from __future__ import annotations

import re
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lanewarden.scenarios.encoder_pipe import encoder_failure, mp4_problem
from lanewarden.scenarios.errors import ScenarioOutputError
from lanewarden.scenarios.plot import write_plot

SIM = ["sim", "--scenario", "fault-operator-stop", "--quiet"]


def sim_limited(out: Path, limit_bytes: int | None,
                *extra: str) -> subprocess.CompletedProcess[str]:
    """`lanewarden sim` into `out` (with `extra` flags), its files (and its ffmpeg's) limited to
    `limit_bytes`."""

    def limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG)
        if limit_bytes is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    return subprocess.run([sys.executable, "-m", "lanewarden", *SIM, "--out", str(out), *extra],
                          capture_output=True, text=True, preexec_fn=limit, timeout=600)


def test_a_video_ffmpeg_cannot_finish_is_one_line_and_the_run_stays_partial(
        tmp_path: Path) -> None:
    whole = sim_limited(tmp_path / "whole", None)
    assert whole.returncode == 0, whole.stderr
    video = tmp_path / "whole" / "video.mp4"
    assert mp4_problem(video) is None
    size = video.stat().st_size
    # just under the finished file: ffmpeg fails writing its index at the end (it had exited 0
    # in the review's replay); 200 KiB: it stops in the middle of the frames (run.jsonl,
    # 125 KiB in all, stays below)
    for name, limit in (("at-the-end", size - 4096), ("mid-video", 200 * 1024)):
        out = tmp_path / name
        done = sim_limited(out, limit)
        assert (done.returncode, done.stderr) == (1, (
            f"lanewarden: error: {out / 'video.mp4'}: video encoding failed (ffmpeg stopped: "
            "File size limit exceeded)\n")), name
        assert "video.mp4" in (out / "PARTIAL").read_text(encoding="utf-8"), name
        assert not (out / "poster.jpg").exists(), name


def test_a_camera_clip_ffmpeg_cannot_finish_is_one_line_and_moved_aside(tmp_path: Path) -> None:
    """`sim --camera-out clip.mp4` shares the encoder: ffmpeg stopped by the limit is one line
    naming the clip (it had been 7, with the ffmpeg command), and the cut clip is moved aside so
    it is never played as the clip."""
    clip = tmp_path / "camera" / "clip.mp4"
    done = sim_limited(tmp_path / "out", 64 * 1024, "--no-video", "--camera-out", str(clip))
    assert done.returncode == 1
    assert done.stderr.startswith(f"lanewarden: error: --camera-out {clip}: cannot write frame ")
    assert done.stderr.endswith(" (ffmpeg stopped: File size limit exceeded)\n")
    assert done.stderr.count("\n") == 1
    assert sorted(p.name for p in clip.parent.iterdir()) == ["clip.partial.mp4"]


def test_a_run_log_past_a_file_size_limit_is_one_line_naming_it(tmp_path: Path) -> None:
    """A write refused with EFBIG (a file-size limit) had been a traceback from the recorder."""
    out = tmp_path / "out"
    done = sim_limited(out, 64 * 1024, "--no-video")
    assert (done.returncode, done.stderr) == (1, (
        f"lanewarden: error: {out / 'run.jsonl'}: cannot write the output (File too large)\n"))


def box(kind: bytes, body: bytes = b"") -> bytes:
    return (8 + len(body)).to_bytes(4, "big") + kind + body


def test_a_cut_or_unfinished_mp4_is_told_from_a_finished_one(tmp_path: Path) -> None:
    """(A real finished video passes: above.)"""
    finished = box(b"ftyp", b"isom\0\0\0\0") + box(b"moov", b"\0" * 40) + box(b"mdat", b"x" * 99)
    for name, data, problem in (
            ("finished", finished, None),
            ("cut", finished[:-10], "cut short at byte 64"),
            ("no-index", box(b"ftyp", b"isom\0\0\0\0") + box(b"mdat", b"x" * 99),
             "unfinished: no moov box (the index a player needs)"),
            ("empty", b"", "unfinished: no moov box (the index a player needs)")):
        (tmp_path / name).write_bytes(data)
        assert mp4_problem(tmp_path / name) == problem, name
    assert mp4_problem(tmp_path / "missing") == "unreadable (No such file or directory)"


def test_a_plot_that_cannot_be_written_names_plot_png(tmp_path: Path) -> None:
    """plot.png a link to /dev/full: every write fails with ENOSPC, as on a full disk, whose
    OSError names no file."""
    plot = tmp_path / "plot.png"
    plot.symlink_to("/dev/full")
    with pytest.raises(ScenarioOutputError) as failed:
        write_plot(plot, "a run", np.array([0.0, 0.1]), [0.1, 0.2], [0.1, 0.2], [0.9, 0.9],
                   ["FOLLOW", "HALT"], [None, "LANE_LOST"], 0.5, [])
    assert str(failed.value) == f"{plot}: cannot write the plot (No space left on device)"


def test_a_title_or_reason_with_dollar_signs_is_plain_text(tmp_path: Path) -> None:
    """'replay of price_$5_$10' and a run folder named '$\\undefinedfoo{x}$' were read as math
    text: a ParseSyntaxException traceback, and the replay's metrics and report were lost (an
    attacker's review)."""
    plot = tmp_path / "plot.png"
    write_plot(plot, "replay of $\\undefinedfoo{x}$ price_$5_$10", np.array([0.0, 0.1]),
               [0.1, 0.2], [0.1, 0.2], [0.9, 0.9], ["FOLLOW", "HALT"],
               [None, "CAMERA_LOST: --camera $x$: gone"], 0.5, [])
    assert plot.stat().st_size > 0


def test_a_video_on_a_full_disk_is_one_line_saying_so(small_disk: Path) -> None:
    """On a real full disk ffmpeg had added two lines of its own ("[out#0/mp4 @ 0x...] Error
    writing trailer: No space left on device", "Error closing file: ...") to ours, which said
    only "ffmpeg ended with exit status 228". run.jsonl (125 KiB) fits; the video does not."""
    out = small_disk / "out"
    done = sim_limited(out, None)
    assert (done.returncode, done.stderr) == (1, (
        f"lanewarden: error: {out / 'video.mp4'}: video encoding failed (ffmpeg stopped: "
        "No space left on device)\n"))
    assert "video.mp4" in (out / "PARTIAL").read_text(encoding="utf-8")
    assert not (out / "poster.jpg").exists()


@pytest.mark.parametrize(("status", "said"), [
    (228, "ffmpeg stopped: No space left on device"),  # AVERROR(ENOSPC) as a byte
    (229, "ffmpeg stopped: File too large"),  # EFBIG
    (255, "ffmpeg ended with exit status 255"),  # ffmpeg's own "a signal stopped it"
    (1, "ffmpeg ended with exit status 1"),
])
def test_how_ffmpeg_ended_is_read_off_its_exit_status(status: int, said: str) -> None:
    process = subprocess.Popen([sys.executable, "-c", f"raise SystemExit({status})"])
    process.wait(timeout=60)
    assert encoder_failure(process) == said


def test_camera_frames_on_a_full_disk_are_one_line_saying_so(
        small_disk: Path, tmp_path: Path) -> None:
    """`sim --camera-out FOLDER` writes PNGs: on a full disk libpng had printed "libpng error:
    Write Error" above a line that said only "cv2.imwrite failed"."""
    frames = small_disk / "frames"
    done = sim_limited(tmp_path / "out", None, "--no-video", "--camera-out", str(frames))
    assert done.returncode == 1
    assert re.fullmatch(rf"lanewarden: error: --camera-out {re.escape(str(frames))}: cannot "
                        r"write frame \d+ \(No space left on device\)\n", done.stderr), done.stderr


def test_a_run_video_in_a_folder_named_like_a_protocol_is_written(tmp_path: Path) -> None:
    """ffmpeg reads a relative `a:b/video.mp4` as protocol 'a' ("Protocol not found", lines of
    its own and a failed run): the run's video is named to it as a file, as the camera clip is."""
    done = subprocess.run([sys.executable, "-m", "lanewarden", *SIM, "--out", "a:b"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert (done.returncode, done.stderr) == (0, "")
    assert mp4_problem(tmp_path / "a:b" / "video.mp4") is None
