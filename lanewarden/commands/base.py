"""`lanewarden base info` and `lanewarden base drive`: bringing up a real Kobuki.

A thin shell over `actuation.kobuki_base.KobukiBase`. `drive` has no camera and no supervisor
state machine (it is a bring-up tool), but it steps the same `ControlLoop` as `run`, on the same
real-time `Ticker` (lanewarden/ticker.py: its clock is the only one it reads), with the same
SafetyGate as every controller's, in bring-up mode (lanewarden/assembly.py `build_bring_up_loop`):
ramped up, capped at the Kobuki's limits its flags are validated against, halted on bumper/cliff/
wheel drop, the dead-man's own latch and a lost link (feedback older than
`supervisor.base_link_timeout_s`: a silent base or a frozen dead-man; a failed send). Starting
it is the operator's explicit start (`KobukiBase.resume`). It always stops on exit:
Ctrl-C, SIGTERM, SIGQUIT and SIGHUP stop it and end it (exit 130); Ctrl-Z stops the base first,
then suspends, and the drive does not resume after SIGCONT (exit 130). Never talks to the serial
port itself.
"""

from __future__ import annotations

import json
import math
import os
import signal
from pathlib import Path
from typing import Any

import click

from lanewarden.actuation.base import STOP, BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.actuation.kobuki_base import KobukiBase
from lanewarden.actuation.kobuki_feedback import (
    BUMPER_SIDES,
    CLIFF_SIDES,
    WHEEL_DROP_SIDES,
    side_names,
)
from lanewarden.assembly import build_bring_up_loop
from lanewarden.commands.command_group import CommandGroup
from lanewarden.commands.config_cmd import config_option
from lanewarden.config import load_config
from lanewarden.errors import EXIT_INTERRUPTED
from lanewarden.stop_signals import SignalRequests, signal_requests, suspend
from lanewarden.supervisor.clock import MonotonicClock
from lanewarden.ticker import Ticker

#: How long `info` counts feedback packets to measure the stream rate.
RATE_WINDOW_S = 1.0
#: How long `info` waits for the versions/UDID after the rate window.
EXTRA_WAIT_S = 0.5
#: `drive` re-sends its command this often (well inside the dead-man's heartbeat timeout).
DRIVE_PERIOD_S = 0.05
MAX_DRIVE_DURATION_S = 60.0

PORT_HELP = "serial port or pyserial URL (default: config, then /dev/kobuki, then /dev/ttyUSB0)"
#: What the USB serial adapter's latency timer should be: at the FTDI default of 16 ms, the
#: Kobuki's 50 Hz packets arrive in bursts and are the known cause of malformed packets.
LATENCY_TIMER_GOAL_MS = 1
UDEV_RULE_DOC = "docs/udev/99-kobuki.rules"


def usb_latency_timer(port: str, sys_root: Path = Path("/sys")) -> tuple[int | None, Path]:
    """The latency timer (ms) Linux exposes for `port`'s USB serial adapter, and where; None when
    it is not exposed (not a USB serial adapter, a pty, a URL) or cannot be read."""
    tty = Path(os.path.realpath(port)).name  # /dev/kobuki -> ttyUSB0
    path = sys_root / "bus" / "usb-serial" / "devices" / tty / "latency_timer"
    try:
        return int(path.read_text().strip()), path
    except (OSError, ValueError):
        return None, path


def latency_timer_text(value: int | None, path: Path) -> str:
    if value is None:
        return "not exposed for this port (not a USB serial adapter)"
    if value <= LATENCY_TIMER_GOAL_MS:
        return f"{value} ms (good)"
    return (f"{value} ms: set it to {LATENCY_TIMER_GOAL_MS} ms (16 ms causes malformed Kobuki "
            f"packets): install the udev rule {UDEV_RULE_DOC}, or for now: "
            f"echo {LATENCY_TIMER_GOAL_MS} | sudo tee {path}")


BUTTON_NAMES = ((1, "B0"), (2, "B1"), (4, "B2"))


@click.group("base", cls=CommandGroup)
def base_group() -> None:
    """Talk to a real Kobuki base over its serial port."""


@base_group.command("info")
@click.option("--port", default=None, help=PORT_HELP)
@click.option("--json", "as_json", is_flag=True, help="print one JSON object")
@config_option
def info(port: str | None, as_json: bool, config_path: str | None) -> None:
    """Show versions, UDID, battery, hazards, the feedback rate and the USB adapter's latency
    timer."""
    config = load_config(config_path).actuation
    clock = MonotonicClock()  # only for the feedback rate: nothing here decides a motion
    with KobukiBase.open(port, clock=clock.now, config=config) as base:
        start_packets, start_s = base.packets_received, clock.now()
        lost = base.wait_for(lambda b: b.link_lost is not None, RATE_WINDOW_S)
        packets, elapsed_s = base.packets_received - start_packets, clock.now() - start_s
        if lost:
            raise ActuationError(base.link_lost or "link lost")
        base.wait_for(lambda b: None not in (b.hardware_version, b.firmware_version, b.udid),
                      EXTRA_WAIT_S)
        now = clock.now()
        report = _info_report(base, base.feedback(now), packets / elapsed_s, now)
    if as_json:
        click.echo(json.dumps(report))
        return
    lines = [
        ("port", report["port"]),
        ("hardware version", report["hardware_version"] or "unknown (no answer)"),
        ("firmware version", report["firmware_version"] or "unknown (no answer)"),
        ("UDID", report["udid"] or "unknown (no answer)"),
        ("battery", "unknown" if report["battery_v"] is None else f"{report['battery_v']:.1f} V"),
        ("bumper", ", ".join(report["bumper"]) or "none"),
        ("cliff", ", ".join(report["cliff"]) or "none"),
        ("wheel drop", ", ".join(report["wheel_drop"]) or "none"),
        ("buttons", ", ".join(report["buttons"]) or "none"),
        ("feedback rate", f"{report['feedback_rate_hz']:.1f} Hz "
                          f"({report['checksum_errors']} checksum errors)"),
        ("latency timer", latency_timer_text(report["latency_timer_ms"],
                                             Path(report["latency_timer_path"]))),
    ]
    for name, value in lines:
        click.echo(f"{name + ':':18}{value}")


def _info_report(base: KobukiBase, feedback: BaseFeedback, rate_hz: float,
                 now: float) -> dict[str, Any]:
    health = base.link_health(now)
    latency_ms, latency_path = usb_latency_timer(base.port)
    return {
        "port": base.port,
        "hardware_version": str(base.hardware_version) if base.hardware_version else None,
        "firmware_version": str(base.firmware_version) if base.firmware_version else None,
        "udid": str(base.udid) if base.udid else None,
        "battery_v": feedback.battery_v,
        "bumper": side_names(feedback.bumper, BUMPER_SIDES),
        "cliff": side_names(feedback.cliff, CLIFF_SIDES),
        "wheel_drop": side_names(feedback.wheel_drop, WHEEL_DROP_SIDES),
        "buttons": side_names(feedback.buttons, BUTTON_NAMES),
        "feedback_rate_hz": round(rate_hz, 1),
        "checksum_errors": health.checksum_errors,
        "low_latency": health.low_latency,
        "latency_timer_ms": latency_ms,
        "latency_timer_path": str(latency_path),
    }


def _check_range(flag: str, value: float, limit: float, unit: str) -> None:
    if not math.isfinite(value) or abs(value) > limit:
        raise click.BadParameter(
            f"{value:g} {unit}: expected a number within -{limit:g}..{limit:g} {unit} "
            "(the Kobuki's limits, see actuation.max_* in the config)",
            param_hint=f"'{flag}'")


class DriveInterrupted(click.ClickException):
    """A signal ended the drive (after the base was stopped)."""

    exit_code = EXIT_INTERRUPTED


def _act_on_signals(base: KobukiBase, requests: SignalRequests, now: float) -> None:
    """Stop signals end the drive; Ctrl-Z stops the base, suspends, and ends it after SIGCONT."""
    if requests.suspend:
        base.hold_stopped(now)  # stop on the wire and held by the dead-man before we freeze
        suspend()
        raise DriveInterrupted("interrupted (SIGTSTP): the base was stopped before suspending; "
                               "the drive does not resume")
    if requests.stop is signal.SIGINT:
        raise KeyboardInterrupt
    if requests.stop is not None:
        raise DriveInterrupted(f"interrupted ({requests.stop.name})")


@base_group.command("drive")
@click.option("--port", default=None, help=PORT_HELP)
@click.option("--linear", "linear_m_s", type=float, required=True, help="forward speed, m/s")
@click.option("--angular", "angular_rad_s", type=float, default=0.0, show_default=True,
              help="turn rate, rad/s (counter-clockwise +)")
@click.option("--duration", "duration_s", type=float, required=True, help="seconds, then stop")
@config_option
def drive(port: str | None, linear_m_s: float, angular_rad_s: float, duration_s: float,
          config_path: str | None) -> None:
    """Drive at a constant velocity, then stop (Ctrl-C stops at once)."""
    full_config = load_config(config_path)
    config = full_config.actuation
    _check_range("--linear", linear_m_s, config.max_linear_m_s, "m/s")
    _check_range("--angular", angular_rad_s, config.max_angular_rad_s, "rad/s")
    if not (math.isfinite(duration_s) and 0.0 < duration_s <= MAX_DRIVE_DURATION_S):
        raise click.BadParameter(f"{duration_s:g} s: expected 0 < S <= {MAX_DRIVE_DURATION_S:g}",
                                 param_hint="'--duration'")
    ticks = Ticker(DRIVE_PERIOD_S)
    with (KobukiBase.open(port, clock=ticks.now, config=config, request_versions=False) as base,
          signal_requests() as requests):
        # signals and every error leave through `with`: close() stops the base
        warning = base.priority_warning()
        if warning is not None:
            click.echo(f"lanewarden: warning: {warning}", err=True)
        loop = build_bring_up_loop(full_config, VelocityCommand(linear_m_s, angular_rad_s), base)
        # this command is the operator's explicit start: it may release the dead-man's own latch
        base.resume(ticks.now())
        start_s = now = ticks.restart()
        loop.start(now)
        while now - start_s < duration_s:
            _act_on_signals(base, requests, now)
            record = loop.step(now)
            if record.state == "HALT":
                raise ActuationError(f"{base.port}: stopped after {now - start_s:.2f} s: "
                                     f"{record.halt_reason}")
            # a signal ends the wait at once
            ticks.wait(until_s=start_s + duration_s, interrupted=requests.pending)
            now = ticks.now()
        base.send(STOP, now)
        pose = base.feedback(now).odometry
    click.echo(f"drove {linear_m_s:g} m/s, {angular_rad_s:g} rad/s for {duration_s:g} s, "
               f"then stopped; odometry x {pose.x_m:.3f} m, y {pose.y_m:.3f} m, "
               f"heading {math.degrees(pose.theta_rad):.1f} deg")


def commands() -> list[click.Command]:
    return [base_group]
