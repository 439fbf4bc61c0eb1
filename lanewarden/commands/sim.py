"""`lanewarden sim` (one scenario, one controller) and `lanewarden demo` (the lecture's course with
both controllers, side by side).

Thin shells: parse flags, load the config and the scenario, call `scenarios.sim_run`, print a
summary. Errors are the layers' one-line errors; the CLI root prints them without a traceback.
"""

from __future__ import annotations

import multiprocessing
import signal
import sys
import textwrap
import threading
import time
from dataclasses import replace
from pathlib import Path

import click

from lanewarden.assembly import build_stack
from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import PathFlag, WholeRange
from lanewarden.commands.output_folders import (
    create_output_folder,
    interrupted_in,
    refuse_a_recording_folder,
)
from lanewarden.config import load_config, narrow_lane_warning
from lanewarden.errors import QualityGateError, UsageError
from lanewarden.perception import line_kernel
from lanewarden.scenarios.before_halt import halt_line
from lanewarden.scenarios.camera_clip import check_clip_target
from lanewarden.scenarios.campaign.cases import MAX_SEED
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.library import library_names, resolve_scenario
from lanewarden.scenarios.output_folder import PARTIAL, OutputFolder
from lanewarden.scenarios.report import (
    comparison_rows,
    demo_summary,
    fault_lines,
    format_table,
    format_value,
    table_notes,
    write_report,
)
from lanewarden.scenarios.sim_run import RunRequest, run_title, run_to_directory
from lanewarden.scenarios.simulator import effective_config
from lanewarden.scenarios.spec import ScenarioSpec
from lanewarden.stop_signals import leave_interrupts_to_the_parent, raise_interrupt
from lanewarden.supervisor.controllers import CONTROLLERS, DEFAULT_CONTROLLER

DEMO_SCENARIO = "lecture"
DEFAULT_DEMO_OUT = "lanewarden-out"


def _load_scenario(name_or_file: str) -> ScenarioSpec:
    """The scenario, or a UsageError (exit 2, like a bad config file): a bad scenario name or file
    is bad input."""
    try:
        return resolve_scenario(name_or_file)
    except ScenarioError as exc:
        raise UsageError(str(exc)) from None


def _summary_lines(metrics: dict[str, object]) -> list[str]:
    def fmt(key: str, unit: str = "") -> str:
        value = metrics.get(key)
        text = format_value(value)
        return text + unit if isinstance(value, int | float) and not isinstance(value, bool) \
            else text

    lines = [
        f"{metrics['scenario']} / {metrics['controller']} (seed {metrics['seed']}): "
        f"{metrics['frames']} frames, {metrics['sim_time_s']} s simulated in "
        f"{metrics['wall_time_s']} s",
        f"  halted: {fmt('halted')}  reason: {metrics.get('halt_reason') or '-'}",
    ]
    lines += fault_lines(metrics)
    if metrics.get("halted"):
        lines.append(f"  halt position: {fmt('halt_position')}")
    if moving := metrics.get("motion_after_halt"):
        lines.append(f"  NOT STOPPED after HALT: {moving} (the base kept driving: unsafe)")
    if line := halt_line(metrics.get("before_halt")):
        lines.append(line)
    lines += [
        f"  states visited: {fmt('states_visited')}",
        f"  turns completed: {fmt('turns_completed')}  max cross-track error: "
        f"{fmt('max_cross_track_error_m', ' m')}  crossed tape: {fmt('crossed_tape')}",
    ]
    if metrics.get("distance_past_lane_end_m") is not None:
        lines.append(f"  distance past lane end: {fmt('distance_past_lane_end_m', ' m')} "
                     "(negative: stopped before it)")
    if metrics.get("lane_loss_to_halt_s") is not None:
        estimated = " (estimated)" if metrics.get("lane_loss_estimated") else ""
        lines.append(f"  lane out of view -> HALT: {fmt('lane_loss_to_halt_s', ' s')}{estimated} "
                     "(negative: halted before the lane left the view)")
    return lines


def _scenario_list(width: int = 76) -> str:
    """The library's names as a help paragraph click will not rewrap (so it never splits a name
    at its hyphens)."""
    lines = textwrap.wrap(", ".join(library_names()), width - 2, break_on_hyphens=False,
                          break_long_words=False)
    return "\b\nScenarios (--scenario NAME):\n" + "\n".join(f"  {line}" for line in lines)


SIM_EXAMPLES = """\b
Examples:
  lanewarden sim --scenario lane-ends
  lanewarden sim --scenario lane-ends --camera-out clip.mp4
  lanewarden sim --scenario lecture --controller lecture --seed 3 --out out/lecture
  lanewarden sim --scenario my-track.yaml --no-video --check
  lanewarden sim --case campaign-out/cases/r00042.yaml
"""


@click.command("sim", epilog=_scenario_list() + "\n\n" + SIM_EXAMPLES)
@click.option("--scenario", "scenario", default=None, metavar="NAME|FILE",
              help="A library scenario (names below) or a scenario YAML file.")
@click.option("--case", "case_file", default=None, metavar="FILE",
              type=PathFlag("a case file", dir_okay=False),
              help="Rerun one campaign case (DIR/cases/<id>.yaml) exactly: its scenario, faults, "
              "seed, controller and config; prints its outcome class.")
@click.option("--controller", type=click.Choice(list(CONTROLLERS)), default=DEFAULT_CONTROLLER,
              show_default=True, help="Who drives: the supervisor, or the lecture's rule.")
@click.option("--seed", type=WholeRange(0, MAX_SEED), default=0, show_default=True,
              help="Varies the floor texture and the sensor noise.")
@click.option("--out", "out_dir", type=PathFlag("a folder", file_okay=False), default=None,
              help="Output directory (default: lanewarden-out/<scenario>-<controller>); its "
              "old outputs are replaced.")
@config_option
@click.option("--no-video", is_flag=True, help="Skip video.mp4 (faster).")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@click.option("--check", is_flag=True,
              help="Exit with code 2 if the scenario's expected outcome is not met.")
@click.option("--camera-out", "camera_out",
              type=PathFlag("a file or folder name", path_type=Path), default=None, metavar="FILE",
              help="Also write the robot camera's raw view (no overlay, no map) at the camera's "
              "size and rate: a video when FILE ends in .mp4/.mkv/.avi/.mov, else a folder of "
              "PNG frames; with FILE.calibration.yaml (and FILE.config.yaml when the config is "
              "not the default) beside it, for `lanewarden run --camera FILE`.")
def sim_command(scenario: str | None, case_file: str | None, controller: str, seed: int,
                out_dir: str | None, config_path: str | None, no_video: bool, quiet: bool,
                check: bool, camera_out: Path | None) -> None:
    """Run one scenario in the simulator; write metrics.json, run.jsonl, video.mp4 (and its
    poster.jpg), plot.png and report.html (and, with --camera-out, a camera clip)."""
    if case_file is not None:
        ctx = click.get_current_context()
        changed = [flag for name, flag in (("seed", "--seed"), ("controller", "--controller"))
                   if ctx.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT]
        if changed:  # they had been ignored without a word: the case holds both
            raise UsageError(f"--case: the case file holds the seed and the controller; drop "
                             f"{' and '.join(changed)}")
        request = _case_request(case_file, scenario, config_path, out_dir, no_video, quiet)
        spec, controller, out = request.spec, request.controller, request.out_dir
    else:
        if scenario is None:
            raise UsageError("sim: expected --scenario NAME|FILE (or --case FILE)")
        config = load_config(config_path)
        spec = _load_scenario(scenario)
        out = Path(out_dir) if out_dir else Path(DEFAULT_DEMO_OUT) / f"{spec.name}-{controller}"
        request = RunRequest(
            spec=spec, config=config, controller=controller, seed=seed, out_dir=out,
            build_stack=build_stack, video=not no_video, progress=not quiet, source=scenario)
    if camera_out is not None:
        # every check before the output folder is prepared (a refused --camera-out had left the
        # earlier run's outputs deleted); the clip and its calibration go into its folder
        refuse_a_recording_folder(camera_out.parent, "--camera-out", given=camera_out)
        _check_clip_beside_outputs(camera_out, out)
        request = replace(request, camera_out=check_clip_target(camera_out))
    if check and getattr(spec.expect, controller, None) is None:  # said before the run, not after
        raise QualityGateError(
            f"--check: scenario {spec.name} states no expected outcome for controller "
            f"{controller!r} (add an expect: block for it), nothing was checked"
        )
    if narrow := narrow_lane_warning(effective_config(request.config, spec)):
        click.echo(f"warning: {narrow}")
    create_output_folder(out, writes="run")
    try:
        metrics = run_to_directory(request)
    except KeyboardInterrupt:
        raise interrupted_in(out) from None
    for line in _summary_lines(metrics):
        click.echo(line)
    if case_file is not None:
        click.echo(f"  outcome: {metrics.get('outcome')} ({metrics.get('outcome_reason')})")
    met = metrics.get("expectation_met")
    if met is not None:
        failures = metrics.get("expectation_failures") or []
        assert isinstance(failures, list)
        click.echo("  expected outcome: " + ("met" if met else "NOT met: " + "; ".join(failures)))
    click.echo(f"  outputs in {out}/ (open {out / 'report.html'})")
    clip = metrics.get("camera_clip")
    if isinstance(clip, dict):
        width, height = clip["size"]
        click.echo(f"  camera clip: {clip['path']} ({width}x{height}, {clip['fps']:g} fps, "
                   f"{clip['frames']} frames: the camera's raw view), calibration "
                   f"{clip['calibration']}" + (f", config {clip['config']}" if clip['config']
                                               else ""))
        click.echo(f"  play it through the whole loop: {clip['run']}")
    if check and met is False:
        raise QualityGateError(f"scenario {spec.name}: expected outcome not met")


@click.command("demo", epilog="""\b
Example:
  lanewarden demo && xdg-open lanewarden-out/report.html
""")
@click.option("--out", "out_dir", type=PathFlag("a folder", file_okay=False),
              default=DEFAULT_DEMO_OUT,
              show_default=True, help="Output directory; its old outputs are replaced.")
@config_option
@click.option("--seed", type=WholeRange(0, MAX_SEED), default=0, show_default=True,
              help="Varies the floor texture and the sensor noise.")
@click.option("--no-video", is_flag=True, help="Skip the videos (faster).")
@click.option("--quiet", is_flag=True, help="No progress bars.")
def demo_command(out_dir: str, config_path: str | None, seed: int, no_video: bool,
                 quiet: bool) -> None:
    """The lecture's course driven by the lecture's controller and by the supervisor, side by
    side: DIR/lecture/, DIR/supervised/, DIR/report.html."""
    started = time.perf_counter()
    config = load_config(config_path)
    spec = _load_scenario(DEMO_SCENARIO)
    out = create_output_folder(Path(out_dir), writes="demo")
    names = ("lecture", "supervised")
    for name in names:  # each run's outputs go into its own folder there
        refuse_a_recording_folder(out / name)
    folder = OutputFolder(out, ["report.html"], subfolders=names)
    folder.begin()
    requests = [
        RunRequest(spec=spec, config=config, controller=name, seed=seed, out_dir=out / name,
                   build_stack=build_stack, video=not no_video, progress=not quiet,
                   progress_position=i)
        for i, name in enumerate(names)
    ]
    try:
        results = _run_in_parallel(requests)
    except KeyboardInterrupt:
        raise interrupted_in(out) from None
    runs = {r.controller: m for r, m in zip(requests, results, strict=True)}
    summary = demo_summary(runs["lecture"], runs["supervised"])
    write_report(out / "report.html", runs, summary,
                 headings={r.controller: f"{r.controller}: "
                           f"{run_title(spec.name, r.controller, seed)}" for r in requests})
    folder.finish()
    sys.stderr.flush()
    click.echo(format_table(comparison_rows(runs)))
    for note in table_notes(runs):
        click.echo(f"  ({note})")
    click.echo("")
    click.echo(summary)
    click.echo(f"Report: {out / 'report.html'}  ({time.perf_counter() - started:.1f} s)")


def _check_clip_beside_outputs(camera_out: Path, out: Path) -> None:
    """UsageError when --camera-out (or a file beside it) would take the place of one of the
    run's own outputs, or of its folder: found before simulating, not when the report is
    written at the end."""
    from lanewarden.scenarios.camera_clip import ClipFiles
    from lanewarden.scenarios.sim_run import RUN_OUTPUTS

    taken = {out.resolve()} | {(out / name).resolve() for name in (*RUN_OUTPUTS, PARTIAL)}
    files = ClipFiles.for_target(camera_out)
    for path in (files.clip, files.calibration, files.config):
        if path.resolve() in taken:
            raise UsageError(f"--camera-out {camera_out}: {path} is one of the run's own outputs "
                             f"in --out {out}; put the clip elsewhere")


def _run_in_parallel(requests: list[RunRequest]) -> list[dict[str, object]]:
    """The runs are independent: one process each (the machine has two cores). Forked (no
    re-import: ~2 s less each) only from a single-threaded process, where forking is safe."""
    line_kernel.ready()  # (before the workers: a compile happens, and is said, once)
    single = threading.active_count() == 1
    method = "fork" if single and "fork" in multiprocessing.get_all_start_methods() else "spawn"
    # Ctrl-C on a terminal reaches every process of the group: the workers leave it to this
    # one, which terminates them (each had printed its own KeyboardInterrupt traceback).
    pool = multiprocessing.get_context(method).Pool(processes=len(requests),
                                                    initializer=leave_interrupts_to_the_parent)
    # Installed after the workers exist (they keep the default): SIGTERM to the demo becomes an
    # interrupt here, so the workers are terminated instead of running on as orphans.
    previous = signal.signal(signal.SIGTERM, raise_interrupt)
    try:
        pending = [pool.apply_async(run_to_directory, (r,)) for r in requests]
        results = [p.get() for p in pending]
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()
        signal.signal(signal.SIGTERM, previous)
    return results


def _case_request(case_file: str, scenario: str | None, config_path: str | None,
                  out_dir: str | None, no_video: bool, quiet: bool) -> RunRequest:
    """The run a campaign case describes; --scenario and --config would change it: refused."""
    from lanewarden.scenarios.campaign.cases import load_case
    from lanewarden.scenarios.campaign.run_case import case_config, judge_metrics

    if scenario is not None or config_path is not None:
        raise UsageError("--case: the case file holds the scenario and the config; drop "
                         "--scenario and --config")
    try:
        case = load_case(case_file)
        spec = case.scenario_spec(case_file)
        config = case_config(case, case_file)
    except ScenarioError as exc:
        raise UsageError(str(exc)) from None
    out = Path(out_dir) if out_dir else Path(DEFAULT_DEMO_OUT) / f"case-{case.id}"
    return RunRequest(spec=spec, config=config, controller=case.controller, seed=case.seed,
                      out_dir=out, build_stack=build_stack, video=not no_video,
                      progress=not quiet, source=case_file, judge=judge_metrics)


def commands() -> list[click.Command]:
    return [sim_command, demo_command]
