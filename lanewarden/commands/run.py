"""`lanewarden run`: follow the lane under the supervisor, on the robot or on the bench."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from lanewarden.bases import BASE_KINDS, DEFAULT_BASE
from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import CAMERA_EXPECTED, FiniteRange, PathFlag
from lanewarden.config import load_config
from lanewarden.errors import UsageError
from lanewarden.supervisor.controllers import CONTROLLERS, DEFAULT_CONTROLLER

if TYPE_CHECKING:
    from lanewarden.runner import RunSummary

RUN_EXAMPLES = """\b
Examples (no robot: a camera clip from the simulator on a simulated base, watched at
http://127.0.0.1:8080/; the live camera with nothing sent; the robot; a recorded run replayed):
  lanewarden sim --scenario lane-ends --camera-out clip.mp4
  lanewarden run --camera clip.mp4 --calibration clip.calibration.yaml --base sim --view 8080
  lanewarden run --camera 0 --base none
  lanewarden run --camera 0 --calibration camera.yaml
  lanewarden replay runs/2026-11-05T14-03-12Z --check
"""
#: Longest `--duration` of one run (a day); without it the run lasts until stopped.
MAX_RUN_DURATION_S = 86_400.0


@click.command("run", epilog=RUN_EXAMPLES)
@click.option("--camera", default="0", show_default=True, metavar="TEXT",
              type=PathFlag(CAMERA_EXPECTED, readable=False),
              help="Camera index, device path, stream URL, video file, or image sequence (a "
              "folder, a glob like 'shots/*.png', or 'dir/frame_%03d.png'). A file or sequence is "
              "played at its frame rate; its end ends the run.")
@click.option("--base", "base_kind", type=click.Choice(BASE_KINDS), default=DEFAULT_BASE,
              show_default=True, help="kobuki: the robot; sim: a simulated Kobuki driven by the "
              "very commands the wheels would get; none: send nothing, show what would be sent.")
@click.option("--port", default=None,
              help="Kobuki serial port (default: actuation.port, then /dev/kobuki, /dev/ttyUSB0).")
@click.option("--calibration", "calibration_path",
              type=PathFlag("a calibration file", dir_okay=False, exists=True), default=None,
              help="Camera calibration (OpenCV YAML from `lanewarden calibrate`).")
@click.option("--assume-camera", "assume_camera", is_flag=True,
              help="Let --base kobuki drive on an assumed camera: with no --calibration the "
              "simulator's default camera, with a calibration that has no ground pose the "
              "simulator's mount (refused without this flag: tapes and seams are then measured "
              "through a camera that may not be yours).")
@click.option("--controller", type=click.Choice(list(CONTROLLERS)), default=DEFAULT_CONTROLLER,
              show_default=True, help="supervised, or the lecture's baseline (never halts on lane "
              "loss: for comparison on a safe track only).")
@click.option("--record", "record_dir", type=PathFlag("a folder", file_okay=False, path_type=Path),
              default=None, help="Record the run into this new folder (default: runs/<UTC "
              "time>/; never overwritten).")
@click.option("--record-gray", is_flag=True,
              help="Record the camera's own frames (their gray version, lossless PNG) instead of "
              "what perception consumed (gray, undistorted, blurred): about 1.7x the disk; "
              "replay can then try another blur or calibration (not another perception.gray: "
              "that needs --record-lossy's colour).")
@click.option("--record-lossy", is_flag=True,
              help="Record the camera's frames as colour JPEG instead of lossless PNG (about half "
              "the default's disk, for long runs; the replay is then not exact).")
@click.option("--view", "view", metavar="[HOST:]PORT", default=None,
              help="Serve the live page on this port (127.0.0.1 unless a host is given, e.g. "
              "0.0.0.0:8080 to watch from another machine).")
@click.option("--duration", "duration_s", default=None,
              type=FiniteRange(0.0, MAX_RUN_DURATION_S, "s", low_open=True),
              help="Stop after this many seconds (default: until Ctrl-C).")
@config_option
def run_command(camera: str, base_kind: str, port: str | None, calibration_path: str | None,
                assume_camera: bool, controller: str, record_dir: Path | None,
                record_gray: bool, record_lossy: bool, view: str | None,
                duration_s: float | None, config_path: str | None) -> int:
    """Follow the lane under the supervisor, on the robot or on the bench. Every check (config,
    calibration, camera, recording folder, base link) passes before anything moves; then the
    command is the start: the robot moves as soon as it sees a confident lane, no key needed.
    Ctrl-C, SIGTERM, SIGQUIT or SIGHUP stop the robot and end the run; Ctrl-Z stops the robot,
    then suspends (after `fg` it stays halted); a crash leaves the dead-man holding stop. Keys
    (after a stop): s start, space stop, r resume; Kobuki buttons: B0 start/resume, B1 stop.
    Every run is recorded (see `lanewarden replay`). Exit 0 for a normal end (operator stop,
    --duration, end of a clip), 3 for a safety stop (its reason also on stderr)."""
    from lanewarden.run_mcap import CAMERA_GRAY, CAMERA_JPEG, PERCEPTION_INPUT
    from lanewarden.runner import run_robot  # the robot stack loads only when used

    if record_gray and record_lossy:
        raise UsageError("--record-gray and --record-lossy: choose one (the camera's gray frames "
                         "lossless, or its colour frames as JPEG)")
    record_image = CAMERA_GRAY if record_gray else CAMERA_JPEG if record_lossy else PERCEPTION_INPUT
    config = load_config(config_path)
    summary = run_robot(config, camera=camera, port=port, calibration_path=calibration_path,
                        controller_name=controller, duration_s=duration_s, base_kind=base_kind,
                        record=record_dir, record_image=record_image, view=view,
                        meta={"config_file": config_path}, assume_camera=assume_camera)
    for line in summary.lines:
        click.echo(line)
    click.echo(summary_line(summary))
    end = summary.end
    if end.safety_stop is not None:
        click.echo(f"lanewarden: {end.text}", err=True)
    return end.exit_code


def summary_line(summary: RunSummary) -> str:
    """The run's last line on stdout: why it ended, how long, the state it ended in, log."""
    end = summary.end
    why = (f"run ended by a {end.text}" if end.safety_stop is not None
           else f"run ended: {end.text}")
    # the steps before the runner's closing stop: summary.json's and replay's counts include it
    return (f"{why}; after {summary.duration_s:.1f} s and {summary.steps} steps before the "
            f"closing stop; state before "
            f"the final stop: {end.state_text}; log: {summary.log_path}")


def commands() -> list[click.Command]:
    return [run_command]
