"""Live camera frames for the robot runner: a capture thread that keeps only the newest frame.

This is a thin I/O shell around cv2.VideoCapture. It stamps each frame with the injected clock at
the moment it is read from the driver; the control loop decides whether that frame is fresh, late
or stale. It never drops an error silently: a capture failure is kept and raised on the next read.
"""

from __future__ import annotations

import os
import re
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np

from lanewarden.errors import DeviceError, UsageError
from lanewarden.image_files import too_many_pixels
from lanewarden.supervisor.loop import Frame


@contextmanager
def quiet_opencv() -> Iterator[None]:
    """OpenCV's own warnings (failed camera opens) would add lines to our one-line errors."""
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        yield
    finally:
        cv2.utils.logging.setLogLevel(level)


_URL = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*://")


def open_camera(camera: str, max_pixels: int | None = None) -> cv2.VideoCapture:
    """cv2.VideoCapture on an int index, a file path (also an image sequence like
    'dir/frame_%03d.png') or a URL; UsageError (bad input: no such file, frames larger than
    `max_pixels` by the source's own size) or DeviceError (cannot open it) naming --camera."""
    source: int | str
    if camera.strip().isdigit():
        source = int(camera)
    else:
        source = camera
        if not _URL.match(camera) and "%" not in camera and not Path(camera).exists():
            raise UsageError(
                f"--camera '{camera}': no such file (expected a camera index like 0, a video "
                "file, an image sequence like 'dir/frame_%03d.png' or a stream URL)"
            )
    # FFmpeg logs failed stream opens itself; keep our one-line error the only line.
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    with quiet_opencv():
        capture = cv2.VideoCapture(source)
        opened = capture.isOpened()
    if not opened:
        capture.release()
        raise DeviceError(
            f"--camera '{camera}': cannot open it as a camera or video (is it plugged in, "
            "free, and a format OpenCV reads?)"
        )
    width = int(capture.get(cv2.CAP_PROP_FRAME_WIDTH) or 0)
    height = int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT) or 0)
    if max_pixels is not None and (why := too_many_pixels(width, height, max_pixels)):
        capture.release()
        raise UsageError(f"--camera '{camera}': {why}")
    return capture


def replay_rate_fps(source: str, capture: cv2.VideoCapture, default_fps: float) -> float | None:
    """The pace to replay a recorded source at (its own FPS, else `default_fps`); None if live."""
    if source.isdigit() or "://" in source or source.startswith("/dev/"):
        return None
    if not (Path(source).is_file() or "%" in source):
        return None
    fps = float(capture.get(cv2.CAP_PROP_FPS) or 0.0)
    return fps if 1.0 <= fps <= 240.0 else default_fps


class CameraFrameSource:
    """A `FrameSource` fed by a background capture thread: `read(now)` returns the newest frame
    (the same one again until a newer one arrives; the loop tells new from repeated by index)."""

    def __init__(
        self,
        capture: cv2.VideoCapture,
        clock: Callable[[], float],
        replay_fps: float | None = None,
        max_pixels: int | None = None,
    ) -> None:
        """`replay_fps`: for a recorded source (video file, image sequence), deliver frames at this
        rate instead of as fast as the file can be decoded; None for a live camera. A frame with
        more than `max_pixels` pixels ends the delivery with an `error` (the loop then halts on
        the stale frame)."""
        self._capture = capture
        self._max_pixels = max_pixels
        self._clock = clock
        self._replay_period_s = 1.0 / replay_fps if replay_fps else None
        self._lock = threading.Lock()
        self._latest: Frame | None = None
        self._error: str | None = None
        self._running = True
        self._thread = threading.Thread(target=self._run, name="camera", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        index = 0
        next_due = self._clock()
        while self._running:
            ok, image = self._capture.read()
            if self._replay_period_s is not None:
                delay = next_due - self._clock()
                if delay > 0:
                    time.sleep(delay)
                next_due += self._replay_period_s
            stamp = self._clock()
            if not ok or image is None:
                with self._lock:
                    self._error = "the camera stopped delivering frames"
                return
            height, width = image.shape[:2]
            if self._max_pixels is not None and (
                why := too_many_pixels(width, height, self._max_pixels)
            ):
                with self._lock:
                    self._error = f"camera frame refused: {why}"
                return
            with self._lock:
                self._latest = Frame(image=np.asarray(image), index=index, time_s=stamp)
            index += 1

    def read(self, now: float) -> Frame | None:
        # When the camera dies the newest frame simply stops changing: the loop's watchdog turns
        # its growing age into a stale-frame HALT, and `error` says why for the operator.
        with self._lock:
            frame = self._latest
        if frame is not None and frame.time_s <= now:
            return frame
        return None

    @property
    def error(self) -> str | None:
        with self._lock:
            return self._error

    def close(self) -> None:
        self._running = False
        self._thread.join(timeout=2.0)
        self._capture.release()
