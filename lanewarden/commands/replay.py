"""`lanewarden replay SOURCE`: perception and the supervisor on recorded frames, with the same
outputs as `sim`; for a recorded run, a step-by-step comparison with the recording.

A thin shell over `lanewarden.replay_sources`, `lanewarden.replay` and
`lanewarden.replay_outputs`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import PathFlag
from lanewarden.errors import InputFileError, QualityGateError, UsageError
from lanewarden.scenarios.before_halt import halt_line
from lanewarden.supervisor.controllers import CONTROLLERS, DEFAULT_CONTROLLER
from lanewarden.wording import counted

if TYPE_CHECKING:
    from lanewarden.replay import ReplaySource

#: What SOURCE is, for an empty one.
SOURCE_EXPECTED = "a run folder, a ROS 2 bag, a video file, a folder or glob of frames or a tub"

REPLAY_EXAMPLES = """\b
Examples:
  lanewarden replay runs/2026-11-05T14-03-12Z --check
  lanewarden replay clip.mp4 --out out/clip
  lanewarden replay my_bag/ --topic /camera/image_raw/compressed
  lanewarden replay my-tub/ --config track.yaml --calibration tub-camera.yaml
"""


@click.command("replay", epilog=REPLAY_EXAMPLES)
@click.argument("source", type=PathFlag(SOURCE_EXPECTED, readable=False))
@click.option("--out", "out_dir", type=PathFlag("a folder", file_okay=False),
              default=None, help="Output directory (default: lanewarden-out/replay-<source name>).")
@config_option
@click.option("--calibration", "calibration_path",
              type=PathFlag("a calibration file", dir_okay=False, exists=True), default=None,
              help="Camera calibration (default: the run folder's own, else none).")
@click.option("--controller", type=click.Choice(list(CONTROLLERS)), default=None,
              help=f"Who drives (default: the recorded run's, else {DEFAULT_CONTROLLER}).")
@click.option("--topic", default=None,
              help="The image topic of a ROS 2 bag (sensor_msgs/msg/Image or CompressedImage); "
              "needed when the bag has several.")
@click.option("--no-video", is_flag=True, help="Skip video.mp4 (faster).")
@click.option("--check", is_flag=True,
              help="Exit with code 2 when a replayed step differs from the recorded run (or the "
              "recording cannot be replayed exactly).")
def replay_command(source: str, out_dir: str | None, config_path: str | None,
                   calibration_path: str | None, controller: str | None, topic: str | None,
                   no_video: bool, check: bool) -> None:
    """Replay SOURCE (a run folder or its run.mcap, a ROS 2 bag: .mcap, .db3 or a rosbag2
    folder, a video file, a folder or glob of camera frames, or a Donkeycar tub) on a fake clock
    at its recorded timestamps: OUT/{video.mp4, poster.jpg, plot.png, metrics.json, run.jsonl,
    report.html}, as `sim` writes them. A recorded run replays with its own recorded config and
    calibration unless --config/--calibration say otherwise, and every step is compared."""
    from lanewarden.commands.output_folders import (
        create_output_folder,
        interrupted_in,
        refuse_a_recording_folder,
        refuse_another_commands_folder,
    )
    from lanewarden.config import load_config
    from lanewarden.perception.detector import too_small
    from lanewarden.replay import check_preparation
    from lanewarden.replay_outputs import ReplayRequest, run_replay
    from lanewarden.replay_sources import (
        KIND_WORDS,
        frame_indices,
        open_replay_source,
        replay_config,
        usable_calibration,
    )
    from lanewarden.scenarios.camera_clip import clip_calibration_hint

    if out_dir is not None:
        refuse_a_recording_folder(Path(out_dir))  # before the source is read
        refuse_another_commands_folder(Path(out_dir), "run")
        _refuse_the_source_folder(Path(out_dir), source)
    given = load_config(config_path)
    replay_source = open_replay_source(source, 1.0 / given.supervisor.camera_period_s,
                                       topic=topic,
                                       max_pixels=given.perception.max_image_pixels)
    if check and replay_source.kind != "run":  # before the work (it had come after the replay)
        raise UsageError(f"--check: {source} is {KIND_WORDS[replay_source.kind]}, not a "
                         "recorded run: there is nothing to compare with")
    config = replay_config(replay_source, config_path)
    # checked as run checks it (a NaN focal length had been a ValueError traceback here, a NaN
    # distortion a silent replay)
    calibration = usable_calibration(calibration_path, replay_source.calibration,
                                     config.calibration,
                                     f"SOURCE '{source}': the recording's calibration")
    check_preparation(replay_source, config, calibration, config_path=config_path,
                      calibration_path=calibration_path)  # before any output is written
    if calibration is None and (beside := clip_calibration_hint(source)):
        # a sim clip replayed without the calibration beside it drove on past the tape's end,
        # where with it the replay halted LANE_LOST (a new user's walk-through), as `run` warns
        click.echo(f"lanewarden: warning: no --calibration{beside}", err=True)
    chosen = controller or replay_source.controller or DEFAULT_CONTROLLER
    if chosen not in CONTROLLERS:
        chosen = DEFAULT_CONTROLLER
    first = replay_source.frames.image(0)
    size = None if first is None else (first.shape[1], first.shape[0])
    if size is not None and (small := too_small(*size)):  # before any output is written
        raise InputFileError(f"SOURCE '{source}': {_frame_names(replay_source, [0])}: {small}")
    out = Path(out_dir) if out_dir else Path("lanewarden-out") / f"replay-{replay_source.name}"
    # a FIFO, a file or another command's outputs there are refused before the work, as by `sim`
    create_output_folder(out, writes="run")
    # which ground model perception sees the frames through, as `run` and `detect` say it (a
    # tub replayed without its camera's description is seen through the default camera)
    if size is not None:
        from lanewarden.assembly import build_stack

        detector = build_stack(config, controller=chosen, calibration=calibration,
                               image_size=size).detector
        named = calibration_path or ("the recording's calibration" if calibration else None)
        click.echo(detector.describe_ground(named, size))
    try:
        metrics = run_replay(ReplayRequest(replay_source, config, calibration, chosen, out,
                                           video=not no_video))
    except KeyboardInterrupt:
        raise interrupted_in(out) from None
    click.echo(f"{replay_source.name} ({replay_source.kind}, config: "
               f"{replay_source.config_origin}): {counted(metrics['steps'], 'step')}, "
               f"{counted(metrics['frames'], 'frame')}, {metrics['sim_time_s']} s replayed in "
               f"{metrics['wall_time_s']} s")
    never = metrics["states_visited"] == ["HALT"]
    reason = metrics.get("halt_reason")
    if never:
        # the robot never left HALT: its last halt reason is what held it there, not a halt
        # (a replay of a tub had read "final state HALT (LANE_DEPARTURE: ...)" for a robot that
        # never moved)
        click.echo("  states visited: HALT; never engaged"
                   + (f" (held by {reason})" if reason else ""))
    else:
        click.echo(f"  states visited: {', '.join(metrics['states_visited'])}; final state "
                   f"{metrics['final_state']}" + (f" ({reason})" if reason else ""))
    # what ended the replay, as metrics.json, the plot and the report say it
    click.echo(f"  ended: {metrics['end_reason']}{' (never engaged)' if never else ''}")
    if line := halt_line(metrics.get("before_halt")):
        click.echo(line)
    if replay_source.kind == "bag":
        click.echo(f"  topic {replay_source.meta['topic']}, timed by its "
                   f"{replay_source.meta['times']}")
    if replay_source.kind == "run":
        if metrics["reproduced"]:
            click.echo(f"  reproduced: all {metrics['compared_steps']} steps match the recording "
                       "(state, events, command)")
        else:
            click.echo(f"  DIVERGES at {metrics['first_divergence']['text']} "
                       f"({metrics['divergent_steps']} steps differ)")
        if not metrics["exact_input"] and not metrics["incomplete"]:
            why = [f"{metrics['frames_missing']} frames missing"]
            if metrics["frames_undecoded"]:
                why.append(f"{len(metrics['frames_undecoded'])} undecodable")
            if not replay_source.meta.get("lossless"):
                why.append("lossy frames")
            click.echo(f"  the recording is not exact ({', '.join(why)}): the replay cannot "
                       "be exact")
    for why in metrics["incomplete"]:
        click.echo(f"  the recording is incomplete: {why}")
    click.echo(f"  outputs in {out}/ (report: {out / 'report.html'})")
    undecoded = metrics.get("frames_undecoded") or []
    if undecoded:
        # a recorded run can lack frames (dropped while recording: the replay gives the loop
        # the frame before); a frame that is there but does not decode, in a run, video,
        # images, a tub or a bag, is damage: the loop saw no frame there (never the frame
        # before), and the replay is bad input, its outputs written. Its frames: every one its
        # steps name (not those the loop got plus these: that left out a run's first frame when
        # it was dropped while recording, the loop having no frame before to get instead)
        total = len(frame_indices(replay_source))
        if not metrics["frames"]:
            none = ("its only frame could not be decoded" if total == 1
                    else f"none of its {total} frames could be decoded")
            raise InputFileError(f"SOURCE '{source}': {none} (a damaged or cut file?)")
        raise InputFileError(
            f"SOURCE '{source}': {len(undecoded)} of its {counted(total, 'frame')} could not be "
            f"decoded (counted from 0): {_frame_names(replay_source, undecoded)} (a damaged or "
            f"cut file?); the loop saw no frame there, outputs in {out}/")
    # what makes a replay inexact is said before the divergences it causes
    if check and metrics["incomplete"]:
        raise QualityGateError(f"replay {source}: the recording is incomplete "
                               f"({metrics['incomplete'][0]}), so it cannot be checked")
    if check and not metrics["exact_input"]:
        raise QualityGateError(f"replay {source}: the recording is not exact (frames dropped or "
                               "lossy), so it cannot be checked")
    if check and not metrics["reproduced"]:
        raise QualityGateError(f"replay {source}: diverges from the recording at "
                               f"{metrics['first_divergence']['text']}")


def _refuse_the_source_folder(out: Path, source: str) -> None:
    """UsageError when --out is SOURCE's own folder (a folder of frames, a tub, a rosbag2
    folder; a glob's folder) or lies inside it: replay would write its outputs among the
    frames, and the next replay of SOURCE would be refused as a sim output folder."""
    from lanewarden.commands.output_folders import lies_within, source_folder

    folder = source_folder(source)
    if folder is not None and lies_within(out, folder):
        raise UsageError(f"--out '{out}': inside SOURCE '{source}'; replay writes its outputs "
                         "elsewhere: expected a folder outside SOURCE")


def _frame_names(replay_source: ReplaySource, indices: list[int], shown: int = 3) -> str:
    """'frame 4 (name.jpg), ...': the first `shown` of a clip's frames, by index (and file name
    for a folder of images)."""
    from lanewarden.replay_sources import frame_name

    names = [frame_name(replay_source, i, files_of=("images", "tub")) for i in indices[:shown]]
    more = len(indices) - shown
    return ", ".join(names) + (f" and {more} more" if more > 0 else "")


def commands() -> list[click.Command]:
    return [replay_command]
