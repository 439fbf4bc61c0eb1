"""`lanewarden run`: drive the real robot with the camera, under the supervisor."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import FiniteRange
from lanewarden.config import load_config
from lanewarden.supervisor.controllers import CONTROLLERS, DEFAULT_CONTROLLER

if TYPE_CHECKING:
    from lanewarden.runner import RunSummary

#: Longest `--duration` of one run (a day); without it the run lasts until stopped.
MAX_RUN_DURATION_S = 86_400.0


@click.command("run")
@click.option("--camera", default="0", show_default=True,
              help="Camera index, device path, video file or stream URL.")
@click.option("--port", default=None,
              help="Kobuki serial port (default: actuation.port, then /dev/kobuki, /dev/ttyUSB0).")
@click.option("--calibration", "calibration_path", type=click.Path(dir_okay=False), default=None,
              help="Camera calibration (OpenCV YAML from `lanewarden calibrate`).")
@click.option("--controller", type=click.Choice(list(CONTROLLERS)), default=DEFAULT_CONTROLLER,
              show_default=True, help="supervised, or the lecture's baseline (never halts on lane "
              "loss: for comparison on a safe track only).")
@click.option("--log", "log_path", type=click.Path(dir_okay=False, path_type=Path),
              default=Path("run.jsonl"), show_default=True, help="Per-frame record (JSON lines).")
@click.option("--duration", "duration_s", default=None,
              type=FiniteRange(0.0, MAX_RUN_DURATION_S, "s", low_open=True),
              help="Stop after this many seconds (default: until Ctrl-C).")
@config_option
def run_command(camera: str, port: str | None, calibration_path: str | None, controller: str,
                log_path: Path, duration_s: float | None, config_path: str | None) -> int:
    """Follow the lane on the robot. Ctrl-C, SIGTERM or SIGQUIT stop the robot and end the run;
    Ctrl-Z stops the robot, then suspends (after `fg` it stays halted); a crash leaves the
    dead-man holding stop. Every check (config, calibration, camera, base link) passes before
    anything moves. Exit 0 for a normal end (operator stop, --duration, end of a clip), 3 for a
    safety stop (its reason also on stderr)."""
    from lanewarden.runner import run_robot  # the robot stack loads only when used

    config = load_config(config_path)
    summary = run_robot(config, camera=camera, port=port, calibration_path=calibration_path,
                        controller_name=controller, log_path=log_path, duration_s=duration_s)
    click.echo(summary_line(summary))
    outcome = summary.outcome
    if outcome.safety_stop is not None:
        click.echo(f"lanewarden: safety stop: {outcome.safety_stop}", err=True)
    return outcome.exit_code


def summary_line(summary: RunSummary) -> str:
    """The run's last line on stdout: why it ended, how long, the state before the stop, log."""
    outcome = summary.outcome
    if outcome.safety_stop is not None:
        why = f"run ended by a safety stop: {outcome.safety_stop}"
    else:
        why = f"run ended: {outcome.ended_by}"
    state = summary.final_state
    if state == "HALT" and summary.halt_reason:
        state = f"HALT ({summary.halt_reason})"
    return (f"{why}; after {summary.duration_s:.1f} s and {summary.steps} steps; state before "
            f"the final stop: {state}; log: {summary.log_path}")


def commands() -> list[click.Command]:
    return [run_command]
