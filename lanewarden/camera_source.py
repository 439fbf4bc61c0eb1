"""Camera frames for the robot runner: a capture thread that keeps only the newest frame.

This is a thin I/O shell around cv2.VideoCapture (a camera index, a device, a stream URL, a video
file, a printf-style image sequence) and `ImageSequence` (a folder of images or a glob pattern). It
stamps each frame with the injected clock at the moment it is read from the driver; the control loop
decides whether that frame is fresh, late or stale. A recorded source (video file, image sequence)
is paced at its frame rate. It never drops an error silently: once the capture fails, or a recorded
source ends, every later read raises `CameraLost` (the loop's CAMERA_ERROR: HALT), and `ended` tells
a clean end of a clip from a failure.
"""

from __future__ import annotations

import glob
import os
import re
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np

from lanewarden.documents import shorten
from lanewarden.errors import DeviceError, UsageError
from lanewarden.image_files import (
    DEFAULT_MAX_PIXELS,
    IMAGE_SUFFIXES,
    header_problem,
    read_image,
    too_many_pixels,
)
from lanewarden.supervisor.loop import Frame
from lanewarden.wording import counted


@contextmanager
def quiet_opencv() -> Iterator[None]:
    """OpenCV's own warnings (failed camera opens) would add lines to our one-line errors."""
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        yield
    finally:
        cv2.utils.logging.setLogLevel(level)


#: The largest camera index taken (OpenCV adds a backend's id, in the hundreds, to an index).
MAX_CAMERA_INDEX = 9999
_URL = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*://")
_GLOB_CHARS = re.compile(r"[*?\[]")
#: What a file OpenCV's video reader cannot open is (run --camera, calibrate capture, replay).
NOT_A_VIDEO = "not a video OpenCV can read"
#: What --camera takes.
CAMERA_HELP = ("a camera index like 0, a video file, an image sequence like "
               "'dir/frame_%03d.png' or a stream URL")


class CameraLost(Exception):
    """The frame source stopped delivering: a failed capture, or the end of a recorded clip."""


def _natural_key(path: Path) -> list[object]:
    """frame_2 before frame_10."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path.name)]


def image_sequence_paths(source: str) -> list[Path] | None:
    """The images of a folder or a glob pattern, in natural name order; None when `source` is
    neither (a video file, a camera, a URL, a printf pattern)."""
    path = Path(source)
    if path.is_dir():  # first: a folder named '50%' is a folder, not a printf pattern
        files = [p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES]
    elif _URL.match(source):
        return None
    elif _GLOB_CHARS.search(source) and not path.exists():  # also '50%/*.png'
        files = [Path(p) for p in glob.glob(source)]
        files = [p for p in files if p.is_file()]
    else:  # a video file, a printf pattern ('frame_%03d.png'), a camera
        return None
    return sorted(files, key=_natural_key)


class ImageSequence:
    """A folder or glob of image files behind cv2.VideoCapture's read/get/release/isOpened, so the
    capture thread treats it like a video. An unreadable file ends it with `failure` set."""

    def __init__(self, paths: list[Path], max_pixels: int | None = None) -> None:
        self.paths = paths
        self._max_pixels = DEFAULT_MAX_PIXELS if max_pixels is None else max_pixels
        self._next = 0
        self.failure: str | None = None

    def isOpened(self) -> bool:  # noqa: N802 (cv2.VideoCapture's name)
        return bool(self.paths)

    def read(self) -> tuple[bool, np.ndarray | None]:
        if self._next >= len(self.paths) or self.failure is not None:
            return False, None
        path = self.paths[self._next]
        image, why = read_image(path, cv2.IMREAD_UNCHANGED, self._max_pixels)
        if image is None or image.dtype != np.uint8:
            self.failure = f"{path}: {why or 'not an 8-bit image'}"
            return False, None
        self._next += 1
        return True, image

    def get(self, prop: int) -> float:
        return 0.0  # no frame rate of its own: paced at the configured camera rate

    def release(self) -> None:
        self._next = len(self.paths)


_PRINTF_INT = re.compile(r"%0?(\d*)d")


def numbered_sequence_gap(camera: str, frames_read: int) -> str | None:
    """For a printf-numbered image sequence ('dir/left%02d.jpg') that delivered `frames_read`
    frames: when more numbered files exist, the first missing number that ended it (OpenCV
    reads such a sequence only up to its first gap), as a clause for the user; else None."""
    match = _PRINTF_INT.search(camera)
    if match is None or _URL.match(camera):
        return None
    folder, name = os.path.split(camera)
    head_tail = _PRINTF_INT.split(name, maxsplit=1)
    if len(head_tail) != 3:
        return None
    head, width, tail = head_tail
    wanted = re.compile(re.escape(head) + r"(\d+)" + re.escape(tail))
    try:
        numbers = sorted(int(m.group(1)) for entry in os.scandir(folder or ".")
                         if (m := wanted.fullmatch(entry.name)))
    except OSError:
        return None
    if len(numbers) <= frames_read:
        return None
    present = set(numbers)
    start = numbers[0]
    missing = next((n for n in range(start, numbers[-1] + 1) if n not in present), None)
    if missing is None or missing != start + frames_read:
        return None  # it did not stop at the gap: another reason (--count, --max-frames)
    gap = os.path.join(folder, f"{head}{missing:0{width or 1}d}{tail}")
    return (f"{gap} is missing: a numbered sequence ends at its first gap, so "
            f"{len(numbers) - frames_read} of its {len(numbers)} files were not read (give the "
            "folder or a glob instead, which read every image in natural order)")


def open_camera(camera: str,
                max_pixels: int | None = None) -> cv2.VideoCapture | ImageSequence:
    """cv2.VideoCapture on an int index, a file path (also an image sequence like
    'dir/frame_%03d.png') or a URL, or an `ImageSequence` on a folder of images or a glob
    ('shots/*.png'); UsageError (bad input: no such file, no images, frames larger than
    `max_pixels` by the source's own size) or DeviceError (cannot open it) naming --camera."""
    paths = image_sequence_paths(camera)
    if paths is not None:
        if not paths:
            raise UsageError(
                f"--camera '{camera}': no images there (expected {', '.join(IMAGE_SUFFIXES)} "
                "files in a folder or matching the pattern)"
            )
        if max_pixels is not None and (why := header_problem(paths[0], max_pixels)):
            raise UsageError(f"--camera '{camera}': {paths[0]}: {why}")
        return ImageSequence(paths, max_pixels)
    if Path(camera).suffix.lower() in IMAGE_SUFFIXES and Path(camera).is_file():
        # one photo: a sequence of one frame, read as `detect` reads it (OpenCV's video reader
        # took a cut JPEG for a 1-frame clip and a text file for a camera that sent nothing)
        image, why = read_image(Path(camera), cv2.IMREAD_UNCHANGED,
                                DEFAULT_MAX_PIXELS if max_pixels is None else max_pixels)
        if image is None:
            raise UsageError(f"--camera '{camera}': {why}")
        return ImageSequence([Path(camera)], max_pixels)
    source: int | str
    if camera.strip().isdigit():
        source = int(camera)
        if source > MAX_CAMERA_INDEX:
            raise UsageError(f"--camera '{shorten(camera)}': expected a camera index from 0 to "
                             f"{MAX_CAMERA_INDEX} (0 is the first camera)")
    else:
        source = camera
        if not _URL.match(camera) and "%" not in camera and not Path(camera).exists():
            if camera.startswith("/dev/"):  # a device not there: unplugged, not bad input
                raise DeviceError(f"--camera '{camera}': no such device (is the camera plugged "
                                  "in? `ls /dev/video*` lists the cameras there are)")
            raise UsageError(f"--camera '{camera}': no such file (expected {CAMERA_HELP})")
    # FFmpeg logs failed stream opens itself; keep our one-line error the only line.
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    with quiet_opencv():
        try:
            capture = cv2.VideoCapture(source)
        except (cv2.error, OverflowError, SystemError) as exc:
            raise DeviceError(f"--camera '{shorten(camera)}': cannot open it "
                              f"({shorten(str(exc))})") from None
        opened = capture.isOpened()
    if not opened:
        capture.release()
        if isinstance(source, str) and "%" not in source and Path(source).is_file():
            # a file is the user's input, not a device that may be unplugged or busy
            raise UsageError(f"--camera '{camera}': {NOT_A_VIDEO}; expected {CAMERA_HELP}")
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


def replay_rate_fps(source: str, capture: cv2.VideoCapture | ImageSequence,
                    default_fps: float) -> float | None:
    """The pace to replay a recorded source at (its own FPS, else `default_fps`); None if live."""
    if isinstance(capture, ImageSequence):
        return default_fps
    if source.isdigit() or "://" in source or source.startswith("/dev/"):
        return None
    if not (Path(source).is_file() or "%" in source):
        return None
    fps = float(capture.get(cv2.CAP_PROP_FPS) or 0.0)
    return fps if 1.0 <= fps <= 240.0 else default_fps


class CameraFrameSource:
    """A `FrameSource` fed by a background capture thread: `read(now)` returns the newest frame
    (the same one again until a newer one arrives; the loop tells new from repeated by index), and
    raises `CameraLost` once the capture failed or a recorded source ended."""

    def __init__(
        self,
        capture: cv2.VideoCapture | ImageSequence,
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
        self._ended = False
        #: the newest frame index `read` has returned, and whether it has raised the end of a
        #: recorded clip: a clip's last frame is delivered before its end is (it was lost to
        #: the loop when the end came before the loop's next read)
        self._delivered = -1
        self._end_seen = False
        self.frames_captured = 0
        self._running = True
        self._playing = threading.Event()
        if replay_fps is None:
            self._playing.set()
        self._thread = threading.Thread(target=self._run, name="camera", daemon=True)
        self._thread.start()

    def play(self) -> None:
        """Start playing a recorded source: until then it holds its first frame (so a clip starts
        when the run does, not while the base is being opened), which now counts as just
        captured. No effect on a live camera."""
        if self._playing.is_set():
            return
        with self._lock:
            if self._latest is not None:
                self._latest = Frame(self._latest.image, self._latest.index, self._clock())
            self._delivered = -1  # read before the run (its first frame): the loop's is new
        self._playing.set()

    def _hold_first_frame(self) -> None:
        while self._running and not self._playing.wait(0.1):
            pass

    def _run(self) -> None:
        index = 0
        next_due = self._clock()
        while self._running:
            if index == 1 and not self._playing.is_set():
                self._hold_first_frame()
                next_due = self._clock() + (self._replay_period_s or 0.0)
            ok, image = self._capture.read()
            if self._replay_period_s is not None:
                delay = next_due - self._clock()
                if delay > 0:
                    time.sleep(delay)
                next_due += self._replay_period_s
            stamp = self._clock()
            if not ok or image is None:
                failure = getattr(self._capture, "failure", None)
                with self._lock:
                    if failure:
                        self._error = failure
                    elif self._replay_period_s is not None and index > 0:
                        self._ended = True
                        self._error = f"end of the recorded clip after {counted(index, 'frame')}"
                    else:
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
                self.frames_captured = index + 1
            index += 1

    def read(self, now: float) -> Frame | None:
        # A dead camera or the end of a clip is a fault the loop turns into CAMERA_ERROR (HALT in
        # the same step), and `error` says why for the operator.
        with self._lock:
            frame, error, ended = self._latest, self._error, self._ended
        if error is not None and not (ended and frame is not None
                                      and frame.index > self._delivered):
            self._end_seen = ended
            raise CameraLost(error)
        if frame is not None and frame.time_s <= now:
            self._delivered = frame.index
            return frame
        return None

    @property
    def latest(self) -> Frame | None:
        """The newest frame captured so far, whether or not the source has failed since."""
        with self._lock:
            return self._latest

    @property
    def ended(self) -> bool:
        """A recorded source (video file, image sequence) reached its end (not a failure)."""
        with self._lock:
            return self._ended

    @property
    def end_seen(self) -> bool:
        """A recorded source ended and `read` has said so (after delivering its last frame)."""
        return self._end_seen

    @property
    def error(self) -> str | None:
        with self._lock:
            return self._error

    def close(self) -> None:
        self._running = False
        self._playing.set()
        self._thread.join(timeout=2.0)
        self._capture.release()


def require_camera_view(image: np.ndarray, named: str) -> None:
    """UsageError (exit 2, one line) when a recorded source's first frame is a run video's
    composite (`lanewarden sim`, `demo` or `replay`'s video.mp4: captions above the camera view
    and a map beside it) instead of a camera's own view: perception would look for tape in the
    captions and the map, never engage, and the run would end as if nothing were wrong. `named`
    says where the frame came from (`--camera FILE`, `SOURCE 'FILE'`)."""
    from lanewarden.scenarios.video import run_video_layout  # only for files, never on a camera

    layout = run_video_layout(image)
    if layout is None:
        return
    height, width = image.shape[:2]
    raise UsageError(
        f"{named}: a run video ({width}x{height}: captions above a "
        f"{layout[0]}-pixel-wide camera panel and a {layout[1]}-pixel map), not a camera's view "
        "(expected the camera's own frames: `lanewarden sim --scenario NAME --camera-out "
        "clip.mp4` writes them)")

