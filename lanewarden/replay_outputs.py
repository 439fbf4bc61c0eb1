"""`lanewarden replay`'s outputs: the same files as `sim` (video.mp4 and its poster.jpg, plot.png,
metrics.json, run.jsonl, report.html) in OUT/, drawn by the simulator's own video, plot and report
code (`scenarios.video.VideoRecorder`, `scenarios.plot.write_plot`, `scenarios.report`), in an
`OutputFolder` like `sim`'s (no stale file from an earlier run; PARTIAL until complete).

The video's map panel has no world to draw for a real run: `OdometryMapView` draws the path the
base's odometry recorded (a grid in metres), coloured by state, with the robot on it; for a video,
images or a tub there is no odometry and the robot stays at the origin.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from lanewarden.actuation.base import Pose2D
from lanewarden.assembly import decision_rule
from lanewarden.config import LanewardenConfig
from lanewarden.errors import OutputError
from lanewarden.perception.calibration import CameraCalibration
from lanewarden.perception.overlay import as_bgr, draw_detection
from lanewarden.replay import (
    Divergence,
    ReplaySource,
    frame_indices,
    missing_frames,
    replay_steps,
)
from lanewarden.run_outcome import (
    CLIP_END,
    NORMAL_HALTS,
    EndReason,
    LoopEnd,
    LoopEndKind,
    end_reason_of,
    halt_event,
    recorded_loop_end,
)
from lanewarden.scenarios.before_halt import before_halt
from lanewarden.scenarios.metrics import first_halt_index
from lanewarden.scenarios.output_folder import OutputFolder
from lanewarden.scenarios.plot import PlotMarker, write_plot
from lanewarden.scenarios.progress import Progress
from lanewarden.scenarios.report import write_report
from lanewarden.scenarios.sim_run import RUN_OUTPUTS, ordered_metrics
from lanewarden.scenarios.state_reasons import state_reasons
from lanewarden.scenarios.video import MapView, VideoRecorder
from lanewarden.supervisor.recorder import JsonlRecorder

RUN_NAME = "replay"
#: At most about this many grid lines across the odometry map (a 1 m grid, coarser for long paths).
MAX_GRID_LINES = 40


class OdometryMapView(MapView):
    """A MapView over the recorded odometry instead of a painted world (same drawing code)."""

    def __init__(self, poses: list[Pose2D], size_px: int) -> None:
        xs = [p.x_m for p in poses] or [0.0]
        ys = [p.y_m for p in poses] or [0.0]
        pad = 0.8
        span = max(max(xs) - min(xs), max(ys) - min(ys), 1.0) + 2 * pad
        cx, cy = (max(xs) + min(xs)) / 2.0, (max(ys) + min(ys)) / 2.0
        self.size = size_px
        self.m_per_px = span / size_px
        self.x_min = cx - span / 2.0
        self.y_max = cy + span / 2.0
        self._roi = np.zeros((0, 2))
        self.background = self._grid(poses)
        self._canvas = self.background.copy()
        self._frame = np.empty_like(self.background)
        self._last = None

    def _grid(self, poses: list[Pose2D]) -> np.ndarray:
        size = self.size
        image = np.full((size, size, 3), 245, np.uint8)
        span = size * self.m_per_px
        step = 10.0 ** max(0, math.ceil(math.log10(span / MAX_GRID_LINES)))  # 1 m, 10 m, ...
        for k in range(math.floor(self.x_min / step), math.ceil((self.x_min + span) / step) + 1):
            px = self.to_px(k * step, 0.0)[0]
            cv2.line(image, (px, 0), (px, size - 1), (215, 215, 215), 1)
        for k in range(math.floor((self.y_max - span) / step), math.ceil(self.y_max / step) + 1):
            py = self.to_px(0.0, k * step)[1]
            cv2.line(image, (0, py), (size - 1, py), (215, 215, 215), 1)
        moved = any(p.x_m or p.y_m for p in poses)
        label = (f"odometry ({step:g} m grid)" if moved
                 else "no odometry (the base did not move)")
        cv2.putText(image, label, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (90, 90, 90), 1,
                    cv2.LINE_AA)
        return image


@dataclass(frozen=True)
class ReplayRequest:
    source: ReplaySource
    config: LanewardenConfig
    calibration: CameraCalibration | None
    controller: str
    out_dir: Path
    video: bool = True


def _poses(source: ReplaySource) -> list[Pose2D]:
    return [s.feedback.odometry for s in source.steps if s.feedback is not None]


def _video_every(times: list[float], video_fps: float) -> tuple[int, float]:
    """Every k-th step goes into the video, and the video's frame rate to play in real time."""
    gaps = np.diff(np.asarray(times, dtype=np.float64))
    gaps = gaps[gaps > 0]
    rate = 1.0 / float(np.median(gaps)) if len(gaps) else video_fps
    every = max(1, round(rate / video_fps))
    return every, min(max(rate / every, 1.0), 120.0)


def run_replay(request: ReplayRequest) -> dict[str, Any]:
    """Replay into OUT/ (the files `sim` writes); returns the metrics."""
    started = time.perf_counter()
    source, config = request.source, request.config
    out = request.out_dir
    folder = OutputFolder(out, RUN_OUTPUTS)
    folder.begin()
    times = [s.t for s in source.steps]
    video: VideoRecorder | None = None
    every, video_fps = _video_every(times, config.simulation.video.fps)
    panel: np.ndarray | None = None
    detection: tuple[Any, str] | None = None
    records = []
    decide = decision_rule(config)
    divergences: list[Divergence] = []
    distance = 0.0
    last_pose: Pose2D | None = None
    progress = Progress(len(times), f"replay {source.name}", "steps")
    closing_from = _loop_end(source).steps  # the runner's closing stop comes after these
    try:
        with JsonlRecorder(out / "run.jsonl") as log:
            for step in replay_steps(source, config, request.calibration, request.controller):
                progress.update()
                record = step.record
                log(record)
                records.append(record)
                if step.divergence is not None:
                    divergences.append(step.divergence)
                feedback = step.step_input.feedback
                pose = feedback.odometry if feedback is not None else Pose2D()
                if last_pose is not None:
                    distance += math.dist((pose.x_m, pose.y_m), (last_pose.x_m, last_pose.y_m))
                last_pose = pose
                if not request.video or (closing_from is not None
                                         and step.index >= closing_from):
                    continue  # (the runner's closing stop is not the run's end: not shown)
                detection = None
                if step.detection is not None:
                    observation, debug = step.detection
                    panel = as_bgr(debug.image)
                    draw_detection(panel, observation, debug)
                    detection = (observation, decide(observation))
                elif step.image is not None and (panel is None or record.observation is None
                                                 and step.record.frame_index is not None):
                    panel = as_bgr(step.image)
                if panel is None:
                    continue
                if video is None:
                    video = VideoRecorder(
                        out / "video.mp4", (panel.shape[1], panel.shape[0]),
                        OdometryMapView(_poses(source), config.simulation.video.map_size_px),
                        video_fps, config.simulation.video.crf, config.simulation.video.preset,
                        title=f"{source.name} (replay)")
                video.step(pose, record)
                if step.index % every == 0:
                    video.add(panel, pose, step.step_input.t - times[0], record, detection)
    finally:
        progress.close(finished=sys.exc_info()[0] is None)
        if video is not None:
            video.close()
    end = _run_end(source, records)
    halt, last = first_halt(source, records, end), ending_halt(source, records, end)
    metrics = replay_metrics(source, records, divergences, distance, config,
                             found=(end, halt, last))
    metrics.update(controller=request.controller, config=source.config_origin,
                   wall_time_s=round(time.perf_counter() - started, 3))
    _write_plot(out / "plot.png", source, records, times, config, halt, last)
    outputs = ["metrics.json", "plot.png", "report.html", "run.jsonl"]
    if video is not None:
        outputs += ["video.mp4"] + (["poster.jpg"] if (out / "poster.jpg").exists() else [])
    metrics["outputs"] = sorted(outputs)
    metrics = ordered_metrics(metrics)
    try:
        (out / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n", encoding="utf-8")
        write_report(out / "report.html", {RUN_NAME: metrics}, summary_sentence(metrics),
                     title=f"Lanewarden replay: {source.name} ({source.kind})",
                     folders={RUN_NAME: ""},
                     labels={"sim_time_s": "recorded time replayed (s)"})  # not simulated
    except OSError as exc:
        raise OutputError(f"{out}: cannot write the replay's outputs ({exc})") from exc
    folder.finish()
    return metrics


def _write_plot(path: Path, source: ReplaySource, records: list[Any], times: list[float],
                config: LanewardenConfig, halt: int | None, last: int | None) -> None:
    """plot.png; `halt`: the index of the first halt after engaging (`first_halt`), and `last`,
    the halt the run ended in (`ending_halt`), marked."""
    t0 = times[0] if times else 0.0
    markers = [] if halt is None else [PlotMarker("HALT", records[halt].time_s - t0)]
    if last is not None and last != halt:
        markers.append(PlotMarker("HALT that ended the run", records[last].time_s - t0))
    states = [r.state for r in records]
    write_plot(
        path, f"replay of {source.name} ({source.kind})",
        np.asarray([t - t0 for t in times[:len(records)]], dtype=np.float64),
        [None if r.observation is None else r.observation.slope_sum for r in records],
        [r.filtered_slope_sum for r in records],
        [None if r.observation is None else r.observation.confidence for r in records],
        states,
        state_reasons(states, [r.events for r in records], [r.halt_reason for r in records]),
        config.supervisor.turn_enter_slope_sum,
        markers,
    )


def _loop_end(source: ReplaySource) -> LoopEnd:
    return recorded_loop_end(source.summary) if source.kind == "run" else CLIP_END


def _run_end(source: ReplaySource, records: list[Any]) -> EndReason:
    return end_reason_of(((r.state, r.halt_reason, r.time_s, r.frame_time_s) for r in records),
                         _loop_end(source))


def _loop_records(source: ReplaySource, records: list[Any]) -> list[Any]:
    """The records of the run's loop: not the runner's closing stop after it."""
    steps = _loop_end(source).steps
    return records if steps is None else records[:steps]


def first_halt(source: ReplaySource, records: list[Any], end: EndReason) -> int | None:
    """The first halt after engaging, as the run's end reason counts halts: not the runner's
    closing stop (the steps after the loop's end) and not a clip's own end (a run that was
    engaged when its clip ran out: `end.state` is not HALT), which `replay` had reported as
    `halted: true` with no reason."""
    considered = _loop_records(source, records)
    if end.kind is LoopEndKind.CLIP and end.state != "HALT":
        while considered and considered[-1].state == "HALT":
            considered = considered[:-1]
    # (`first_halt_index` says 0 for steps that never engaged: no halt after engaging)
    return first_halt_index([r.state for r in considered]) or None


def ending_halt(source: ReplaySource, records: list[Any], end: EndReason) -> int | None:
    """Where the halt the run ended in began: the start of its last stretch of HALT after
    engaging, the runner's closing stop not counted; None when it ended engaged (or never
    engaged). A run stopped and resumed from the page had been described by its first halt,
    the operator's stop, not by the one that ended it (an instructor's review)."""
    considered = _loop_records(source, records)
    if (end.kind is LoopEndKind.CLIP and end.state != "HALT") or not considered \
            or considered[-1].state != "HALT":
        return None
    start = len(considered) - 1
    while start > 0 and considered[start - 1].state == "HALT":
        start -= 1
    return start or None  # (0: it never engaged)


def replay_metrics(source: ReplaySource, records: list[Any], divergences: list[Divergence],
                   distance_m: float, config: LanewardenConfig | None = None, *,
                   found: tuple[EndReason, int | None, int | None] | None = None
                   ) -> dict[str, Any]:
    """Numbers for metrics.json (the keys `sim` uses where they apply); with the `config` the
    steps ran under, `before_halt` too (what perception gave the supervisor before the halt the
    run ended in). `found`: the run's end reason, first halt and ending halt when the caller has
    them already (`_run_end`, `first_halt`, `ending_halt`)."""
    states: list[str] = []
    for record in records:
        if record.state not in states:
            states.append(record.state)
    if found is None:
        end = _run_end(source, records)
        found = end, first_halt(source, records, end), ending_halt(source, records, end)
    end, halt, last = found
    first_time = records[0].time_s if records else 0.0
    engaged_steps = sum(r.state != "HALT" for r in records)
    missing = missing_frames(source)
    recorded_complete = bool(source.summary.get("complete", True))
    metrics: dict[str, Any] = {
        "scenario": source.name,
        "source_kind": source.kind,
        "frames": len({r.frame_index for r in records if r.frame_index is not None}),
        "steps": len(records),
        "sim_time_s": round(records[-1].time_s - first_time, 4) if records else 0.0,
        "halted": halt is not None,
        "end_reason": end.text,
        "halt_reason": end.halt_reason,
        "first_halt_reason": records[halt].halt_reason if halt is not None else None,
        "first_halt_time_s": round(records[halt].time_s - first_time, 4) if halt else None,
        # the halt the run ended in (as `run`'s summary describes it), when it ended halted
        "halt_time_s": round(records[last].time_s - first_time, 4) if last else None,
        "final_state": end.state if records else None,
        "states_visited": states,
        "engaged_fraction": round(engaged_steps / len(records), 4) if records else 0.0,
        "distance_travelled_m": round(distance_m, 4),
        # why the recording (a run, a bag) is not whole: replayed as far as it goes
        "incomplete": list(source.incomplete),
    }
    if config is not None:
        # what perception gave before the safety stop that ended the run, as `run`'s summary
        # says it; an operator's stop is no such halt (a replay of space, r, Ctrl-C had printed
        # "before the halt")
        operator = last is not None and halt_event(records[last].halt_reason or "") in NORMAL_HALTS
        metrics["before_halt"] = None if last is None or operator else before_halt(
            records, last, config.supervisor, config.perception.edges.max_abs_slope)
    # frames that are there but did not decode: the loop got no frame at those steps
    wanted = frame_indices(source)
    if stream_end := source.frames.stream_end():  # (none beyond it exists; at 0: damaged)
        wanted = {i for i in wanted if i < stream_end}
    if source.kind != "run":
        metrics["frames_undecoded"] = sorted(wanted - {r.frame_index for r in records})
    else:  # (a run's frames dropped while recording are `frames_missing`, not these)
        metrics["frames_undecoded"] = sorted(wanted & source.frames.undecoded)
    if source.kind == "run":
        exact_input = (missing == 0 and recorded_complete and not source.incomplete
                       and not metrics["frames_undecoded"]
                       and bool(source.meta.get("lossless")))
        metrics.update(
            compared_steps=len(records),
            divergent_steps=len(divergences),
            first_divergence=None if not divergences else {
                "step": divergences[0].step, "time_s": divergences[0].time_s,
                "what": divergences[0].what, "recorded": divergences[0].recorded,
                "replayed": divergences[0].replayed, "text": divergences[0].describe()},
            reproduced=not divergences,
            frames_missing=missing,
            exact_input=exact_input,
            recorded_exit_code=source.summary.get("exit_code"),
        )
    return metrics


def summary_sentence(metrics: dict[str, Any]) -> str:
    text = (f"Replayed {metrics['steps']} steps ({metrics['frames']} frames, "
            f"{metrics['sim_time_s']} s) of {metrics['scenario']} ({metrics['source_kind']}); "
            f"states visited: {', '.join(metrics['states_visited'])}; final state "
            f"{metrics['final_state']}; the run ended: {metrics['end_reason']}.")
    if metrics["source_kind"] == "run":
        if metrics["divergent_steps"] == 0:
            text += f" Every step reproduced the recording ({metrics['compared_steps']} steps)."
        else:
            text += (f" {metrics['divergent_steps']} of {metrics['compared_steps']} steps diverge "
                     f"from the recording; the first: {metrics['first_divergence']['text']}.")
        if not metrics["incomplete"] and not metrics["exact_input"]:
            text += (" The recording is not exact (frames dropped, undecodable or lossy), so "
                     "the replay cannot be exact either.")
    if metrics["incomplete"]:
        text += f" The recording is incomplete: {'; '.join(metrics['incomplete'])}."
    return text
