"""The control loop on a fake clock: camera faults, perception faults, base faults, run.jsonl."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import pytest

from lanewarden.actuation.base import STOP
from lanewarden.actuation.sim_base import SimBase
from lanewarden.perception.observation import reference_lanes
from lanewarden.supervisor.clock import FakeClock
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.controller import SupervisedController
from lanewarden.supervisor.controllers import make_controller
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.gate import SafetyGate
from lanewarden.supervisor.lecture import LectureController
from lanewarden.supervisor.loop import ControlLoop, Detector, FrameSource, StepRecord
from lanewarden.supervisor.recorder import JsonlRecorder
from tests.supervisor.rig import (
    DT,
    RecordingBase,
    ScriptedCamera,
    ScriptedDetector,
    observation,
)

CONFIG = SupervisorConfig()


class Run:
    """A loop with a SimBase, stepped at the camera rate on a fake clock."""

    def __init__(
        self,
        camera: FrameSource | None = None,
        detector: Detector | None = None,
        base: SimBase | RecordingBase | None = None,
        controller: SupervisedController | LectureController | None = None,
    ) -> None:
        self.clock = FakeClock()
        self.base = base if base is not None else SimBase()
        self.records: list[StepRecord] = []
        self.loop = ControlLoop(
            camera or ScriptedCamera(),
            detector or ScriptedDetector(),
            SafetyGate(controller or SupervisedController(CONFIG), CONFIG),
            self.base,
            record=self.records.append,
        )
        self.steps = 0

    def step(self) -> StepRecord:
        now = self.steps * DT
        self.steps += 1
        return self.loop.step(now)

    def until(self, seconds: float) -> list[StepRecord]:
        out = []
        while self.steps * DT <= seconds + 1e-9:
            out.append(self.step())
        return out

    def engage(self) -> None:
        self.loop.start(0.0)
        self.until(1.0)
        assert self.records[-1].state == "FOLLOW"

    def first(self, state: str, after_s: float = 0.0) -> StepRecord:
        return next(r for r in self.records if r.time_s >= after_s and r.state == state)


def _assert_zero_after_halt(records: list[StepRecord]) -> None:
    halted = False
    for r in records:
        halted = halted or r.state == "HALT"
        if halted:
            assert r.command == STOP and r.state == "HALT", r


def test_frames_stop_halts_within_the_watchdog_limit() -> None:
    last_frame_s = 1.5
    run = Run(camera=ScriptedCamera(stop_at_s=last_frame_s))
    run.engage()
    run.until(3.0)
    halt = run.first("HALT", after_s=last_frame_s)
    assert "FRAME_STALE" in halt.events
    waited = halt.time_s - last_frame_s
    assert waited <= CONFIG.frame_stale_s + DT + 1e-9
    assert waited <= 0.2  # the default limit: HALT within 200 ms of the last frame
    _assert_zero_after_halt(run.records[run.records.index(halt) :])
    assert isinstance(run.base, SimBase)
    assert run.base.commanded == STOP


def test_frozen_frames_halt() -> None:
    freeze_s = 1.5
    run = Run(camera=ScriptedCamera(freeze_at_s=freeze_s))
    run.engage()
    run.until(3.0)
    halt = run.first("HALT", after_s=freeze_s)
    assert "FRAME_FROZEN" in halt.events
    assert halt.time_s - freeze_s <= CONFIG.frame_frozen_s + 2 * DT + 1e-9
    _assert_zero_after_halt(run.records[run.records.index(halt) :])


def test_a_stopped_robot_seeing_the_same_image_is_not_frozen() -> None:
    run = Run(camera=ScriptedCamera(freeze_at_s=0.0))  # identical frames from the start
    run.until(1.0)  # not started: the robot stands still
    assert all("FRAME_FROZEN" not in r.events for r in run.records)


def test_late_frames_degrade_and_recover() -> None:
    def latency(now: float) -> float:  # rises smoothly to 90 ms, holds, then recovers
        if now < 1.5 or now >= 2.5:
            return 0.0
        return min(0.09, 0.3 * (now - 1.5))

    run = Run(camera=ScriptedCamera(latency_s=latency))
    run.engage()
    run.until(4.0)
    degraded = run.first("DEGRADED", after_s=1.5)
    assert "FRAME_LATE" in degraded.events
    assert degraded.command.linear_m_s <= CONFIG.follow_speed_m_s * CONFIG.degraded_speed_fraction
    assert all(r.state != "HALT" for r in run.records if r.time_s >= 1.0)
    assert run.records[-1].state == "FOLLOW"


def test_one_edge_missing_briefly_degrades_then_follows_again() -> None:
    def script(i: int, t: float):  # type: ignore[no-untyped-def]
        if 45 <= i < 52:  # ~0.23 s with the right edge missing
            return observation(i, t, right=False, confidence=0.5)
        return observation(i, t)

    run = Run(detector=ScriptedDetector(script))
    run.engage()
    run.until(3.0)
    states = [r.state for r in run.records if r.frame_index is not None and r.frame_index >= 40]
    assert "DEGRADED" in states and "HALT" not in states
    first_degraded = states.index("DEGRADED")
    assert "ONE_EDGE_LOST" in run.records[40 + first_degraded].events
    assert states[-1] == "FOLLOW"


def test_lane_ending_halts_within_lane_lost_limit() -> None:
    def script(i: int, t: float):  # type: ignore[no-untyped-def]
        if t >= 2.0:
            return observation(i, t, left=False, right=False, confidence=0.0)
        return observation(i, t)

    run = Run(detector=ScriptedDetector(script))
    run.engage()
    run.until(3.0)
    halt = run.first("HALT", after_s=2.0)
    assert "LANE_LOST" in halt.events
    assert halt.time_s - 2.0 <= CONFIG.lane_lost_halt_s + DT + 1e-9
    _assert_zero_after_halt(run.records[run.records.index(halt) :])


def test_perception_exception_halts_and_the_loop_keeps_running() -> None:
    def script(i: int, t: float):  # type: ignore[no-untyped-def]
        if i == 40:
            raise RuntimeError("boom in the detector")
        return observation(i, t)

    run = Run(detector=ScriptedDetector(script))
    run.engage()
    run.until(2.0)
    halt = run.first("HALT", after_s=0.5)
    assert halt.frame_index == 40 and "PERCEPTION_ERROR" in halt.events
    assert halt.halt_reason is not None and "RuntimeError: boom in the detector" in halt.halt_reason
    assert run.records[-1].frame_index == 60  # still stepping
    _assert_zero_after_halt(run.records[run.records.index(halt) :])


def test_camera_exception_is_a_fault_not_a_crash() -> None:
    run = Run(camera=ScriptedCamera(fail_at_s=1.2))
    run.engage()
    run.until(2.0)
    halt = run.first("HALT", after_s=1.2)
    assert "CAMERA_ERROR" in halt.events and halt.time_s < 1.2 + DT
    assert halt.halt_reason is not None and "/dev/video0" in halt.halt_reason


def test_sim_base_bumper_and_link_loss_halt() -> None:
    bumped = Run()
    bumped.engage()
    assert isinstance(bumped.base, SimBase)
    bumped.base.inject(bumper=2)
    record = bumped.step()
    assert record.state == "HALT" and "BUMPER" in record.events and record.command == STOP

    cut = Run()
    cut.engage()
    assert isinstance(cut.base, SimBase)
    cut_at = (cut.steps - 1) * DT
    cut.base.set_link_alive(False)
    cut.until(2.0)
    halt = cut.first("HALT", after_s=cut_at)
    assert "BASE_LINK_LOST" in halt.events
    assert halt.time_s - cut_at <= CONFIG.base_link_timeout_s + DT + 1e-9


def test_base_send_failure_becomes_link_lost_and_halts() -> None:
    base = RecordingBase()
    run = Run(base=base)
    run.engage()
    base.fail_send = True
    failed = run.step()
    assert "BASE_LINK_LOST" in failed.events
    base.fail_send = False
    after = run.step()
    assert after.state == "HALT" and after.command == STOP
    assert after.halt_reason is not None and "/dev/ttyUSB0" in after.halt_reason
    assert base.sent[-1][1] == STOP


def test_operator_stop_zeroes_at_once_and_latches() -> None:
    base = RecordingBase()
    run = Run(base=base)
    run.engage()
    run.until(1.5)
    assert not base.sent[-1][1].is_stop
    run.loop.operator_stop(1.51)
    assert base.sent[-1] == (1.51, STOP)
    run.until(2.5)
    _assert_zero_after_halt(run.records[-30:])
    assert run.records[-1].halt_reason == "OPERATOR_STOP: operator stop"
    run.loop.resume(2.5)
    run.until(3.0)
    assert run.records[-1].state == "FOLLOW"


def test_no_frames_at_all_never_moves() -> None:
    class NoCamera:
        def read(self, now: float) -> None:
            return None

    run = Run(camera=NoCamera())
    run.loop.start(0.0)
    run.until(1.0)
    assert all(r.command == STOP and r.state == "HALT" for r in run.records)
    assert any("FRAME_STALE" in r.events for r in run.records)


def test_a_run_log_that_cannot_be_written_names_its_file() -> None:
    """A full disk under `replay --out` had said 'cannot write the output (No space left on
    device)', naming no file (an attacker's review). The write itself names it, and so does the
    close that flushes what the failed write left buffered."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full on this system")
    records: list[StepRecord] = []
    run = Run()
    run.loop = ControlLoop(
        ScriptedCamera(), ScriptedDetector(),
        SafetyGate(SupervisedController(CONFIG), CONFIG), SimBase(), record=records.append,
    )  # fmt: skip
    run.loop.start(0.0)
    run.until(0.1)
    recorder = JsonlRecorder("/dev/full")
    with pytest.raises(OSError) as raised:
        recorder(records[0])
    assert (raised.value.filename, raised.value.errno) == ("/dev/full", errno.ENOSPC)
    with pytest.raises(OSError) as closing:
        recorder.close()
    assert (closing.value.filename, closing.value.errno) == ("/dev/full", errno.ENOSPC)


def test_jsonl_recorder_writes_one_flushed_line_per_step(tmp_path: Path) -> None:
    path = tmp_path / "run.jsonl"
    with JsonlRecorder(path) as recorder:
        run = Run()
        run.loop = ControlLoop(
            ScriptedCamera(), ScriptedDetector(),
            SafetyGate(SupervisedController(CONFIG), CONFIG), SimBase(),
            record=recorder,
        )  # fmt: skip
        run.loop.start(0.0)
        run.until(0.5)
        lines = path.read_text().splitlines()  # readable while still open: flushed per line
        assert len(lines) == run.steps == recorder.lines
    rows = [json.loads(line) for line in lines]
    assert rows[0]["state"] == "HALT" and rows[0]["observation"]["frame_index"] == 0
    assert rows[-1]["state"] == "FOLLOW"
    assert set(rows[-1]) >= {
        "frame_index", "time_s", "observation", "filtered_slope_sum", "slope_sum_variance",
        "state", "events", "command", "halt_reason",
    }  # fmt: skip
    assert rows[-1]["command"]["linear_m_s"] > 0.0


def test_records_say_whether_the_supervisor_trusted_each_new_frame() -> None:
    def script(i: int, t: float):  # type: ignore[no-untyped-def]
        if i == 20:
            return observation(i, t, confidence=0.1)  # below confidence_usable_min (0.2)
        if i == 21:
            return observation(i, t, right=False, confidence=0.3)  # one edge, usable
        return observation(i, t)

    run = Run(camera=ScriptedCamera(period_s=2 * DT), detector=ScriptedDetector(script))
    run.loop.start(0.0)
    run.until(1.5)
    by_frame = {r.frame_index: r.lane_trusted for r in run.records if r.observation is not None}
    assert (by_frame[19], by_frame[20], by_frame[21], by_frame[22]) == (True, False, True, True)
    assert {r.lane_trusted for r in run.records if r.observation is None} == {None}
    assert {r.as_json()["lane_trusted"] for r in run.records} == {True, False, None}

    lecture = Run(controller=LectureController(CONFIG))
    lecture.loop.start(0.0)
    lecture.until(0.5)
    assert {r.lane_trusted for r in lecture.records} == {None}  # the lecture judges nothing


def test_recorder_refuses_an_unwritable_path_in_one_line(tmp_path: Path) -> None:
    with pytest.raises(SupervisorError) as err:
        JsonlRecorder(tmp_path / "missing-dir" / "run.jsonl")
    assert "missing-dir" in str(err.value) and "\n" not in str(err.value)


def test_lecture_controller_keeps_going_when_the_lane_ends_but_obeys_stop() -> None:
    def script(i: int, t: float):  # type: ignore[no-untyped-def]
        if t >= 1.0:
            return observation(i, t, left=False, right=False, confidence=0.0)
        return observation(i, t, slope_sum=7.0 if i > 15 else 0.0)

    base = RecordingBase()
    run = Run(detector=ScriptedDetector(script), base=base, controller=LectureController(CONFIG))
    run.until(0.3)
    assert all(r.state == "HALT" and r.command == STOP for r in run.records)  # not started
    run.loop.start(0.3)
    run.until(2.0)
    assert run.records[-1].state == "TURN_LEFT"  # its last decision, forever
    assert not run.records[-1].command.is_stop
    run.loop.operator_stop(2.0)
    assert base.sent[-1][1] == STOP
    assert run.step().state == "HALT"


def test_lecture_controller_still_halts_on_a_bumper_until_resumed() -> None:
    base = RecordingBase()
    run = Run(base=base, controller=LectureController(CONFIG))
    run.loop.start(0.0)
    run.until(0.5)
    assert not run.records[-1].command.is_stop
    base.bumper = 1
    hit = run.step()
    assert hit.state == "HALT" and hit.command == STOP and hit.halt_reason is not None
    assert "BUMPER" in hit.halt_reason
    base.bumper = 0
    run.until(1.5)
    assert all(r.state == "HALT" and r.command == STOP for r in run.records[-10:])  # latched
    run.loop.resume(1.5)
    run.until(2.0)
    assert not run.records[-1].command.is_stop


def test_make_controller_by_name() -> None:
    assert isinstance(make_controller("lecture", CONFIG), LectureController)
    assert isinstance(make_controller("supervised", CONFIG), SupervisedController)
    with pytest.raises(SupervisorError, match="--controller: unknown controller 'pid'"):
        make_controller("pid", CONFIG)


def test_operator_stop_arriving_during_a_step_is_never_lost() -> None:
    base = RecordingBase()
    holder: list[ControlLoop] = []

    def script(i: int, t: float):  # type: ignore[no-untyped-def]
        if i == 40:  # another thread presses stop while this step is running
            holder[0].operator_stop(t)
        return observation(i, t)

    run = Run(detector=ScriptedDetector(script), base=base)
    holder.append(run.loop)
    run.engage()
    run.until(40 * DT)
    assert run.records[-1].frame_index == 40
    assert base.sent[-1][1] == STOP  # the step's own command was followed by STOP
    assert run.step().state == "HALT"


class ReferenceDetector(ScriptedDetector):
    """Records, per frame, which earlier frames perception was told to agree with (`previous`:
    none, one, or several, the best agreement counting)."""

    def __init__(self, untrusted: set[int]) -> None:
        super().__init__(script=lambda i, t: observation(
            i, t, confidence=0.0 if i in untrusted else 0.9))
        self.reference: dict[int, tuple[int, ...]] = {}

    def detect(self, image, frame_index, time_s, previous=None):  # type: ignore[no-untyped-def]
        self.reference[frame_index] = tuple(lane.frame_index for lane in reference_lanes(previous))
        return super().detect(image, frame_index, time_s, previous)


def test_consistency_is_measured_against_the_last_trusted_lane_while_it_is_recent() -> None:
    # Frames 40 and 41 are untrusted (a seam taken for an edge): 41 and 42 are compared with
    # the frame before them and with frame 39, the last lane the supervisor trusted (the better
    # agreement counts). From frame 60, untrusted frames until 60 + lane_lost_halt_s: past that
    # window after frame 59 there is no trusted lane left, and each frame is compared with the
    # one before only, as before engaging (a false lane must repeat itself to score).
    window_frames = round(CONFIG.lane_lost_halt_s / DT)  # 6
    untrusted = {40, 41, *range(60, 60 + window_frames + 3)}
    detector = ReferenceDetector(untrusted)
    run = Run(detector=detector)
    run.engage()
    run.until(3.0)
    assert detector.reference[0] == ()  # nothing before the first frame
    assert detector.reference[39] == (38,)  # the frame before is the trusted one
    assert detector.reference[40] == (39,)
    assert detector.reference[41] == (40, 39)
    assert detector.reference[42] == (41, 39)
    assert detector.reference[43] == (42,)
    w = window_frames
    assert detector.reference[59 + w] == (59 + w - 1, 59)  # exactly the window old: kept
    assert detector.reference[59 + w + 1] == (59 + w,)
    assert detector.reference[60 + w + 3] == (60 + w + 2,)
    assert detector.reference[60 + w + 4] == (60 + w + 3,)  # trusted again


def test_the_lectures_controller_compares_each_frame_with_the_one_before() -> None:
    detector = ReferenceDetector({40, 41})
    run = Run(detector=detector, controller=LectureController(CONFIG))
    run.loop.start(0.0)
    run.until(2.0)
    assert detector.reference[41] == (40,) and detector.reference[42] == (41,)
