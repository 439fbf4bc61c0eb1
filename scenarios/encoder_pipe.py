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
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Generator
from types import FrameType
from typing import Any

#: The signals that stop a command (`lanewarden.stop_signals.STOP_SIGNALS`) but SIGQUIT,
#: deferred during a frame's write.
_DEFERRED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


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
