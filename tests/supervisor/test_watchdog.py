"""Watchdog: input ages, loop overruns, frozen and invalid frames, late base feedback (a lost base
link is the SafetyGate's: tests/supervisor/test_gate.py)."""

from __future__ import annotations

import numpy as np

from lanewarden.actuation.base import BaseFeedback
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import FrameInfo
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.watchdog import RECENT_IMAGES, Watchdog, frame_fingerprint

CONFIG = SupervisorConfig()
DT = 1.0 / 30.0


def _frame(i: int, t: float, fp: bytes | None = None, new: bool = True) -> FrameInfo:
    return FrameInfo(i, t, fp if fp is not None else i.to_bytes(4, "big"), new)


def _alive(t: float) -> BaseFeedback:
    return BaseFeedback(received_at_s=t)


def test_fresh_inputs_raise_nothing() -> None:
    wd = Watchdog(CONFIG)
    for i in range(60):
        t = i * DT
        assert wd.check(t, _frame(i, t), _alive(t), moving=True) == frozenset()
    assert wd.newest_frame_time_s == 59 * DT


def test_frame_age_goes_late_then_stale() -> None:
    wd = Watchdog(CONFIG)
    wd.check(0.0, _frame(0, 0.0), _alive(0.0), moving=True)
    seen = {}
    for i in range(1, 10):
        t = i * DT
        seen[i] = wd.check(t, _frame(0, 0.0, new=False), _alive(t), moving=True)
    late = [i for i, ev in seen.items() if Event.FRAME_LATE in ev]
    stale = [i for i, ev in seen.items() if Event.FRAME_STALE in ev]
    assert late and stale and max(late) < min(stale)
    assert min(late) * DT > CONFIG.frame_late_s and (min(late) - 1) * DT <= CONFIG.frame_late_s
    assert min(stale) * DT > CONFIG.frame_stale_s
    assert (min(stale) - 1) * DT <= CONFIG.frame_stale_s


def test_a_stale_frame_says_whether_frames_still_arrive() -> None:
    """A safety reviewer's review: a camera that stopped and one whose frames arrive 0.3 s late
    halted with the same words. The detail says which, with the newest frame's age."""
    limit = CONFIG.frame_stale_s  # 0.15 s
    late, dead = Watchdog(CONFIG), Watchdog(CONFIG)
    for wd in (late, dead):
        wd.check(0.0, _frame(0, 0.0), _alive(0.0), moving=True)
    now = 0.2
    assert Event.FRAME_STALE in late.check(now, _frame(1, now - 0.18), _alive(now), moving=True)
    assert late.stale_detail(now, _frame(1, now - 0.18)) == (
        f"frames arrive, but the newest was captured 0.18 s ago, over the limit {limit:g} s")
    assert Event.FRAME_STALE in dead.check(now, _frame(0, 0.0, new=False), _alive(now),
                                           moving=True)
    assert dead.stale_detail(now, _frame(0, 0.0, new=False)) == (
        f"no new frame: the newest was captured 0.20 s ago, over the limit {limit:g} s")
    assert Watchdog(CONFIG).stale_detail(1.0, None) == "no frame at all in 0.00 s"


def test_nothing_ever_arriving_is_stale_after_the_limit() -> None:
    wd = Watchdog(CONFIG)
    assert wd.check(5.0, None, None, moving=False) == frozenset()
    assert wd.check(5.0 + CONFIG.frame_stale_s + 0.01, None, None, moving=False) == {
        Event.FRAME_STALE, Event.LOOP_OVERRUN, Event.BASE_FEEDBACK_LATE}


def test_loop_overrun() -> None:
    wd = Watchdog(CONFIG)
    wd.check(0.0, _frame(0, 0.0), _alive(0.0), moving=True)
    t = CONFIG.loop_overrun_s + 0.01
    assert wd.check(t, _frame(1, t), _alive(t), moving=True) == {Event.LOOP_OVERRUN}


def test_frozen_only_while_moving_and_only_after_the_limit() -> None:
    wd = Watchdog(CONFIG)
    frozen_at = []
    for i in range(30):
        t = i * DT
        moving = i >= 10
        events = wd.check(t, _frame(i, t, fp=b"same"), _alive(t), moving=moving)
        if Event.FRAME_FROZEN in events:
            frozen_at.append(t)
    assert frozen_at, "identical images while moving must be reported"
    # the run of identical images seen while moving starts with the last frame before moving
    assert frozen_at[0] - 9 * DT >= CONFIG.frame_frozen_s - 1e-9
    assert frozen_at[0] - 9 * DT <= CONFIG.frame_frozen_s + DT + 1e-9


def test_changing_images_reset_the_frozen_timer() -> None:
    wd = Watchdog(CONFIG)
    for i in range(60):
        t = i * DT
        fp = (i // 3).to_bytes(4, "big")  # runs of 3 identical frames (0.1 s < limit), each new
        assert Event.FRAME_FROZEN not in wd.check(t, _frame(i, t, fp=fp), _alive(t), True)


def _ring(buffers: int, frames: int, moving: bool) -> list[tuple[float, frozenset[Event], bool]]:
    """A camera cycling through `buffers` old images (A, B, A, B for two): each step's time,
    events and `image_repeated`."""
    wd = Watchdog(CONFIG)
    seen = []
    for i in range(frames):
        t = i * DT
        events = wd.check(t, _frame(i, t, fp=b"buffer %d" % (i % buffers)), _alive(t), moving)
        seen.append((t, events, wd.image_repeated))
    return seen


def test_a_camera_cycling_through_two_old_images_is_frozen() -> None:
    """The attacker's review: a clip alternating two frames (A, B, A, B) engaged and drove 1.84 m
    when only the previous image counted as the same. From the third frame on every image is one
    the camera showed before: FRAME_FROZEN while moving once they have run for frame_frozen_s
    (from the last new image, the second frame)."""
    seen = _ring(2, 30, moving=True)
    assert [repeated for _, _, repeated in seen[:4]] == [False, False, True, True]
    frozen_at = [t for t, events, _ in seen if Event.FRAME_FROZEN in events]
    assert frozen_at, "two alternating images while moving must be reported as frozen"
    assert CONFIG.frame_frozen_s - 1e-9 <= frozen_at[0] - DT <= CONFIG.frame_frozen_s + DT + 1e-9


def test_a_ring_of_old_buffers_is_repeated_images_moving_or_not() -> None:
    """A ring as long as the watchdog remembers: once round, every image is a repeated one (no
    evidence towards engaging), whether the robot moves or not; a stopped robot is never
    FRAME_FROZEN."""
    for moving in (False, True):
        seen = _ring(RECENT_IMAGES, 3 * RECENT_IMAGES, moving)
        assert [repeated for _, _, repeated in seen] == (
            [False] * RECENT_IMAGES + [True] * (2 * RECENT_IMAGES))
        assert any(Event.FRAME_FROZEN in events for _, events, _ in seen) == moving


def test_invalid_frames() -> None:
    wd = Watchdog(CONFIG)
    wd.check(1.0, _frame(10, 1.0), _alive(1.0), moving=True)
    assert Event.FRAME_INVALID in wd.check(1.03, _frame(11, 1.5), _alive(1.03), True)  # future
    assert Event.FRAME_INVALID in wd.check(1.06, _frame(9, 1.05), _alive(1.06), True)  # index back
    assert Event.FRAME_INVALID in wd.check(1.1, _frame(12, 0.9), _alive(1.1), True)  # time back
    assert Event.FRAME_INVALID in wd.check(1.13, _frame(13, float("nan")), _alive(1.13), True)
    assert wd.check(1.16, _frame(14, 1.16), _alive(1.16), True) == frozenset()


def test_base_feedback_is_late_until_the_link_timeout_where_the_gate_takes_over() -> None:
    wd = Watchdog(CONFIG)
    seen = {}
    for i in range(12):
        t = i * DT
        seen[t] = wd.check(t, _frame(i, t), _alive(0.0), moving=True)
    late = [t for t, ev in seen.items() if ev == {Event.BASE_FEEDBACK_LATE}]
    assert late and min(late) > CONFIG.base_feedback_late_s
    assert (min(late) - DT) <= CONFIG.base_feedback_late_s
    assert max(late) <= CONFIG.base_link_timeout_s
    after = [ev for t, ev in seen.items() if t > CONFIG.base_link_timeout_s]
    assert after and all(ev == frozenset() for ev in after)  # BASE_LINK_LOST: the gate's


def test_fingerprint_tells_noise_apart_and_ignores_nothing_but_non_images() -> None:
    rng = np.random.default_rng(3)
    image = rng.integers(0, 256, size=(480, 640, 3), dtype=np.uint8)
    same = image.copy()
    noisy = image.copy()
    noisy[100, 100, 0] ^= 1  # one sampled pixel differs by one grey level
    assert frame_fingerprint(image) == frame_fingerprint(same)
    assert frame_fingerprint(image) != frame_fingerprint(noisy)
    assert frame_fingerprint(image) != frame_fingerprint(image[:, :, 0])
    assert frame_fingerprint(np.zeros((0, 0), np.uint8)) is None
    assert frame_fingerprint("not an image") is None
