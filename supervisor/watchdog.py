"""Watchdog: are the inputs fresh, in order and alive? Pure logic on injected time.

Checks, each step:
- loop overrun: time since the previous step above `loop_overrun_s` (LOOP_OVERRUN, a warning: the
  frame checks below are what stop a robot whose loop stalls);
- camera: age of the newest frame (now - capture time) above `frame_late_s` (FRAME_LATE) or
  `frame_stale_s` (FRAME_STALE); a new frame from the future, or going backwards in time or index
  (FRAME_INVALID); identical images for `frame_frozen_s` while the robot is commanded to move
  (FRAME_FROZEN; a stopped robot may legitimately see the same image: "identical" as below);
  and, moving or not, whether this step's new frame shows exactly the image of one of the last
  RECENT_IMAGES frames (`image_repeated`: no new evidence, so the supervisor does not count it
  towards engaging or recovering: a camera that froze on a confident lane while the robot waited
  must not be what engages it). Identical to any of the recent images, not only the previous
  one: a camera stuck re-delivering a ring of old buffers (A, B, A, B: a V4L2 mmap ring, a
  looping decoder) shows no new image either, and an attacker's review drove 1.84 m on two
  alternating frames when only the previous image counted (a real sensor's noise never gives the
  same pixels twice);
- base: age of the newest feedback above `base_feedback_late_s` but not above
  `base_link_timeout_s` (BASE_FEEDBACK_LATE; beyond it the SafetyGate halts on BASE_LINK_LOST for
  every controller, see supervisor/gate.py).
Before the first frame or feedback, ages count from the watchdog's first check, so "nothing ever
arrived" turns into STALE (and, at the gate, LINK_LOST) after the same limits.

Never reads a clock, never sleeps; the images themselves are reduced to a fingerprint by the loop.
"""

from __future__ import annotations

import hashlib
import math
from collections import deque

import numpy as np

from lanewarden.actuation.base import BaseFeedback
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import FrameInfo
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.hazards import feedback_age_s

#: Pixel stride of the fingerprint: 1/16 of the pixels is plenty to tell sensor noise apart.
FINGERPRINT_STRIDE = 4
#: A new frame whose image equals any of this many previous frames' is a repeated image: a
#: camera cycling through up to this many stale buffers is caught (V4L2 drivers keep 2-8; half a
#: second at 30 fps).
RECENT_IMAGES = 16


def frame_fingerprint(image: object) -> bytes | None:
    """A cheap digest of a strided copy of the image; None for something that is not an image."""
    if not isinstance(image, np.ndarray) or image.ndim < 2 or image.size == 0:
        return None
    sample = image[::FINGERPRINT_STRIDE, ::FINGERPRINT_STRIDE].tobytes()  # one strided copy
    digest = hashlib.blake2b(sample, digest_size=16)
    digest.update(repr((image.shape, image.dtype.str)).encode())
    return digest.digest()


#: `mark_capture` makes this many different versions of an image: a power of two above
#: RECENT_IMAGES, so no version repeats one the watchdog remembers.
CAPTURE_MARKS = 2 * RECENT_IMAGES


def mark_capture(image: np.ndarray, index: int) -> np.ndarray:
    """`image` (in place, and returned) made different, as the fingerprint sees it, from the
    versions marked with the CAPTURE_MARKS - 1 indices before `index`: capture `index`'s count
    in the lowest bit of a few pixels of the top row, pixels the fingerprint samples, outside
    every region perception reads (its region of interest is floor below the horizon). For the
    cameras that can deliver the same pixels twice where a real one cannot: the simulator's,
    whose sensor noise comes from a bank of a dozen frames, and a still held in view
    (lanewarden survey). A real sensor's noise never repeats."""
    version = index % CAPTURE_MARKS
    width = image.shape[1]
    for bit in range(CAPTURE_MARKS.bit_length() - 1):
        if version >> bit & 1:
            image[0, min(FINGERPRINT_STRIDE * bit, width - 1)] ^= 1
    return image


class Watchdog:
    def __init__(self, config: SupervisorConfig) -> None:
        self._config = config
        self._first_check_s: float | None = None
        self._last_check_s: float | None = None
        self._newest_index: int | None = None
        self._newest_time_s: float | None = None
        #: The fingerprints of the last RECENT_IMAGES accepted frames' images (None: not an image).
        self._recent: deque[bytes | None] = deque(maxlen=RECENT_IMAGES)
        self._same_since_s: float | None = None
        #: This step's new frame shows exactly the image of one of the last RECENT_IMAGES
        #: accepted frames.
        self.image_repeated = False

    @property
    def newest_frame_time_s(self) -> float | None:
        """Capture time of the newest accepted frame."""
        return self._newest_time_s

    def stale_detail(self, now: float, frame: FrameInfo | None) -> str:
        """What FRAME_STALE measured, one line: how old the newest frame is and whether frames
        still arrive (late ones: their capture times lag) or none does (a camera that stopped
        delivering); a reviewer could not tell the two apart from the halt reason."""
        if self._newest_time_s is None:
            since = now - (self._first_check_s if self._first_check_s is not None else now)
            return f"no frame at all in {since:.2f} s"
        age = now - self._newest_time_s
        limit = f"the limit {self._config.frame_stale_s:g} s"
        if frame is not None and frame.is_new:
            return f"frames arrive, but the newest was captured {age:.2f} s ago, over {limit}"
        return f"no new frame: the newest was captured {age:.2f} s ago, over {limit}"

    def check(
        self,
        now: float,
        frame: FrameInfo | None,
        feedback: BaseFeedback | None,
        moving: bool,
    ) -> frozenset[Event]:
        """Events for this step. `moving`: the previous command sent to the base was not a stop."""
        cfg = self._config
        events: set[Event] = set()
        if self._first_check_s is None:
            self._first_check_s = now
        self.image_repeated = False
        if self._last_check_s is not None and now - self._last_check_s > cfg.loop_overrun_s:
            events.add(Event.LOOP_OVERRUN)
        self._last_check_s = now

        if frame is not None and frame.is_new:
            if self._frame_is_valid(now, frame):
                events |= self._accept_frame(frame, moving)
            else:
                events.add(Event.FRAME_INVALID)

        frame_ref = self._newest_time_s if self._newest_time_s is not None else self._first_check_s
        frame_age = now - frame_ref
        if frame_age > cfg.frame_stale_s:
            events.add(Event.FRAME_STALE)
        elif frame_age > cfg.frame_late_s:
            events.add(Event.FRAME_LATE)

        feedback_age = feedback_age_s(feedback, self._first_check_s, now)
        if cfg.base_feedback_late_s < feedback_age <= cfg.base_link_timeout_s:
            events.add(Event.BASE_FEEDBACK_LATE)
        return frozenset(events)

    def _frame_is_valid(self, now: float, frame: FrameInfo) -> bool:
        if not math.isfinite(frame.time_s) or frame.time_s > now:
            return False
        if self._newest_time_s is not None and frame.time_s < self._newest_time_s:
            return False
        return self._newest_index is None or frame.index > self._newest_index

    def _accept_frame(self, frame: FrameInfo, moving: bool) -> frozenset[Event]:
        previous_time_s = self._newest_time_s
        same = frame.fingerprint is not None and frame.fingerprint in self._recent
        self.image_repeated = same
        self._newest_index = frame.index
        self._newest_time_s = frame.time_s
        self._recent.append(frame.fingerprint)
        if not (same and moving) or previous_time_s is None:
            self._same_since_s = None
            return frozenset()
        if self._same_since_s is None:
            self._same_since_s = previous_time_s
        if frame.time_s - self._same_since_s >= self._config.frame_frozen_s:
            return frozenset({Event.FRAME_FROZEN})
        return frozenset()
