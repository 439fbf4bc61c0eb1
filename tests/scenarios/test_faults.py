"""The simulated camera's fault modes and the fault schedule acting on real parts."""

from __future__ import annotations

import numpy as np
import pytest

from lanewarden.actuation.sim_base import SimBase
from lanewarden.scenarios.faults import FaultSchedule, camera_pool_size
from lanewarden.scenarios.sim_camera import SimCamera, SimulatedCameraError
from lanewarden.scenarios.spec import FaultSpec

DT = 1 / 30


def capture(camera: SimCamera, k: int) -> None:
    camera.buffer()[:] = k % 256
    camera.capture(k, k * DT)


def test_newest_frame_is_repeated_until_a_newer_one_exists() -> None:
    camera = SimCamera((4, 4), pool_size=4)
    assert camera.read(0.0) is None
    capture(camera, 0)
    first = camera.read(0.0)
    assert first is not None and first.index == 0
    assert camera.read(0.01) is first
    capture(camera, 1)
    second = camera.read(DT)
    assert second is not None and second.index == 1 and int(second.image[0, 0]) == 1


def test_drop_latency_freeze_corrupt_error_and_future() -> None:
    camera = SimCamera((4, 4), pool_size=8)
    for k in range(3):
        capture(camera, k)
    camera.dropping = True
    capture(camera, 3)
    frame = camera.read(3 * DT)
    assert frame is not None and frame.index == 2  # frame 3 never arrived
    camera.dropping = False

    camera.latency_s = 0.1
    for k in range(4, 8):
        capture(camera, k)
        if k == 4:
            held = camera.read(4 * DT)
            assert held is not None and held.index == 2  # nothing older than 0.1 s is newer
    late = camera.read(7 * DT)
    assert late is not None and late.time_s <= 7 * DT - 0.1 + 1e-9 and late.index == 4
    camera.latency_s = 0.0

    newest = camera.read(7 * DT)
    assert newest is not None and newest.index == 7
    camera.freeze(True)
    for k in range(8, 11):
        capture(camera, k)
    frozen = camera.read(10 * DT)
    assert frozen is not None and frozen.index == 10 and frozen.time_s == pytest.approx(10 * DT)
    assert np.all(frozen.image == 7)  # the image it had when the freeze began
    camera.freeze(False)

    camera.corrupt = True
    capture(camera, 11)
    broken = camera.read(11 * DT)
    assert broken is not None and broken.image.size == 0
    camera.corrupt = False

    camera.future_s = 0.5
    capture(camera, 12)
    ahead = camera.read(12 * DT)
    assert ahead is not None and ahead.time_s == pytest.approx(12 * DT + 0.5)
    camera.future_s = 0.0

    camera.failing = True
    with pytest.raises(SimulatedCameraError):
        camera.read(12 * DT)


class StopButton:
    """The loop's operator_stop, as the schedule calls it (records the time)."""

    def __init__(self) -> None:
        self.pressed_at: list[float] = []

    def operator_stop(self, now: float) -> None:
        self.pressed_at.append(now)


def test_schedule_starts_and_ends_faults_on_the_simulated_clock() -> None:
    faults = [
        FaultSpec(kind="bumper", at_s=0.1, duration_s=0.1, bits=4),
        FaultSpec(kind="base_link_loss", at_s=0.3),
        FaultSpec(kind="operator_stop", at_s=0.35),
        FaultSpec(kind="late_frames", at_s=0.0, duration_s=0.05, latency_s=0.2),
        FaultSpec(kind="loop_stall", at_s=0.4, duration_s=0.1),
    ]
    schedule = FaultSchedule(faults)
    camera = SimCamera((2, 2), camera_pool_size(faults, 30.0))
    assert camera.pool_size >= 0.2 * 30
    base = SimBase()
    button = StopButton()
    seen: dict[float, list[str]] = {}
    for k in range(20):
        now = k * 0.05
        changed = schedule.apply(now, camera, base, button)
        if changed:
            seen[round(now, 2)] = changed
        fb = base.feedback(now)
        if now < 0.1 - 1e-9 or now >= 0.2 - 1e-9:
            assert fb.bumper == 0
        else:
            assert fb.bumper == 4
        if now >= 0.3 - 1e-9:
            assert fb.received_at_s is not None and fb.received_at_s < 0.3 - 1e-9
        assert camera.latency_s == (0.2 if now < 0.05 - 1e-9 else 0.0)
        assert schedule.loop_stalled == (0.4 - 1e-9 <= now < 0.5 - 1e-9)
    assert button.pressed_at == [pytest.approx(0.35)]
    assert seen[0.1] == ["bumper begins"] and seen[0.2] == ["bumper ends"]
    assert seen[0.3] == ["base_link_loss begins"]


def test_a_corruption_takes_effect_when_a_late_frame_is_delivered_corrupted() -> None:
    """Campaign run r00356 (seed 1): late frames (0.106 s) and then a perception exception at
    7.319 s. The first frame delivered corrupted was captured before 7.319 (it was late), the
    loop halted on it at once, and the fault's effect was dated by the first corrupted frame
    CAPTURED after the start, 0.13 s later: the judge found the halt before the fault acted and
    called it a false halt. The effect is the delivery of a corrupted frame."""
    faults = [FaultSpec(kind="late_frames", at_s=0.0, duration_s=5.0, latency_s=0.1),
              FaultSpec(kind="perception_exception", at_s=0.5, duration_s=1.0)]
    schedule = FaultSchedule(faults)
    camera = SimCamera((2, 2), camera_pool_size(faults, 30.0))
    base = SimBase()
    first_corrupt = None
    for k in range(40):
        now = k * DT
        schedule.apply(now, camera, base, StopButton())
        capture(camera, k)
        frame = camera.read(now)
        schedule.observe(k, now, camera, base)
        if first_corrupt is None and frame is not None and frame.image.size == 0:
            first_corrupt = (now, frame.time_s)
    assert first_corrupt is not None
    delivered_s, captured_s = first_corrupt
    assert captured_s < 0.5 <= delivered_s  # a late frame, captured before the fault began
    assert schedule.effects[1].time_s == pytest.approx(delivered_s)


def test_a_ring_under_a_collapsed_frame_rate_replays_images_the_camera_delivered() -> None:
    """Campaign seed 3 run r00194: with the frame rate collapsed to a fifth, each capture the
    camera did not deliver still took a pool buffer, so the kept frames' buffers held renders
    the loop never saw; a ring then replayed those, new images to the watchdog, and its
    FRAME_FROZEN came 83 ms after the judge's deadline. Every image a ring or a freeze
    delivers must be one the camera delivered before."""
    camera = SimCamera((4, 4), pool_size=4)
    camera.rate_hz = 6.0  # every fifth capture at 30 Hz
    delivered: list[int] = []
    for k in range(40):
        capture(camera, k)
        frame = camera.read(k * DT)
        if frame is not None and (not delivered or frame.index != delivered[-1]):
            delivered.append(frame.index)
            assert int(frame.image[0, 0]) == frame.index % 256
    assert delivered == [0, 5, 10, 15, 20, 25, 30, 35]
    camera.ring(True, buffers=3)
    replayed = []
    for k in range(40, 70):
        capture(camera, k)
        frame = camera.read(k * DT)
        if frame is not None and frame.index >= 40 and (
                not replayed or frame.index != replayed[-1][0]):
            replayed.append((frame.index, int(frame.image[0, 0])))
    # the last three delivered images (25, 30, 35), in turn, with fresh indices
    assert replayed == [(40, 25), (45, 30), (50, 35), (55, 25), (60, 30), (65, 35)]
    camera.ring(False)
    camera.freeze(True)
    capture(camera, 70)
    frozen = camera.read(70 * DT)
    assert frozen is not None and frozen.index == 70 and int(frozen.image[0, 0]) == 35
