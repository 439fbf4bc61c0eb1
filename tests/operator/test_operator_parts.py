"""The operator's small parts: the null base, requests, buttons, the run's statistics and status,
the terminal's line and keys, the recorded step format, the USB latency timer report."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from lanewarden.actuation.base import STOP, BaseFeedback, Pose2D, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.actuation.null_base import NullBase
from lanewarden.actuation.sim_base import SimBase
from lanewarden.bases import SerializedBase
from lanewarden.commands.base import latency_timer_text, usb_latency_timer
from lanewarden.operator import (
    ButtonEdges,
    OperatorPanel,
    RunStats,
    apply_buttons,
    base_link,
    status_of,
    summary_lines,
)
from lanewarden.perception.observation import LaneObservation
from lanewarden.run_record import StepError, StepInput, StepTimes, read_step, step_line
from lanewarden.supervisor.loop import StepRecord
from lanewarden.terminal import format_status, key_action


# ---- NullBase and SerializedBase ---------------------------------------------------------------
def test_null_base_feedback_is_always_fresh_and_harmless() -> None:
    base = NullBase()
    feedback = base.feedback(12.5)
    assert feedback == BaseFeedback(received_at_s=12.5, bumper=0, wheel_drop=0, cliff=0,
                                    buttons=0, battery_v=None, odometry=Pose2D(0.0, 0.0, 0.0))


def test_null_base_keeps_what_would_be_sent() -> None:
    base = NullBase()
    base.send(VelocityCommand(0.2, 0.1), 0.0)
    base.send(STOP, 0.1)
    base.send(VelocityCommand(0.15, -0.3), 0.2)
    assert base.last_command == VelocityCommand(0.15, -0.3)
    assert (base.commands_sent, base.motion_commands_sent) == (3, 2)
    with pytest.raises(ActuationError):
        base.send(VelocityCommand(math.nan, 0.0), 0.3)
    assert base.last_command == STOP, "a malformed command leaves stop, never the last command"
    base.close()
    assert base.last_command == STOP
    with pytest.raises(ActuationError):
        base.send(VelocityCommand(0.1, 0.0), 0.4)


def test_serialized_base_never_lets_time_go_backwards() -> None:
    sim = SimBase()
    base = SerializedBase(sim)
    base.send(VelocityCommand(0.2, 0.0), 1.0)
    base.feedback(2.0)
    base.send(STOP, 1.9)  # another thread's stop, read its clock a moment earlier
    assert sim.commanded == STOP
    assert base.feedback(2.5).received_at_s == 2.5


# ---- requests and buttons ----------------------------------------------------------------------
class LoopCalls:
    """Stands in for ControlLoop's three request methods (records the calls)."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, float]] = []

    def start(self, now: float) -> None:
        self.calls.append(("start", now))

    def resume(self, now: float) -> None:
        self.calls.append(("resume", now))

    def operator_stop(self, now: float) -> None:
        self.calls.append(("stop", now))


def test_stop_goes_to_the_loop_at_once_start_and_resume_wait_for_the_control_thread() -> None:
    loop = LoopCalls()
    panel = OperatorPanel(loop, clock=lambda: 7.0)
    panel.start("key")
    panel.resume("page")
    panel.stop("page")
    assert loop.calls == [("stop", 7.0)]
    delivered = panel.deliver(8.0)
    assert [(r.kind, r.source) for r in delivered] == [("start", "key"), ("resume", "page")]
    assert loop.calls == [("stop", 7.0), ("start", 8.0), ("resume", 8.0)]
    assert panel.deliver(9.0) == []


def test_button_edges_count_a_press_once() -> None:
    edges = ButtonEdges()
    assert [edges.pressed(b) for b in (0, 1, 1, 1, 0, 1, 3, 2, 0)] == [0, 1, 0, 0, 0, 1, 2, 0, 0]


def test_b0_starts_then_resumes_and_b1_stops() -> None:
    loop = LoopCalls()
    panel = OperatorPanel(loop, clock=lambda: 1.0)
    edges = ButtonEdges()
    for buttons in (0, 1, 1, 0):
        apply_buttons(edges, BaseFeedback(received_at_s=0.0, buttons=buttons), panel)
    panel.deliver(2.0)
    for buttons in (2, 0, 1):
        apply_buttons(edges, BaseFeedback(received_at_s=0.0, buttons=buttons), panel)
    panel.deliver(3.0)
    apply_buttons(edges, BaseFeedback(received_at_s=0.0, buttons=3), panel)  # both at once
    apply_buttons(edges, None, panel)
    panel.deliver(4.0)
    assert loop.calls == [("start", 2.0), ("stop", 1.0), ("resume", 3.0), ("stop", 1.0)]


# ---- statistics, status, summary ---------------------------------------------------------------
def _record(index: int | None, t: float, state: str, *, events: tuple[str, ...] = (),
            reason: str | None = None, linear: float = 0.0,
            observation: LaneObservation | None = None) -> StepRecord:
    return StepRecord(frame_index=index, time_s=t, observation=observation,
                      filtered_slope_sum=0.5, slope_sum_variance=0.1, state=state,
                      events=events, command=VelocityCommand(linear, 0.25), halt_reason=reason,
                      frame_time_s=None if index is None else t - 0.01)


def _feedback(t: float, x: float, y: float = 0.0) -> BaseFeedback:
    return BaseFeedback(received_at_s=t, battery_v=16.23, odometry=Pose2D(x, y, 0.0))


def test_run_stats_add_up_a_run() -> None:
    stats = RunStats()
    stats.add(_record(0, 10.0, "HALT", reason="not engaged yet"), _feedback(10.0, 0.0), 0.004)
    stats.add(_record(1, 10.1, "FOLLOW", linear=0.2), _feedback(10.1, 0.3, 0.4), 0.006)
    stats.add(_record(1, 10.2, "FOLLOW", events=("FRAME_LATE",)), _feedback(10.2, 0.3, 0.4),
              0.002)
    stats.add(_record(4, 10.3, "DEGRADED", events=("LOOP_OVERRUN",)), _feedback(10.3, 1.3, 0.4),
              0.008)
    stats.add(_record(5, 10.4, "HALT", reason="LANE_LOST: gone"), None, 0.0)
    assert stats.steps == 5
    assert stats.duration_s == pytest.approx(0.4)
    assert stats.states_visited == ["HALT", "FOLLOW", "DEGRADED"]
    assert stats.distance_m == pytest.approx(1.5)
    assert (stats.frames_seen, stats.frames_skipped) == (4, 2)
    assert (stats.steps_frame_late, stats.loop_overruns) == (1, 1)
    assert stats.loop_time_s_max == pytest.approx(0.008)
    assert stats.loop_time_percentile_s(50) == pytest.approx(0.004)
    assert stats.halt_reason == stats.halt_cause == "LANE_LOST: gone"
    # frames at 9.99, 10.09, 10.29, 10.39: 3 intervals over 0.4 s
    assert stats.fps == pytest.approx(7.5)


def test_status_and_summary_say_what_the_operator_needs() -> None:
    stats = RunStats()
    observation = LaneObservation(3, 9.99, None, None, None, 0.8123,
                                  {"edges": 0.9, "width": 0.75})
    record = _record(3, 10.0, "HALT", reason="LANE_LOST: no usable lane", linear=0.0,
                     observation=observation)
    feedback = _feedback(9.95, 0.0)
    stats.add(record, feedback, 0.0042)
    status = status_of(record, stats, feedback, link=base_link(feedback, 10.0, 0.1, 0.2),
                       extra={"base": "sim"})
    assert status == {
        "time_s": 0.0, "step": 1, "state": "HALT", "halt_reason": "LANE_LOST: no usable lane",
        "events": [], "frame_index": 3, "confidence": 0.812,
        "components": {"edges": 0.9, "width": 0.75}, "slope_sum": None,
        "filtered_slope_sum": 0.5, "command": {"linear_m_s": 0.0, "angular_rad_s": 0.25},
        "fps": None, "loop_ms": 4.2, "loop_ms_max": 4.2, "base_link": "ok", "battery_v": 16.2,
        "distance_m": 0.0,
        "frames_skipped": 0, "frames_late": 0, "base": "sim"}
    assert format_status(status) == ("HALT (LANE_LOST)  - fps  conf 0.81 (weakest width 0.75)  "
                                     "slope -/+0.50  v 0.00 w +0.25  battery 16.2 V  link ok")
    # every component at 1: nothing named
    whole = {**status, "components": {"edges": 1.0, "width": 1.0}}
    assert "conf 0.81  slope" in format_status(whole)
    lines = summary_lines(stats, recording="runs/x",
                          frames_dropped_recording=2, view_dropped=5)
    assert lines == [
        "  halted: LANE_LOST: no usable lane",
        "  distance (odometry) 0.00 m; states visited: HALT",
        "  frames: 1 seen, 0 skipped by the loop, 0 steps with a late frame; loop time mean "
        "4.2 ms, max 4.2 ms",
        "  recorded in runs/x, 2 frames dropped (replay cannot be exact)",
        "  live view: 5 view frames dropped (the loop never waits)",
    ]
    # a later step without a new frame still shows the newest observation's numbers
    stats.add(_record(3, 10.033, "HALT", reason="LANE_LOST: no usable lane"), feedback, 0.0062)
    later = status_of(_record(3, 10.033, "HALT"), stats, feedback, link="ok")
    assert (later["confidence"], later["loop_ms"], later["loop_ms_max"]) == (0.812, 5.2, 6.2)


def test_base_link_by_feedback_age() -> None:
    assert base_link(None, 5.0, 0.1, 0.2) == "lost"
    assert base_link(BaseFeedback(), 5.0, 0.1, 0.2) == "lost"
    assert base_link(BaseFeedback(received_at_s=4.95), 5.0, 0.1, 0.2) == "ok"
    assert base_link(BaseFeedback(received_at_s=4.85), 5.0, 0.1, 0.2) == "late"
    assert base_link(BaseFeedback(received_at_s=4.7), 5.0, 0.1, 0.2) == "lost"


def test_keys() -> None:
    assert [key_action(k) for k in "sS rRxq\n"] == [
        "start", "start", "stop", "resume", "resume", None, None, None]


# ---- the recorded step format ------------------------------------------------------------------
def test_a_recorded_step_reads_back_exactly() -> None:
    step = StepInput(
        t=1234.567890123456, frame=(17, 1234.5432101234567),
        feedback=BaseFeedback(received_at_s=1234.5600000000001, bumper=2, wheel_drop=1,
                              cliff=4, buttons=1, battery_v=15.9,
                              odometry=Pose2D(0.1234567890123, -2.5e-9, math.pi / 3)),
        send_errors=1, requests=("resume", "stop"), command=(0.1999999999999, -0.0731234567891))
    record = _record(17, step.t, "FOLLOW")
    line = json.loads(json.dumps(step_line(record, step)))
    assert read_step(line)[0] == step
    failed = StepInput(t=2.0, frame_error=("CameraLost", "end of the recorded clip after 3 "
                                           "frames"), feedback_error=("KobukiLinkError", "gone"))
    assert read_step(step_line(_record(None, 2.0, "HALT"), failed))[0] == failed


def test_an_unknown_request_is_refused() -> None:
    line = step_line(_record(None, 1.0, "HALT"), StepInput(t=1.0))
    line["input"]["requests"] = ["launch"]
    with pytest.raises(StepError, match="launch"):
        read_step(line)


# ---- base info: the USB adapter's latency timer ------------------------------------------------
def test_latency_timer_is_read_from_sysfs(tmp_path: Path) -> None:
    device = tmp_path / "dev"
    device.mkdir()
    tty = device / "ttyUSB0"
    tty.touch()
    (device / "kobuki").symlink_to(tty)
    sysfs = tmp_path / "sys" / "bus" / "usb-serial" / "devices" / "ttyUSB0"
    sysfs.mkdir(parents=True)
    (sysfs / "latency_timer").write_text("16\n")
    value, path = usb_latency_timer(str(device / "kobuki"), tmp_path / "sys")
    assert (value, path) == (16, sysfs / "latency_timer")
    assert latency_timer_text(value, path) == (
        f"16 ms: set it to 1 ms (16 ms causes malformed Kobuki packets): install the udev rule "
        f"docs/udev/99-kobuki.rules, or for now: echo 1 | sudo tee {sysfs / 'latency_timer'}")
    assert latency_timer_text(1, path) == "1 ms (good)"


def test_latency_timer_of_a_pty_is_not_exposed(tmp_path: Path) -> None:
    value, path = usb_latency_timer("/dev/pts/7", tmp_path / "sys")
    assert value is None
    assert latency_timer_text(value, path) == (
        "not exposed for this port (not a USB serial adapter)")


# ---- the terminal ------------------------------------------------------------------------------
def test_keys_are_read_in_cbreak_mode_and_the_terminal_is_restored() -> None:
    import os
    import termios
    import threading

    from lanewarden.terminal import KeyReader

    master, slave = os.openpty()
    stream = os.fdopen(slave, "r")
    try:
        before = termios.tcgetattr(slave)
        keys: list[str] = []
        got = threading.Event()

        def on_key(key: str) -> None:
            keys.append(key)
            got.set()

        with KeyReader(on_key, stream) as reader:
            assert reader.active
            during = termios.tcgetattr(slave)
            assert not during[3] & termios.ICANON and not during[3] & termios.ECHO
            assert during[3] & termios.ISIG, "Ctrl-C must still send SIGINT"
            os.write(master, b"r")
            assert got.wait(10.0)
            reader.pause()  # Ctrl-Z: the shell gets the terminal as it was
            assert termios.tcgetattr(slave) == before
            reader.resume()  # fg
            assert termios.tcgetattr(slave) == during
        assert keys == ["r"]
        assert termios.tcgetattr(slave) == before
        with pytest.raises(RuntimeError), KeyReader(on_key, stream):
            raise RuntimeError("an error on the way out")
        assert termios.tcgetattr(slave) == before, "restored on an error too"
    finally:
        stream.close()
        os.close(master)


def test_plain_status_lines_on_state_changes_and_every_message() -> None:
    import io

    from lanewarden.terminal import StatusPrinter

    out = io.StringIO()
    printer = StatusPrinter(out, tty_mode=False)
    printer.message("start requested (key)")
    printer.publish({"time_s": 1.5, "state": "FOLLOW", "fps": 30.0})
    printer.close()
    lines = out.getvalue().splitlines()
    assert lines[0] == "start requested (key)"
    assert lines[1] == ("[   1.50 s] FOLLOW  30.0 fps  conf -  slope -/-  v - w -  battery ? V  "
                        "link ?")


def test_a_warning_is_one_line_on_stderr_and_on_stdout() -> None:
    """The recording's "stopped" warning is what a script or a log watching stderr must see; on
    stdout it stays among the status lines (printed once where both are the same terminal)."""
    import io

    from lanewarden.terminal import StatusPrinter

    out, err = io.StringIO(), io.StringIO()
    printer = StatusPrinter(out, tty_mode=False, err=err)
    printer.message("start requested (key)")
    printer.warning("warning: the recording stopped: disk full; the run goes on unrecorded")
    printer.close()
    assert err.getvalue() == ("warning: the recording stopped: disk full; the run goes on "
                              "unrecorded\n")
    assert out.getvalue().splitlines() == [
        "start requested (key)",
        "warning: the recording stopped: disk full; the run goes on unrecorded"]


def test_a_step_time_far_beyond_the_first_is_said_in_a_short_line() -> None:
    """A forged step time of 1e300 s was printed as its 301 digits."""
    times = StepTimes()
    assert times.check(10.0) == ""
    assert times.check(1e300) == ("input.t = 1e+300: 1e+300 s after the first step, more than "
                                  "a recording may span (86400 s)")
    assert times.check(10.0 + 86_400.5) == ("input.t = 86410.5: 86400.5 s after the first "
                                            "step, more than a recording may span (86400 s)")
