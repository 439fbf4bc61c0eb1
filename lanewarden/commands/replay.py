"""`lanewarden replay SOURCE`: perception and the supervisor on recorded frames, with the same
outputs as `sim`; for a run folder, a step-by-step comparison with the recording.

A thin shell over `lanewarden.replay` and `lanewarden.replay_outputs`.
"""

from __future__ import annotations

from pathlib import Path

import click

from lanewarden.commands.config_cmd import config_option
from lanewarden.errors import QualityGateError
from lanewarden.supervisor.controllers import CONTROLLERS, DEFAULT_CONTROLLER

REPLAY_EXAMPLES = """\b
Examples:
  lanewarden replay runs/2026-11-05T14-03-12Z --check
  lanewarden replay clip.mp4 --out out/clip
  lanewarden replay my-tub/ --config track.yaml --calibration tub-camera.yaml
"""


@click.command("replay", epilog=REPLAY_EXAMPLES)
@click.argument("source")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Output directory (default: lanewarden-out/replay-<source name>).")
@config_option
@click.option("--calibration", "calibration_path", type=click.Path(dir_okay=False), default=None,
              help="Camera calibration (default: the run folder's own, else none).")
@click.option("--controller", type=click.Choice(list(CONTROLLERS)), default=None,
              help=f"Who drives (default: the recorded run's, else {DEFAULT_CONTROLLER}).")
@click.option("--no-video", is_flag=True, help="Skip video.mp4 (faster).")
@click.option("--check", is_flag=True,
              help="Exit with code 2 when a replayed step differs from the recorded run (or the "
              "recording cannot be replayed exactly).")
def replay_command(source: str, out_dir: str | None, config_path: str | None,
                   calibration_path: str | None, controller: str | None, no_video: bool,
                   check: bool) -> None:
    """Replay SOURCE (a run folder, a video file, a folder or glob of images, or a Donkeycar tub)
    on a fake clock at its recorded timestamps: OUT/{video.mp4, poster.jpg, plot.png,
    metrics.json, run.jsonl, report.html}, as `sim` writes them. A run folder replays with its
    own recorded config and calibration unless --config/--calibration say otherwise, and every
    step is compared."""
    from lanewarden.config import load_config
    from lanewarden.perception.calibration import load_calibration
    from lanewarden.replay import open_replay_source, replay_config
    from lanewarden.replay_outputs import ReplayRequest, run_replay

    rate_hz = 1.0 / load_config(config_path).supervisor.camera_period_s
    replay_source = open_replay_source(source, rate_hz)
    config = replay_config(replay_source, config_path)
    calibration = (load_calibration(calibration_path) if calibration_path
                   else replay_source.calibration)
    chosen = controller or replay_source.controller or DEFAULT_CONTROLLER
    if chosen not in CONTROLLERS:
        chosen = DEFAULT_CONTROLLER
    out = Path(out_dir) if out_dir else Path("lanewarden-out") / f"replay-{replay_source.name}"
    metrics = run_replay(ReplayRequest(replay_source, config, calibration, chosen, out,
                                       video=not no_video))
    click.echo(f"{replay_source.name} ({replay_source.kind}, config: "
               f"{replay_source.config_origin}): {metrics['steps']} steps, {metrics['frames']} "
               f"frames, {metrics['sim_time_s']} s replayed in {metrics['wall_time_s']} s")
    click.echo(f"  states visited: {', '.join(metrics['states_visited'])}; final state "
               f"{metrics['final_state']}"
               + (f" ({metrics['halt_reason']})" if metrics.get("halt_reason") else ""))
    if replay_source.kind == "run":
        if metrics["reproduced"]:
            click.echo(f"  reproduced: all {metrics['compared_steps']} steps match the recording "
                       "(state, events, command)")
        else:
            click.echo(f"  DIVERGES at {metrics['first_divergence']['text']} "
                       f"({metrics['divergent_steps']} steps differ)")
        if not metrics["exact_input"]:
            click.echo(f"  the recording is not exact ({metrics['frames_missing']} frames missing"
                       f"{'' if replay_source.meta.get('lossless') else ', lossy frames'}): the "
                       "replay cannot be exact")
    click.echo(f"  outputs in {out}/ (report: {out / 'report.html'})")
    if check and replay_source.kind != "run":
        raise QualityGateError(f"--check: {source} is a {replay_source.kind}, not a recorded run: "
                               "there is nothing to compare with")
    if check and not metrics["reproduced"]:
        raise QualityGateError(f"replay {source}: diverges from the recording at "
                               f"{metrics['first_divergence']['text']}")
    if check and not metrics["exact_input"]:
        raise QualityGateError(f"replay {source}: the recording is not exact (frames dropped or "
                               "lossy), so it cannot be checked")


def commands() -> list[click.Command]:
    return [replay_command]
