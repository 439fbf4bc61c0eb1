"""KobukiBase, the dead-man process and `lanewarden base` over a pseudo-terminal stand-in base.

Real processes, real pyserial, real pty; no sleeps: every wait is on an event/queue with a
generous deadline. Latencies are measured in benchmarks/deadman_latency.py, not asserted here.
"""

from __future__ import annotations

import itertools
import json
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from lanewarden.actuation.base import STOP, VelocityCommand
from lanewarden.actuation.config import ActuationConfig
from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.errors import DeadmanTrippedError, KobukiLinkError
from lanewarden.actuation.kobuki_base import KobukiBase
from lanewarden.actuation.kobuki_commands import SoundSequence, encode_base_control
from lanewarden.cli import main
from lanewarden.run_outcome import LoopEnd, LoopEndKind, RunWatch, end_reason
from lanewarden.runner import _closed_link_end
from tests.actuation.kobuki_standin import STOP_PACKET, KobukiStandIn, ReceivedPacket
from tests.actuation.processes import ControlProcess, stderr_lines

PROJECT_ROOT = Path(__file__).resolve().parents[2]
DEADLINE_S = 5.0
MOVE = VelocityCommand(0.2, 0.0)


def _is_motion(packet: ReceivedPacket) -> bool:
    control = packet.base_control
    return control is not None and control != (0, 0)


def _one_line_error(err: str) -> str:
    lines = stderr_lines(err)
    assert len(lines) == 1, err
    assert lines[0].startswith("lanewarden: error: ") and "Traceback" not in err
    return lines[0]


# ---- the CLI ------------------------------------------------------------------------------------
def test_base_info(standin: KobukiStandIn, capsys: pytest.CaptureFixture[str]) -> None:
    standin.set_sensors(bumper=1, wheel_drop=2)
    assert main(["base", "info", "--port", standin.port]) == 0
    out = capsys.readouterr().out
    for expected in (f"port:             {standin.port}", "hardware version: 1.0.4",
                     "firmware version: 1.2.0", "UDID:             12345678-9ABCDEF0-0BADCAFE",
                     "battery:          16.2 V", "bumper:           right",
                     "cliff:            none", "wheel drop:       left", "feedback rate:"):
        assert expected in out


def test_base_info_json(standin: KobukiStandIn, capsys: pytest.CaptureFixture[str]) -> None:
    standin.set_sensors(cliff=6)
    assert main(["base", "info", "--port", standin.port, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["hardware_version"] == "1.0.4" and report["firmware_version"] == "1.2.0"
    assert report["udid"] == "12345678-9ABCDEF0-0BADCAFE"
    assert report["battery_v"] == 16.2
    assert report["cliff"] == ["left", "centre"] and report["bumper"] == []
    assert report["feedback_rate_hz"] > 0.0 and report["checksum_errors"] == 0
    # only stops ever went out
    assert {control for _, control in standin.base_controls()} == {(0, 0)}


def test_base_drive_ramps_up_then_stops(standin: KobukiStandIn,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["base", "drive", "--port", standin.port, "--linear", "0.1", "--angular", "0.5",
                 "--duration", "1.0"]) == 0
    assert "then stopped" in capsys.readouterr().out
    assert standin.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
    controls = [control for _, control in standin.base_controls()]
    # R = 200 mm, outer wheel (200 + 115) * 0.5 = 157.5 -> 157 mm/s
    assert controls.count((157, 200)) >= 5
    first_full = controls.index((157, 200))
    # The safety gate ramps the start (0.3 m/s^2, 3.5 rad/s^2 -> 0.1 m/s after ~0.33 s): slower
    # commands come first, never the full command at once.
    ramp = [control for control in controls[:first_full] if control != (0, 0)]
    assert ramp and all(0 < speed < 157 for speed, _ in ramp), ramp


def test_base_drive_stops_on_a_pressed_bumper_without_moving(
        standin: KobukiStandIn, capsys: pytest.CaptureFixture[str]) -> None:
    standin.set_sensors(bumper=4)
    assert main(["base", "drive", "--port", standin.port, "--linear", "0.1",
                 "--duration", "2"]) == 1
    line = _one_line_error(capsys.readouterr().err)
    assert "bumper pressed (left)" in line and standin.port in line
    assert {control for _, control in standin.base_controls()} == {(0, 0)}


@pytest.mark.parametrize(("flags", "named"), [
    (["--linear", "0.8", "--duration", "1"], "'--linear'"),
    (["--linear", "nan", "--duration", "1"], "'--linear'"),
    (["--linear", "0.1", "--angular", "-3.2", "--duration", "1"], "'--angular'"),
    (["--linear", "0.1", "--duration", "0"], "'--duration'"),
    (["--linear", "0.1", "--duration", "61"], "'--duration'"),
])
def test_base_drive_validates_flags_before_opening_anything(
        flags: list[str], named: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["base", "drive", "--port", "/dev/never-opened", *flags]) == 2
    line = _one_line_error(capsys.readouterr().err)
    assert named in line and "/dev/never-opened" not in line


def test_missing_port_is_one_line_naming_it(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    port = str(tmp_path / "ttyKobuki")
    assert main(["base", "info", "--port", port]) == 1
    line = _one_line_error(capsys.readouterr().err)
    assert port in line and "no such device" in line and "udev" in line


def test_silent_device_is_one_line_naming_it(capsys: pytest.CaptureFixture[str]) -> None:
    with KobukiStandIn(stream=False) as silent:
        assert main(["base", "info", "--port", silent.port]) == 1
    line = _one_line_error(capsys.readouterr().err)
    assert silent.port in line
    assert "no Kobuki sensor data (valid feedback packet) within 1 s" in line


def test_a_port_that_echoes_our_commands_is_not_a_kobuki(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # loop:// hands every byte written back: valid frames, but never the base's sensor stream.
    assert main(["base", "info", "--port", "loop://"]) == 1
    line = _one_line_error(capsys.readouterr().err)
    assert "loop://" in line and "no Kobuki sensor data" in line


def test_unplugged_while_driving_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    with KobukiStandIn(unplug_on_motion=True) as standin:
        assert main(["base", "drive", "--port", standin.port, "--linear", "0.1",
                     "--duration", "10"]) == 1
    line = _one_line_error(capsys.readouterr().err)
    assert standin.port in line and "serial link lost" in line


def test_ctrl_c_stops_base_drive(standin: KobukiStandIn) -> None:
    drive = subprocess.Popen(
        [sys.executable, "-m", "lanewarden", "base", "drive", "--port", standin.port,
         "--linear", "0.1", "--duration", "30"],
        cwd=PROJECT_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:  # a loaded machine can take 10 s and more to start two Pythons
        assert standin.wait_for(lambda pkts: any(map(_is_motion, pkts)), 6 * DEADLINE_S)
        drive.send_signal(signal.SIGINT)
        _, err = drive.communicate(timeout=3 * DEADLINE_S)
    finally:
        drive.kill()
    assert drive.returncode == 130
    assert _one_line_error(err) == "lanewarden: error: interrupted"
    assert standin.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)


# ---- KobukiBase ---------------------------------------------------------------------------------
@pytest.fixture
def kobuki(standin: KobukiStandIn) -> Iterator[KobukiBase]:
    with KobukiBase.open(standin.port) as base:
        yield base


def _wait_packets(base: KobukiBase, count: int) -> None:
    target = base.packets_received + count
    assert base.wait_for(lambda b: b.packets_received >= target, DEADLINE_S)


def test_versions_udid_sensors_and_health(kobuki: KobukiBase) -> None:
    assert kobuki.wait_for(lambda b: b.udid is not None and b.firmware_version is not None,
                           DEADLINE_S)
    assert (str(kobuki.hardware_version), str(kobuki.firmware_version)) == ("1.0.4", "1.2.0")
    assert str(kobuki.udid) == "12345678-9ABCDEF0-0BADCAFE"
    assert kobuki.battery_v == 16.2
    packet = kobuki.latest_packet
    assert packet.cliff_adc is not None and packet.cliff_adc.left == 2200
    assert packet.raw_gyro is not None and len(packet.raw_gyro.samples) == 2
    assert packet.gpio is not None and packet.gpio.analog_in == (10, 20, 30, 40)
    health = kobuki.link_health(time.monotonic())
    assert health.packets > 0 and health.checksum_errors == 0 and health.lost_reason is None
    assert health.deadman_mode is DeadmanMode.DISARMED  # nothing sent yet: not armed
    kobuki.send(STOP, time.monotonic())
    assert kobuki.wait_for(lambda b: b.deadman_mode is DeadmanMode.ARMED, DEADLINE_S)


def test_checksum_errors_are_counted_and_the_stream_survives() -> None:
    with KobukiStandIn(corrupt_every=3) as standin, KobukiBase.open(standin.port) as base:
        _wait_packets(base, 6)
        assert base.link_health(time.monotonic()).checksum_errors >= 2


def test_a_packet_repeating_its_time_stamp_is_no_fresh_feedback() -> None:
    # The control side's own rule, beside the dead-man's: a device replaying one packet (its
    # time stamp no longer advancing) must not keep the feedback fresh for the gate, which halts
    # on BASE_LINK_LOST once it is older than base_link_timeout_s. The injected clock counts
    # its calls, so each arrival has its own time.
    calls = itertools.count()
    with KobukiStandIn() as standin, KobukiBase.open(
            standin.port, clock=lambda: float(next(calls))) as base:
        _wait_packets(base, 2)
        streaming = base.feedback(0.0).received_at_s
        _wait_packets(base, 2)
        assert base.feedback(0.0).received_at_s != streaming  # fresh packets refresh it
        standin.replaying = True
        _wait_packets(base, 3)  # (the one in flight when it began is fresh)
        replayed_from = base.feedback(0.0).received_at_s
        _wait_packets(base, 5)
        assert base.feedback(0.0).received_at_s == replayed_from
        standin.replaying = False
        _wait_packets(base, 2)
        assert base.feedback(0.0).received_at_s != replayed_from  # stamped anew: fresh again


def test_unchanged_command_is_repeated_at_a_steady_rate(standin: KobukiStandIn) -> None:
    # The dead-man's own timeouts at their largest (1 s): this test is about the repetition, and
    # on a loaded machine (CI's) a send every 3 packets (~60 ms) could otherwise arrive after the
    # default 0.2 s heartbeat timeout, stopping the base and ramping it up again mid-count (the
    # timeouts have their own tests below).
    slow_machine = ActuationConfig(heartbeat_timeout_s=1.0, feedback_timeout_s=1.0)
    with KobukiBase.open(standin.port, config=slow_machine) as kobuki:
        sends = 0
        for _ in range(10):  # one send every 3 feedback packets (~60 ms)
            kobuki.send(MOVE, time.monotonic())
            sends += 1
            _wait_packets(kobuki, 3)
        kobuki.send(STOP, time.monotonic())
    # every motion packet is on the wire before the stop: wait for the stop, then count
    assert standin.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
    speeds = [control[0] for _, control in standin.base_controls() if control != (0, 0)]
    # the dead-man's envelope ramps the start (1 m/s^2: 20 mm/s per 20 ms packet, +-1 for the
    # protocol's whole mm/s), then holds
    first_full = speeds.index(200)
    ramp = speeds[:first_full + 1]
    assert all(0 < later - earlier <= 21 for earlier, later in zip(ramp, ramp[1:], strict=False))
    assert set(speeds[first_full:]) == {200}
    assert len(speeds[first_full:]) >= sends  # generous: ~3 per send at 50 Hz, minus the ramp


def test_stop_is_the_exact_stop_packet(standin: KobukiStandIn, kobuki: KobukiBase) -> None:
    kobuki.send(MOVE, time.monotonic())
    assert standin.wait_for(lambda pkts: any(map(_is_motion, pkts)), DEADLINE_S)
    mark = len(standin.snapshot())
    kobuki.send(STOP, time.monotonic())
    assert standin.wait_for(lambda pkts: any(p.packet == bytes.fromhex(
        "AA 55 06 01 04 00 00 00 00 03") for p in pkts[mark:]), DEADLINE_S)


def test_extra_commands_reach_the_wire_but_never_motion(standin: KobukiStandIn,
                                                         kobuki: KobukiBase) -> None:
    kobuki.play_sound_sequence(SoundSequence.BUTTON)
    assert standin.wait_for(lambda pkts: any(
        p.packet == bytes.fromhex("AA 55 03 04 01 03 05") for p in pkts), DEADLINE_S)
    with pytest.raises(ValueError, match="base control"):
        kobuki.send_extra(encode_base_control(100, 0))


def test_unplugging_the_pty_is_a_clear_error_not_a_hang(standin: KobukiStandIn,
                                                       kobuki: KobukiBase) -> None:
    kobuki.send(MOVE, time.monotonic())
    standin.unplug()
    assert kobuki.wait_for(lambda b: b.link_lost is not None, DEADLINE_S)
    with pytest.raises(KobukiLinkError) as info:
        kobuki.send(MOVE, time.monotonic())
    assert standin.port in str(info.value) and "serial link lost" in str(info.value)
    now = time.monotonic()
    feedback = kobuki.feedback(now)  # stale data, not an exception: the watchdog decides
    assert feedback.received_at_s is not None and feedback.received_at_s <= now
    assert not kobuki.link_health(now).alive
    kobuki.close()
    # the port was tried again for the stop, and that no stop went out is said plainly
    assert kobuki.link_lost is not None and kobuki.link_lost.endswith(
        "the base may still be driving its last command: switch it off"), kobuki.link_lost
    assert kobuki.stop_failed == kobuki.link_lost


@pytest.mark.parametrize("normal", [
    LoopEnd(LoopEndKind.CLIP, "end of the clip", 40),
    LoopEnd(LoopEndKind.OPERATOR, "operator stop (SIGINT)", 40),
    LoopEnd(LoopEndKind.DURATION, "--duration 2 s reached", 40),
])
def test_a_normal_end_whose_closing_stop_fails_is_a_safety_stop(
        standin: KobukiStandIn, kobuki: KobukiBase, normal: LoopEnd) -> None:
    """The runner's loop ended as it should (the clip ran out, the operator stopped it, its
    duration was reached) while the robot followed, but the device was gone before the closing
    stop: no stop reached the base, which may drive its last command. The run must end as a
    safety stop, exit 3, saying so; it had ended with exit 0 and its normal reason."""
    watch = RunWatch()
    for step in range(40):
        watch.observe("FOLLOW", None, step / 30, step / 30)
    assert end_reason(watch, normal).exit_code == 0  # the same end, its stop written
    kobuki.send(MOVE, time.monotonic())
    standin.unplug()
    assert kobuki.wait_for(lambda b: b.link_lost is not None, DEADLINE_S)
    kobuki.close()  # the closing stop: tried, not written
    end = end_reason(watch, _closed_link_end(kobuki, normal))
    assert end.exit_code == 3
    assert end.safety_stop is not None and end.safety_stop.startswith(
        f"BASE_LINK_LOST: {standin.port}: serial link lost"), end.safety_stop
    assert end.safety_stop.endswith("the base may still be driving its last command: switch it "
                                    "off"), end.safety_stop


def test_a_normal_end_whose_closing_stop_went_out_stays_normal(kobuki: KobukiBase) -> None:
    watch = RunWatch()
    for step in range(40):
        watch.observe("FOLLOW", None, step / 30, step / 30)
    kobuki.send(MOVE, time.monotonic())
    kobuki.close()
    clip_end = LoopEnd(LoopEndKind.CLIP, "end of the clip", 40)
    assert _closed_link_end(kobuki, clip_end) == clip_end
    assert end_reason(watch, clip_end).exit_code == 0


def test_a_base_that_comes_back_at_its_path_gets_the_stop(tmp_path: Path) -> None:
    """An attacker's review: the device vanished (a USB glitch) while the robot drove and came
    back at its path at once; nothing reopened it, no stop was written, and the run said halted.
    The control side now tries the port again once the dead-man has lost it."""
    port = tmp_path / "kobuki"  # as udev's /dev/kobuki: a link to the device of the moment
    with KobukiStandIn() as first:
        port.symlink_to(first.port)
        with KobukiStandIn() as second, KobukiBase.open(str(port)) as kobuki:
            kobuki.send(MOVE, time.monotonic())
            assert first.wait_for(lambda pkts: any(map(_is_motion, pkts)), DEADLINE_S)
            port.unlink()
            port.symlink_to(second.port)  # back at its path, another device node
            first.unplug()
            assert second.wait_for(lambda pkts: any(p.packet == STOP_PACKET for p in pkts),
                                   DEADLINE_S), "the stop reached the device that came back"
            assert kobuki.wait_for(lambda b: b.link_lost is not None
                                   and "a stop was written to the port directly" in b.link_lost,
                                   DEADLINE_S), kobuki.link_lost
            assert "serial link lost" in str(kobuki.link_lost)
            assert not any(map(_is_motion, second.snapshot()))
        assert kobuki.stop_failed is None


def test_a_quiet_caller_trips_the_deadman_and_must_rearm(standin: KobukiStandIn,
                                                          kobuki: KobukiBase) -> None:
    kobuki.send(MOVE, time.monotonic())
    # no more sends: the heartbeat timeout (0.2 s) trips the dead-man
    assert kobuki.wait_for(lambda b: b.deadman_mode is DeadmanMode.TRIPPED, DEADLINE_S)
    assert "no heartbeat" in kobuki.link_health(time.monotonic()).deadman_reason
    assert standin.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
    with pytest.raises(DeadmanTrippedError, match="ignored until rearm"):
        kobuki.send(MOVE, time.monotonic())
    kobuki.send(STOP, time.monotonic())  # stopping is always fine
    kobuki.rearm(time.monotonic())
    assert kobuki.wait_for(lambda b: b.deadman_mode is DeadmanMode.ARMED, DEADLINE_S)
    mark = len(standin.snapshot())
    kobuki.send(MOVE, time.monotonic())
    assert standin.wait_for(lambda pkts: any(map(_is_motion, pkts[mark:])), DEADLINE_S)
    kobuki.send(STOP, time.monotonic())


def test_second_opener_is_told_the_port_is_busy(standin: KobukiStandIn,
                                                kobuki: KobukiBase) -> None:
    with pytest.raises(KobukiLinkError, match="in use by another process"):
        KobukiBase.open(standin.port)
    kobuki.send(STOP, time.monotonic())  # the first owner is unaffected


@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGQUIT, signal.SIGINT, signal.SIGHUP])
def test_a_stop_signal_to_the_deadman_stops_the_base(standin: KobukiStandIn, kobuki: KobukiBase,
                                                     how: signal.Signals) -> None:
    kobuki.send(MOVE, time.monotonic())
    assert standin.wait_for(lambda pkts: any(map(_is_motion, pkts)), DEADLINE_S)
    os.kill(kobuki.deadman_pid, how)
    assert kobuki.wait_for(lambda b: b.link_lost is not None, DEADLINE_S)
    assert f"stopped by signal {how.name}" in kobuki.link_health(time.monotonic()).deadman_reason
    assert standin.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
    with pytest.raises(KobukiLinkError, match="dead-man process exited"):
        kobuki.send(MOVE, time.monotonic())


# ---- the control process dies or freezes --------------------------------------------------------
def _exits_within(pid: int, timeout_s: float) -> bool:
    """Wait (pidfd, no polling) for a process that is not our child to exit."""
    try:
        pidfd = os.pidfd_open(pid)
    except ProcessLookupError:
        return True
    try:
        return bool(select.select([pidfd], [], [], timeout_s)[0])
    finally:
        os.close(pidfd)


@pytest.fixture
def control(standin: KobukiStandIn) -> Iterator[ControlProcess]:
    process = ControlProcess(standin.port)
    try:
        yield process
    finally:
        process.close()


def test_sigkill_of_the_control_process_stops_the_base(standin: KobukiStandIn,
                                                       control: ControlProcess) -> None:
    assert standin.wait_for(lambda pkts: any(map(_is_motion, pkts)), 3 * DEADLINE_S)
    killed_at = time.monotonic()
    os.kill(control.process.pid, signal.SIGKILL)
    assert standin.wait_for(lambda pkts: any(p.arrival_s >= killed_at and p.packet == STOP_PACKET
                                             for p in pkts), DEADLINE_S)
    # the orphaned dead-man keeps stopping for a moment, then exits; nothing moves again
    assert _exits_within(control.deadman_pid, DEADLINE_S)
    after = [p for p in standin.snapshot() if p.arrival_s >= killed_at]
    first_stop = next(i for i, p in enumerate(after) if p.packet == STOP_PACKET)
    assert not any(map(_is_motion, after[first_stop:]))


def test_frozen_control_process_trips_and_stays_stopped_until_rearmed(
        standin: KobukiStandIn, control: ControlProcess) -> None:
    assert standin.wait_for(lambda pkts: any(map(_is_motion, pkts)), 3 * DEADLINE_S)
    frozen_at = time.monotonic()
    os.kill(control.process.pid, signal.SIGSTOP)
    assert standin.wait_for(lambda pkts: any(p.arrival_s >= frozen_at and p.packet == STOP_PACKET
                                             for p in pkts), DEADLINE_S)
    os.kill(control.process.pid, signal.SIGCONT)
    # it runs again and sends commands again...
    assert "no heartbeat for " in control.expect("tripped ")
    mark = len(standin.snapshot())
    assert standin.wait_for(lambda pkts: len(pkts) >= mark + 10, DEADLINE_S)
    assert not any(map(_is_motion, standin.snapshot()[mark:]))  # ...which are ignored
    control.say("rearm")
    assert control.expect("rearmed") == ""
    mark = len(standin.snapshot())
    assert standin.wait_for(lambda pkts: any(map(_is_motion, pkts[mark:])), DEADLINE_S)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGQUIT])
def test_a_stop_signal_ends_base_drives_wait_at_once(
        sig: signal.Signals, standin: KobukiStandIn, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The signal comes at the start of a 50 ms tick's wait: the wait asks, and knows at once
    (it had slept to the next tick, while the dead-man repeated the motion command)."""
    from lanewarden.commands import base as base_command
    from tests.signal_probe import signalling_ticker

    seen: list[bool | None] = []
    monkeypatch.setattr(base_command, "Ticker", signalling_ticker(sig, 2, seen))
    code = main(["base", "drive", "--port", standin.port, "--linear", "0.1",
                 "--duration", "30"])
    assert seen == [True]
    assert code == 130, capsys.readouterr().err
    assert standin.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
