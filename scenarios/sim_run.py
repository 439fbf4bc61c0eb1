"""One simulated run written to a directory: metrics.json, run.jsonl, video.mp4 (+ poster.jpg),
plot.png and report.html; old outputs cleared first, a PARTIAL marker until all are written.

The shell around `Simulation`: opens the files, shows progress on stderr (`progress.Progress`: a
bar on a terminal, a line every few seconds otherwise), measures the wall time for the report
(wall time never feeds the simulation) and writes the outputs. `lanewarden sim` calls it once;
`lanewarden demo` calls it in two worker processes. Errors are the layers' one-line errors
(ScenarioError, SupervisorError, ...).
"""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from lanewarden.scenarios.camera_clip import CameraClipWriter, ClipFiles
from lanewarden.scenarios.errors import ScenarioError, ScenarioOutputError
from lanewarden.scenarios.expectations import check_expectation
from lanewarden.scenarios.output_folder import OutputFolder
from lanewarden.scenarios.plot import PlotMarker, write_plot
from lanewarden.scenarios.progress import Progress
from lanewarden.scenarios.report import run_summary, write_report
from lanewarden.scenarios.simulator import (
    Simulation,
    SimulationResult,
    camera_buffers_problem,
    effective_config,
    latest_time_s,
)
from lanewarden.scenarios.spec import ScenarioSpec
from lanewarden.scenarios.state_reasons import state_reasons
from lanewarden.scenarios.world import build_world
from lanewarden.supervisor.recorder import JsonlRecorder

if TYPE_CHECKING:
    from lanewarden.assembly import BuildStack
    from lanewarden.config import LanewardenConfig

#: Every file a run writes into its folder.
RUN_OUTPUTS = ("metrics.json", "run.jsonl", "video.mp4", "poster.jpg", "plot.png", "report.html")

#: metrics.json keys, in this order first (the issue's names); the rest follow alphabetically.
METRIC_KEYS = (
    "scenario", "controller", "seed", "frames", "sim_time_s", "wall_time_s", "halted",
    "halt_reason", "final_state", "states_visited", "max_cross_track_error_m",
    "mean_cross_track_error_m", "distance_travelled_m", "distance_past_lane_end_m",
    "crossed_tape", "lane_loss_to_halt_s", "turns_completed",
)


@dataclass(frozen=True)
class RunRequest:
    """Everything one run needs; picklable, so a worker process can take it. `build_stack`: the
    composition root's (`lanewarden.assembly.build_stack`, a module-level function)."""

    spec: ScenarioSpec
    config: LanewardenConfig
    controller: str
    seed: int
    out_dir: Path
    build_stack: BuildStack
    video: bool = True
    progress: bool = True
    progress_position: int = 0
    source: str | None = None
    #: `--camera-out`: write the camera's raw view there too (scenarios.camera_clip); checked by
    #: `check_clip_target` before the output folder is prepared, as a refused one must leave an
    #: earlier run's outputs untouched
    camera_out: ClipFiles | None = None
    #: more metrics from the finished run (e.g. a campaign case's outcome); a module-level
    #: function, so the request stays picklable
    judge: Callable[[SimulationResult, LanewardenConfig], dict[str, object]] | None = None


def _progress(request: RunRequest, config: LanewardenConfig) -> Progress:
    """Simulated seconds of the time limit; the run may halt long before it, and one still
    DEGRADED there goes on a little (`latest_time_s`): the ETA is a bound. The rate is measured
    from the first simulated step (building the world is not simulating it)."""
    return Progress(
        request.spec.run.max_time_s, f"{request.spec.name}/{request.controller}", "s simulated",
        enabled=request.progress and config.simulation.progress,
        position=request.progress_position, fmt="{:.1f}",
        at_most=latest_time_s(config, request.spec.run), warm_up=True,
        bar_format="{desc}: {bar} {n:.1f}/{total:.1f} s simulated [{elapsed}]")


def _camera_clip(request: RunRequest, config: LanewardenConfig) -> CameraClipWriter | None:
    """The camera clip's writer (`--camera-out`), opened before the run starts."""
    if request.camera_out is None:
        return None
    sim = config.simulation
    return CameraClipWriter(request.camera_out, (sim.width_px, sim.height_px),
                            sim.camera_rate_hz, sim.video.preset, gray=not sim.perception_color)


def ordered_metrics(metrics: dict[str, object]) -> dict[str, object]:
    first = {k: metrics[k] for k in METRIC_KEYS if k in metrics}
    rest = {k: metrics[k] for k in sorted(metrics) if k not in first}
    return {**first, **rest}


def _check_world(request: RunRequest, config: LanewardenConfig) -> None:
    """The scenario's world (its geometry against the size limits), built before any output is
    touched; a problem names the scenario's file, as its other problems do (the world's own
    checks know only the scenario's name)."""
    try:
        build_world(request.spec, margin_m=config.simulation.world_margin_m)
        if problem := camera_buffers_problem(request.spec, config):
            raise ScenarioError(f"{request.spec.name}: {problem}")
    except ScenarioOutputError:
        raise
    except ScenarioError as exc:
        message, named = str(exc), f"{request.spec.name}: "
        if request.source and message.startswith(named):
            raise ScenarioError(f"{request.source}: {message.removeprefix(named)}") from None
        raise


def run_to_directory(request: RunRequest) -> dict[str, object]:
    """Run one scenario and write its outputs into `request.out_dir` (old outputs cleared first,
    a PARTIAL marker until all are written); returns the metrics."""
    started = time.perf_counter()
    config = effective_config(request.config, request.spec, request.source)
    _check_world(request, config)
    out = request.out_dir
    folder = OutputFolder(out, RUN_OUTPUTS)
    folder.begin()
    video_path = out / "video.mp4" if request.video else None
    clip = _camera_clip(request, config)
    bar = _progress(request, config)
    shown = [0.0]

    def progress(now: float) -> None:
        if now - shown[0] >= 0.5:
            bar.advance_to(now)
            shown[0] = now

    try:
        with JsonlRecorder(out / "run.jsonl") as recorder:
            simulation = Simulation(
                request.spec, config, request.build_stack, controller=request.controller,
                seed=request.seed, video_path=video_path, record=recorder, progress=progress,
                camera_frames=None if clip is None else clip.add)
            result = simulation.run()
        # The run usually ends before its time limit: show it finished.
        bar.set_total(round(float(result.trace.time_s[-1]), 1) if len(result.records) else 0.0)
        bar.advance_to(bar.total)
    except BaseException:
        bar.close(finished=False)
        if clip is not None:
            moved = clip.abort()
            if moved is not None:
                with contextlib.suppress(ScenarioOutputError):  # the first error is the one said
                    folder.note(f"{moved} (the camera clip, cut short after {clip.frames} "
                                "frames; no calibration beside it)")
        raise
    bar.close()
    camera_clip = None if clip is None else clip.close(
        simulation.calibration, config.model_dump(mode="json", exclude_defaults=True))
    write_run_plot(out / "plot.png", result, config)
    metrics = dict(result.metrics)
    if request.judge is not None:
        metrics.update(request.judge(result, config))
    expect = getattr(request.spec.expect, request.controller, None)
    failures = None if expect is None else check_expectation(metrics, expect)
    outputs = ["metrics.json", "plot.png", "report.html", "run.jsonl"]
    if video_path is not None:
        outputs.append("video.mp4")
        if (out / "poster.jpg").exists():  # written when the video has a frame
            outputs.append("poster.jpg")
    metrics.update(
        scenario=request.spec.name,
        controller=request.controller,
        seed=request.seed,
        frames=len(result.records),
        sim_time_s=round(float(result.trace.time_s[-1]), 4) if len(result.records) else 0.0,
        wall_time_s=round(time.perf_counter() - started, 3),
        resolution=[config.simulation.width_px, config.simulation.height_px],
        expectation_met=None if failures is None else not failures,
        expectation_failures=failures or [],
        outputs=sorted(outputs),
    )
    if camera_clip is not None:
        metrics["camera_clip"] = camera_clip
    metrics = ordered_metrics(metrics)
    try:
        (out / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n", encoding="utf-8")
        write_report(out / "report.html", {request.controller: metrics}, run_summary(metrics),
                     title=run_title(request.spec.name, request.controller, request.seed),
                     folders={request.controller: ""})
    except OSError as exc:
        raise ScenarioOutputError(f"{out}: cannot write the run's outputs ({exc})") from exc
    folder.finish()
    return metrics


#: How plot titles and reports name each controller.
CONTROLLER_TITLES = {
    "supervised": "the supervisor",
    "lecture": "the lecture's rule (baseline)",
}


def run_title(scenario: str, controller: str, seed: int | None = None) -> str:
    """'Scenario lecture driven by the supervisor (seed 0)'."""
    who = CONTROLLER_TITLES.get(controller, f"the {controller} controller")
    return f"Scenario {scenario} driven by {who}" + ("" if seed is None else f" (seed {seed})")


def write_run_plot(path: Path, result: SimulationResult, config: LanewardenConfig) -> None:
    records = result.records
    metrics = result.metrics
    markers = []
    loss_time = metrics.get("lane_loss_time_s")
    if isinstance(loss_time, float):
        markers.append(PlotMarker("lane out of view", loss_time,
                                  estimated=bool(metrics.get("lane_loss_estimated"))))
    for index, effect in sorted(result.fault_effects.items()):  # the fault, then the answer
        markers.append(PlotMarker(f"fault {index}: {effect.kind}", effect.time_s))
    halt_time = metrics.get("halt_time_s") if metrics.get("halted") else None
    if isinstance(halt_time, float):
        markers.append(PlotMarker("HALT", halt_time))
    write_plot(
        path,
        run_title(result.spec.name, result.controller, result.seed),
        result.trace.time_s,
        [None if r.observation is None else r.observation.slope_sum for r in records],
        [r.filtered_slope_sum for r in records],
        [None if r.observation is None else r.observation.confidence for r in records],
        [r.state for r in records],
        state_reasons([r.state for r in records], [r.events for r in records],
                      [r.halt_reason for r in records]),
        config.supervisor.turn_enter_slope_sum,
        markers,
    )
