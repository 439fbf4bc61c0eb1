"""The dead-man as the base's safety monitor, end to end over the pty stand-in: it latches a stop
on a hazard by itself (even with the control process frozen), forwards nothing non-zero until the
hazard has cleared and the operator resumes, and tells the control process, whose gate halts on
it. Also: it runs the installed code, whatever folder it is started from, and refuses to work
with a control process of another version.

Real processes; no sleeps: every wait is on a condition with a generous deadline. The assertions
are about what reached the wire and in which order, never how fast (benchmarks/deadman_latency.py
measures that).
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

import lanewarden
from lanewarden.actuation.base import STOP, BaseFeedback, VelocityCommand
from lanewarden.actuation.config import ActuationConfig
from lanewarden.actuation.deadman import EXIT_VERSION_MISMATCH
from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.deadman_messages import (
    MAX_MESSAGE_BYTES,
    Hello,
    decode_hello,
    encode_control,
)
from lanewarden.actuation.kobuki_base import KobukiBase
from lanewarden.assembly import build_bring_up_gate, build_bring_up_loop
from lanewarden.cli import main
from lanewarden.config import LanewardenConfig
from lanewarden.run_record import StepError, feedback_as_json, feedback_from_json
from lanewarden.runner import OperatorEngage
from lanewarden.supervisor.control_io import ControlInputs
from tests.actuation.kobuki_standin import STOP_PACKET, KobukiStandIn, ReceivedPacket
from tests.actuation.processes import (
    DEADLINE_S,
    ControlProcess,
    is_motion,
    motion_after_the_stop,
    start_lanewarden,
    stderr_lines,
    wait_for_more_packets,
)
from tests.operator.runs import steps
from tests.test_robot_runner import clip, last_line, scenes  # noqa: F401 (a fixture)

MOVE = VelocityCommand(0.2, 0.0)
#: The control side's heartbeat timeout in the frozen-control tests: long, so the stop under
#: test is the bumper's even when a loaded machine delays the press after the freeze.
SLOW_HEARTBEAT_S = 1.0
#: `run` for the latch test: every timeout long, so that a loaded machine's delays between the
#: freeze, the press and the thaw cannot add a halt of their own.
PATIENT_RUN = f"""\
actuation:
  heartbeat_timeout_s: {SLOW_HEARTBEAT_S}
  feedback_timeout_s: 1.0
supervisor:
  frame_late_s: 0.5
  frame_stale_s: 1.0
  frame_frozen_s: 1.0
  base_feedback_late_s: 0.5
  base_link_timeout_s: 1.0
  loop_overrun_s: 0.5
"""


def _sent_after(standin: KobukiStandIn, since_s: float) -> list[ReceivedPacket]:
    return [p for p in standin.snapshot() if p.arrival_s >= since_s]


def _controls_since(standin: KobukiStandIn, since_s: float) -> list[tuple[int, int]]:
    return [c for p in _sent_after(standin, since_s) if (c := p.base_control) is not None]


def _controls_from(standin: KobukiStandIn, mark: int) -> list[tuple[int, int]]:
    return [c for p in standin.snapshot()[mark:] if (c := p.base_control) is not None]


@pytest.fixture
def slow_control(standin: KobukiStandIn) -> Iterator[ControlProcess]:
    process = ControlProcess(standin.port, "--heartbeat-timeout-s", str(SLOW_HEARTBEAT_S))
    try:
        yield process
    finally:
        process.close()


# ---- the acceptance case: a bumper while the control process is frozen -------------------------
def test_a_bumper_while_the_control_process_is_frozen_stops_the_base_until_an_operator_resume(
        standin: KobukiStandIn, slow_control: ControlProcess) -> None:
    control = slow_control
    assert standin.wait_for(lambda pkts: any(map(is_motion, pkts)), 3 * DEADLINE_S)
    os.kill(control.process.pid, signal.SIGSTOP)  # frozen: nothing in it can react
    pressed_s = standin.press(bumper=2)
    assert standin.wait_for(lambda pkts: any(
        p.arrival_s >= pressed_s and p.packet == STOP_PACKET for p in pkts), DEADLINE_S), \
        "the dead-man did not stop the base on the bumper"
    wait_for_more_packets(standin, 10)
    os.kill(control.process.pid, signal.SIGCONT)
    # the dead-man's own latch (not its heartbeat timeout), reported to the control process
    assert control.expect("latched ").split(" ", 1)[1] == "bumper pressed (centre)"
    wait_for_more_packets(standin, 15)  # the control process sends 0.2 m/s all along...
    control.say("rearm")  # ...and an automatic re-arm is not a resume
    assert control.expect("not rearmed ") == "latched"
    control.say("resume")  # the operator's resume, with the bumper still pressed
    assert control.expect("refused ") == "resume refused: bumper pressed (centre)"
    released_s = standin.press(bumper=0)
    assert standin.wait_for(lambda _: len(_controls_since(standin, released_s)) >= 10, DEADLINE_S)
    resumed_mark = len(standin.snapshot())
    control.say("resume")
    assert control.expect("resumed") == ""
    # on the wire: the stop after the bumper packet, then nothing non-zero until the resume
    held = [p.base_control for p in standin.snapshot()[:resumed_mark]
            if p.arrival_s >= pressed_s and p.base_control is not None]
    first_stop = held.index((0, 0))
    assert set(held[first_stop:]) == {(0, 0)} and len(held[first_stop:]) >= 35
    assert standin.wait_for(lambda pkts: any(map(is_motion, pkts[resumed_mark:])), DEADLINE_S)


def test_a_control_process_suspended_long_enough_to_miss_messages_still_learns_of_the_latch(
        standin: KobukiStandIn, slow_control: ControlProcess) -> None:
    control = slow_control
    assert standin.wait_for(lambda pkts: any(map(is_motion, pkts)), 3 * DEADLINE_S)
    control.say("hold")  # as before Ctrl-Z: the dead-man holds stop without heartbeats
    assert control.expect("held") == ""
    os.kill(control.process.pid, signal.SIGSTOP)
    # 5 s of feedback and WIRE reports (100 messages a second): more than the socket's send
    # buffer holds (net.core.wmem_default, 208 KiB by default: ~250 such messages)
    for _ in range(5):
        wait_for_more_packets(standin, 50)
    standin.press(bumper=1)  # the latch's MODE message finds the socket full
    wait_for_more_packets(standin, 5)
    standin.press(bumper=0)
    os.kill(control.process.pid, signal.SIGCONT)
    assert control.expect("latched ").split(" ", 1)[1] == "bumper pressed (right)"


# ---- in-process: the latch, the feedback, the resume ----------------------------------------
@pytest.fixture
def kobuki(standin: KobukiStandIn) -> Iterator[KobukiBase]:
    with KobukiBase.open(standin.port) as base:
        yield base


def _drive_until(base: KobukiBase, done: Callable[[], bool], what: str,
                 command: VelocityCommand = MOVE) -> None:
    """A control loop's heartbeat: send `command` at every feedback packet until `done()`."""
    deadline = time.monotonic() + DEADLINE_S
    while not done():
        assert time.monotonic() < deadline, what
        base.send(command, time.monotonic())
        base.wait_for(_newer_packet(base.packets_received), 0.05)


def _newer_packet(seen: int) -> Callable[[KobukiBase], bool]:
    return lambda base: base.packets_received > seen


def _drive_until_mode(base: KobukiBase, mode: DeadmanMode) -> None:
    _drive_until(base, lambda: base.deadman_mode is mode, f"the dead-man never became {mode}")


@pytest.mark.parametrize(("bits", "reason"), [
    ({"cliff": 4}, "cliff sensor triggered (left)"),
    ({"wheel_drop": 3}, "wheel dropped (left, right)"),
])
def test_a_hazard_latches_shows_in_the_feedback_and_only_a_resume_after_it_clears_moves(
        standin: KobukiStandIn, kobuki: KobukiBase, bits: dict[str, int], reason: str) -> None:
    _drive_until_mode(kobuki, DeadmanMode.ARMED)
    assert standin.wait_for(lambda pkts: any(map(is_motion, pkts)), DEADLINE_S)
    hazard_s = standin.press(**bits)
    _drive_until_mode(kobuki, DeadmanMode.LATCHED)  # sending MOVE throughout: no error
    assert kobuki.feedback(time.monotonic()).stop_latched == reason
    kobuki.rearm(time.monotonic())
    cleared_s = standin.press(cliff=0, wheel_drop=0)
    assert standin.wait_for(lambda _: len(_controls_since(standin, cleared_s)) >= 5, DEADLINE_S)
    assert kobuki.deadman_mode is DeadmanMode.LATCHED  # cleared, and re-armed: not resumed
    assert motion_after_the_stop(standin, hazard_s) == []
    assert kobuki.resume(time.monotonic()) is True, kobuki.deadman_reason
    assert kobuki.feedback(time.monotonic()).stop_latched is None
    mark = len(standin.snapshot())
    _drive_until(kobuki, lambda: any(map(is_motion, standin.snapshot()[mark:])), "no motion")
    kobuki.send(STOP, time.monotonic())


def test_the_deadman_keeps_commands_inside_the_envelope(standin: KobukiStandIn,
                                                        kobuki: KobukiBase) -> None:
    # a control process asking for the full 0.7 m/s at once gets the dead-man's 1 m/s^2 ramp
    _drive_until_mode(kobuki, DeadmanMode.ARMED)
    _drive_until(kobuki, lambda: (700, 0) in _controls_from(standin, 0),
                 "it never reached the commanded speed", VelocityCommand(0.7, 0.0))
    kobuki.send(STOP, time.monotonic())
    # the whole climb from standstill: arming forwards MOVE's first steps (how many depends on
    # when the test sees ARMED), then 0.7 m/s continues the same ramp
    speeds = [speed for speed, _ in _controls_from(standin, 0)]
    top = speeds.index(700)
    last_stop = top - speeds[top::-1].index(0)
    ramp = speeds[last_stop:top + 1]
    # 20 mm/s more per 20 ms packet (+-1: the protocol truncates to whole mm/s), never a jump:
    # so at least 700 / 21 packets from 0 to 700
    assert all(0 < later - earlier <= 21 for earlier, later in zip(ramp, ramp[1:], strict=False))
    assert ramp[0] == 0 and len(ramp) - 1 >= 34


# ---- `run`: the gate halts on the dead-man's latch and the summary names it -------------------
def test_run_halts_on_the_deadmans_latch_and_names_it(
        scenes: dict[str, list[Path]], tmp_path: Path) -> None:  # noqa: F811
    config = tmp_path / "relaxed.yaml"
    config.write_text(PATIENT_RUN)
    camera = clip(tmp_path / "camera", scenes, ("lane", 30.0))
    with KobukiStandIn() as base:
        run = start_lanewarden("run", "--camera", camera, "--port", base.port, "--record",
                               str(tmp_path / "run"), "--config", str(config),
                               "--assume-camera")  # (the simulator's default camera's frames)
        try:
            assert base.wait_for(lambda pkts: any(map(is_motion, pkts)), 6 * DEADLINE_S)
            os.kill(run.pid, signal.SIGSTOP)
            pressed_s = base.press(bumper=2)  # a short press, over before the run can see it
            assert base.wait_for(lambda pkts: any(
                p.arrival_s >= pressed_s and p.packet == STOP_PACKET for p in pkts), DEADLINE_S)
            base.press(bumper=0)
            os.kill(run.pid, signal.SIGCONT)
            wait_for_more_packets(base, 40)  # it runs again, halted by the latch
            os.kill(run.pid, signal.SIGTERM)
            out, err = run.communicate(timeout=3 * DEADLINE_S)
        finally:
            run.kill()
            run.wait()
        assert motion_after_the_stop(base, pressed_s) == []
    reason = ("DEADMAN_LATCHED: the dead-man latched a stop on its own, held until a resume "
              "(bumper pressed (centre))")
    assert run.returncode == 3
    assert stderr_lines(err) == [f"lanewarden: safety stop: {reason}"]
    assert last_line(out).startswith(f"run ended by a safety stop: {reason}")
    records = steps(tmp_path / "run")
    latched = [r for r in records if r["halt_reason"] == reason]
    # the latch is the reason whether or not the run also read, after SIGCONT, a feedback packet
    # from while it was stopped that still shows the bumper (that depends on the machine's load)
    assert latched and latched[0]["input"]["feedback"]["stop_latched"] == "bumper pressed (centre)"


# ---- item 7: the installed code, the same version ----------------------------------------------
def test_the_deadman_imports_the_installed_lanewarden_not_a_decoy_in_the_current_folder(
        standin: KobukiStandIn, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    decoy = tmp_path / "lanewarden"
    (decoy / "actuation").mkdir(parents=True)
    marker = tmp_path / "decoy-imported"
    (decoy / "__init__.py").write_text(
        f"open({str(marker)!r}, 'w').close()\n__version__ = '0.1.0'\n")
    (decoy / "actuation" / "__init__.py").write_text("")
    (decoy / "actuation" / "deadman.py").write_text("raise SystemExit(97)\n")
    monkeypatch.chdir(tmp_path)  # the dead-man starts here
    with KobukiBase.open(standin.port) as base:
        hello = base.deadman_hello
        base.send(STOP, time.monotonic())
        assert base.wait_for(lambda b: b.deadman_mode is DeadmanMode.ARMED, DEADLINE_S)
    assert hello is not None
    assert hello.package_folder == str(Path(lanewarden.__file__).resolve().parent)
    assert not marker.exists()


def test_a_version_mismatch_is_one_line_exit_1_and_nothing_reaches_the_wire(
        standin: KobukiStandIn, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    installed = lanewarden.__version__
    monkeypatch.setattr(lanewarden, "__version__", "9.9.9")  # this side is another release
    assert main(["base", "drive", "--port", standin.port, "--linear", "0.1",
                 "--duration", "1"]) == 1
    lines = stderr_lines(capsys.readouterr().err)
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"lanewarden: error: {standin.port}: the dead-man process is "
                               f"lanewarden {installed} (dead-man protocol 2) from ")
    assert ", but this side is lanewarden 9.9.9 (dead-man protocol 2) from " in lines[0]
    assert standin.snapshot() == []  # the dead-man is gone and never wrote to the port


def test_the_deadman_itself_refuses_a_control_process_of_another_version(
        standin: KobukiStandIn, tmp_path: Path) -> None:
    ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    ours.send(encode_control(Hello(1, "0.0.1", "/old/lanewarden")))
    deadman = subprocess.Popen(
        [sys.executable, "-P", "-m", "lanewarden.actuation.deadman", "--port", standin.port,
         "--control-fd", str(theirs.fileno())], pass_fds=(theirs.fileno(),), cwd=tmp_path)
    theirs.close()
    try:
        assert deadman.wait(timeout=3 * DEADLINE_S) == EXIT_VERSION_MISMATCH
        said = decode_hello(ours.recv(MAX_MESSAGE_BYTES))
    finally:
        deadman.kill()
        ours.close()
    assert (said.protocol, said.package_version) == (2, lanewarden.__version__)
    assert standin.snapshot() == []  # it exited without ever writing to the port


# ---- the control side: the gate halts on the latch; only the operator's start/resume clears it --
def test_the_gate_halts_on_the_deadmans_latch_whatever_the_controller() -> None:
    # the bring-up controller wants its command whatever the events say: only the gate can halt
    gate = build_bring_up_gate(LanewardenConfig(), VelocityCommand(0.1, 0.0))
    assert gate.step(ControlInputs(feedback=BaseFeedback(received_at_s=0.0),
                                   start_requested=True), 0.0).state == "BRING_UP"
    out = gate.step(ControlInputs(feedback=BaseFeedback(
        received_at_s=0.05, stop_latched="wheel dropped (left)")), 0.05)
    assert (out.state, out.command) == ("HALT", STOP)
    assert out.halt_reason == ("DEADMAN_LATCHED: the dead-man latched a stop on its own, held "
                               "until a resume (wheel dropped (left))")


@pytest.fixture
def patient_kobuki(standin: KobukiStandIn) -> Iterator[KobukiBase]:
    """A KobukiBase whose dead-man waits SLOW_HEARTBEAT_S for heartbeats: a test that steps a
    loop only now and then must not trip it."""
    with KobukiBase.open(standin.port,
                         config=ActuationConfig(heartbeat_timeout_s=SLOW_HEARTBEAT_S)) as base:
        yield base


def test_the_operators_resume_releases_the_deadmans_latch_and_the_loops(
        standin: KobukiStandIn, patient_kobuki: KobukiBase) -> None:
    kobuki = patient_kobuki
    loop = build_bring_up_loop(LanewardenConfig(), VelocityCommand(0.1, 0.0), kobuki)
    engage = OperatorEngage(loop, kobuki)
    engage.start(time.monotonic())
    assert loop.step(time.monotonic()).state == "BRING_UP"
    standin.press(cliff=1)
    assert kobuki.wait_for(lambda b: b.deadman_mode is DeadmanMode.LATCHED, DEADLINE_S)
    assert loop.step(time.monotonic()).state == "HALT"
    standin.press(cliff=0)
    assert kobuki.wait_for(lambda b: b.sensors is not None and b.sensors.cliff == 0, DEADLINE_S)
    assert loop.step(time.monotonic()).state == "HALT"  # cleared, but nobody resumed
    engage.resume(time.monotonic())
    assert kobuki.deadman_mode is DeadmanMode.ARMED
    assert loop.step(time.monotonic()).state == "BRING_UP"


def test_the_latch_is_recorded_for_replay_and_read_back_exactly() -> None:
    latched = BaseFeedback(received_at_s=3.5, stop_latched="wheel dropped (right)")
    assert feedback_as_json(latched)["stop_latched"] == "wheel dropped (right)"
    assert feedback_from_json(feedback_as_json(latched)) == latched
    assert "stop_latched" not in feedback_as_json(BaseFeedback(received_at_s=3.5))  # as before
    with pytest.raises(StepError, match="input.feedback.stop_latched = 5: expected a text"):
        feedback_from_json({**feedback_as_json(latched), "stop_latched": 5})
