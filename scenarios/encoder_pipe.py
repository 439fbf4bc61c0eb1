"""Frames to an ffmpeg encoder (imageio-ffmpeg's `write_frames` generator), each written whole.

A stop signal landing in the middle of a frame's pipe write (a terminal's Ctrl-C reaching the
`sim` process, or the `demo` terminating its worker processes with SIGTERM) left ffmpeg a
truncated frame, and ffmpeg, whose stderr is the terminal's, reported it in six lines
("Invalid buffer size, packet size ... < expected frame_size ...") beside the command's one
line. So the stop signals are deferred while a frame is written: their handlers are replaced
by one that notes the signal, and after the write the old handlers come back and the noted
signal is sent again, so the process stops, or raises KeyboardInterrupt, between frames.
(Handlers, not a signal mask: a mask holds for one thread only, and a process-directed signal
goes to any thread that does not block it, such as a progress bar's monitor thread.)
SIGQUIT (Ctrl-\\) is not deferred: should an encoder ever stop reading in the middle of a
frame, it still ends the process at once. Only offline commands write videos (`sim`, `demo`,
`replay`); the robot runner does not.

imageio-ffmpeg's generator does not say how ffmpeg ended, and its error for a write to a
stopped ffmpeg is 7 lines with the ffmpeg command: `encoder_process`, `encoder_failure` and
`mp4_problem` let a writer tell a finished video from one ffmpeg could not finish (a file-size
limit, a full disk), in a few words. ffmpeg itself writes to the terminal only what is fatal
(`FFMPEG_LOG_LEVEL`): on a full disk it had added two lines of its own ("[out#0/mp4 @ 0x...]
Error writing trailer: No space left on device") to ours, which said only "exit status 228";
its exit status carries the reason, and ours now says it.
"""

from __future__ import annotations

import errno
import os
import re
import signal
import struct
import subprocess
import threading
from collections.abc import Generator
from pathlib import Path
from types import FrameType
from typing import Any

#: The signals that stop a command (`lanewarden.stop_signals.STOP_SIGNALS`) but SIGQUIT,
#: deferred during a frame's write.
_DEFERRED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

#: What ffmpeg may print on the terminal beside our one line: only what is fatal (a failed
#: write's reason is read from its exit status instead, `encoder_failure`).
FFMPEG_LOG_LEVEL = "fatal"


def ffmpeg_output(path: Path) -> str:
    """`path` as ffmpeg's output argument, read as a file name whatever it holds: ffmpeg takes
    `NAME:...` for a protocol (`a:b.mp4` failed, "Protocol not found"; `file:c.mp4` wrote
    c.mp4) and a name starting with '-' for an option (pathlib makes `./-x.mp4` `-x.mp4`),
    each reported by ffmpeg in lines of its own beside ours."""
    return f"file:{path}"


def send_whole(writer: Generator[Any, Any, None], frame: Any) -> None:
    """`writer.send(frame)` with the stop signals deferred until the frame is written (outside
    the main thread, where handlers cannot be set, a plain send)."""
    if threading.current_thread() is not threading.main_thread():
        writer.send(frame)
        return
    noted: list[int] = []

    def note(signum: int, frame: FrameType | None) -> None:
        noted.append(signum)

    previous = {sig: signal.signal(sig, note) for sig in _DEFERRED}
    try:
        writer.send(frame)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for signum in dict.fromkeys(noted):
            os.kill(os.getpid(), signum)


def encoder_process(writer: Generator[Any, Any, None]) -> subprocess.Popen[bytes] | None:
    """The ffmpeg process behind a started `write_frames` generator (its local `p`), or None.
    imageio-ffmpeg's close() never looks at how ffmpeg ended: a video cut short by a file-size
    limit or a full disk was taken for a finished one."""
    frame = getattr(writer, "gi_frame", None)  # a generator object's; None once it ended
    process = None if frame is None else frame.f_locals.get("p")
    return process if isinstance(process, subprocess.Popen) else None


def encoder_failure(process: subprocess.Popen[bytes] | None,
                    error: BaseException | None = None) -> str | None:
    """Why the encoder failed, in a few words ("ffmpeg stopped: File size limit exceeded",
    "ffmpeg stopped: No space left on device", "ffmpeg stopped: Broken pipe", "ffmpeg ended
    with exit status 1"), or None when it ended
    well. `error`: what a write to it raised; imageio-ffmpeg's text of it is 7 lines (the
    ffmpeg command among them): only its reason is kept."""
    code = None if process is None else process.poll()
    if code is not None and code < 0:
        return f"ffmpeg stopped: {signal.strsignal(-code) or f'signal {-code}'}"
    if code:
        # ffmpeg exits with the error it ended on, AVERROR(e) = -e, as a byte: 256 - e (228 on a
        # full disk, ENOSPC). 255 is its own "stopped by a signal".
        if 128 < code < 255 and (256 - code) in errno.errorcode:
            return f"ffmpeg stopped: {os.strerror(256 - code)}"
        return f"ffmpeg ended with exit status {code}"
    if error is None:
        return None
    first = re.sub(r"^\[Errno \d+\] ", "", (str(error).splitlines() or [""])[0])
    return f"ffmpeg stopped: {first or type(error).__name__}"


def close_encoder(writer: Generator[Any, Any, None],
                  process: subprocess.Popen[bytes] | None, path: Path, frames: int) -> str | None:
    """Close a started `write_frames` generator (`process`: its ffmpeg, `encoder_process`) that
    was sent `frames` frames into `path`, and say why the video is not a finished one (None: it
    is, or nothing was sent): what closing raised, how ffmpeg ended, or the file cut short."""
    try:
        writer.close()
    except (OSError, RuntimeError) as exc:
        return encoder_failure(process, exc)
    if frames == 0:
        return None
    return encoder_failure(process) or (
        None if (problem := mp4_problem(path)) is None else f"the file is {problem}")


def mp4_problem(path: Path) -> str | None:
    """Why the MP4 (or MOV) file at `path` is not a finished one, or None: its top-level boxes
    must fill the file exactly and include `moov` (the index ffmpeg writes last, or first with
    +faststart, once every frame is in; without it no player opens the file)."""
    try:
        with path.open("rb") as file:
            size, offset, boxes = os.fstat(file.fileno()).st_size, 0, set()
            while offset < size:
                file.seek(offset)
                head = file.read(16)
                if len(head) < 8:
                    return f"cut short at byte {offset}"
                length, kind = struct.unpack(">I4s", head[:8])
                if length == 1 and len(head) == 16:
                    length = struct.unpack(">Q", head[8:])[0]
                elif length == 0:
                    length = size - offset
                if length < 8 or offset + length > size:
                    return f"cut short at byte {offset}"
                boxes.add(kind)
                offset += length
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"  # (a phrase after "the file is")
    return None if b"moov" in boxes else "unfinished: no moov box (the index a player needs)"
