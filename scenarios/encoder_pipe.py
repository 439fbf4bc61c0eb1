"""Frames to an ffmpeg encoder (imageio-ffmpeg's `write_frames` generator), each written whole.

A stop signal landing in the middle of a frame's pipe write (a terminal's Ctrl-C reaching the
`sim` process, or the `demo` terminating its worker processes with SIGTERM) left ffmpeg a
truncated frame, and ffmpeg, whose stderr is the terminal's, reported it in six lines
("Invalid buffer size, packet size ... < expected frame_size ...") beside the command's one
line. So the stop signals are held back while a frame is written: the process stops, or raises
KeyboardInterrupt, between frames, and ffmpeg ends the video on a whole frame, silently.
SIGQUIT (Ctrl-\\) is not held back: should an encoder ever stop reading in the middle of a
frame, it still ends the process at once. (Only offline commands write videos: `sim`, `demo`,
`replay`; the robot runner does not.)
"""

from __future__ import annotations

import signal
from collections.abc import Generator
from typing import Any

#: The signals that stop a command (`lanewarden.stop_signals.STOP_SIGNALS`) but SIGQUIT, held
#: back during a frame's write.
_HELD = frozenset({signal.SIGINT, signal.SIGTERM, signal.SIGHUP})


def send_whole(writer: Generator[Any, Any, None], frame: Any) -> None:
    """`writer.send(frame)` with the stop signals held back until the frame is written (in this
    thread; where the platform cannot hold signals back, a plain send)."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:
        writer.send(frame)
        return
    held = mask(signal.SIG_BLOCK, _HELD)
    try:
        writer.send(frame)
    finally:
        mask(signal.SIG_SETMASK, held)
