"""The closed loop in simulation: the robot's own runtime driven by a synthetic camera and base.

    SimBase (true pose) -> CameraRenderer -> SimCamera (faults) -> ControlLoop(LaneDetector,
    SafetyGate(SupervisedController | LectureController)) -> SimBase

On a fake clock at the camera rate: each tick advances the simulated base to `now`, renders the
frame the camera sees at the true pose, applies the scenario's faults, and calls
`loop.step(now)` (the same step the robot runner calls). `loop.start(0)` is the explicit start;
the supervisor engages by itself after its confident frames. The stack between camera and base
(detector, controller, gate, loop) is not wired here: it comes from the composition root's
`build_stack` (lanewarden/assembly.py), passed in by the caller, with the true calibration of the
simulated camera for perception to undistort with. Ground-truth metrics come from the world.

Never reads a clock (wall time is measured by the caller) and never writes files itself: the
run's records, video frames, camera images and progress go to callbacks the caller passes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D, VelocityCommand
from lanewarden.actuation.sim_base import SimBase, SimBaseParams
from lanewarden.perception.overlay import draw_detection
from lanewarden.scenarios.before_halt import before_halt
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.camera_effects import CameraEffects
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.false_lane import false_lane_metrics, frame_edge_errors
from lanewarden.scenarios.fault_link import FaultyLink
from lanewarden.scenarios.faults import FaultEffect, FaultSchedule, camera_pool_size, floor_marks
from lanewarden.scenarios.highlights import Highlights
from lanewarden.scenarios.metrics import (
    LaneContrast,
    RunTrace,
    TapeVisibility,
    compute_metrics,
    fault_to_halt,
    first_halt_index,
    motion_after_halt,
)
from lanewarden.scenarios.render import CameraRenderer
from lanewarden.scenarios.sim_camera import SimCamera
from lanewarden.scenarios.spec import CameraSpec, RunSpec, ScenarioSpec, with_overrides
from lanewarden.scenarios.texture import (
    GroundTexture,
    paint_ground,
    paint_ground_cached,
    with_marks,
)
from lanewarden.scenarios.world import World, build_world
from lanewarden.supervisor.loop import StepRecord
from lanewarden.supervisor.watchdog import mark_capture

if TYPE_CHECKING:
    from lanewarden.assembly import BuildStack
    from lanewarden.config import LanewardenConfig
    from lanewarden.scenarios.video import VideoRecorder

U8 = NDArray[np.uint8]

#: A run that has not engaged after this long ends (nothing will move).
NOT_ENGAGED_LIMIT_S = 5.0
#: The run ends when the robot's centre comes this close to the edge of the painted floor.
WORLD_EDGE_MARGIN_M = 1.0
#: The video's camera view is rendered from a floor texture this many times coarser.
DISPLAY_TEXTURE_FACTOR = 2
#: Below this the base counts as at rest (for ending a run after a HALT).
AT_REST_M_S = 1e-3


@dataclass
class SimulationResult:
    """One finished run: the metrics, every step record and the true trajectory."""

    spec: ScenarioSpec
    controller: str
    seed: int
    world: World
    metrics: dict[str, object]
    records: list[StepRecord]
    trace: RunTrace
    end_reason: str
    #: the first frame where each fault took effect (by its place in the scenario's list)
    fault_effects: dict[int, FaultEffect] = field(default_factory=dict)
    #: (index, kind, from_s, to_s) while each fault that took effect was acting
    fault_windows: list[tuple[int, str, float, float]] = field(default_factory=list)


def effective_config(config: LanewardenConfig, spec: ScenarioSpec,
                     source: str | None = None) -> LanewardenConfig:
    """The config a scenario runs with: `config` plus the scenario's own `config:` overrides;
    a camera block's size becomes `simulation.width_px`/`height_px` (the render size's one home
    during the run); a perception that takes colour apart (`perception.gray.yellow_boost`) gets
    colour frames (`simulation.perception_color`), as from a robot's colour camera."""
    where = source or f"scenario {spec.name}"
    config = with_overrides(config, spec.config, where)
    camera = spec.camera
    if camera is not None and camera.width_px is not None:
        config = with_overrides(config, {"simulation": {
            "width_px": camera.width_px, "height_px": camera.height_px}}, where)
    if config.perception.gray.yellow_boost > 0.0 and not config.simulation.perception_color:
        config = with_overrides(config, {"simulation": {"perception_color": True}}, where)
    return config


def camera_model_of(camera: CameraSpec | None, width_px: int, height_px: int) -> CameraModel:
    """The camera a scenario's `camera:` block describes (None: the default camera) at a size."""
    if camera is None:
        return CameraModel(width_px=width_px, height_px=height_px)
    return CameraModel(width_px=width_px, height_px=height_px, hfov_deg=camera.hfov_deg,
                       height_m=camera.height_m, pitch_down_deg=camera.pitch_deg,
                       roll_deg=camera.roll_deg, forward_offset_m=camera.forward_m,
                       dist_coeffs=camera.distortion)


#: The most memory the simulated camera's own frame buffers may take, bytes: its pool (frames
#: kept to serve a `late_frames` latency) and its noise bank (float32 frames). A 1920x1440 colour
#: camera at 120 Hz with a 5 s latency and 64 noise frames took 7.5 GB, without a word (an
#: attacker's review); the defaults at the largest camera take 0.4 GB.
MAX_CAMERA_BUFFER_BYTES = 2 * 2**30


def camera_buffers_problem(spec: ScenarioSpec, config: LanewardenConfig) -> str:
    """'' when the simulated camera's buffers fit MAX_CAMERA_BUFFER_BYTES, else why not and
    what makes them large (checked before anything is painted or written)."""
    sim = config.simulation
    channels = 3 if sim.perception_color else 1
    frame = sim.width_px * sim.height_px * channels
    pool = camera_pool_size(spec.faults, sim.camera_rate_hz)
    noise = max(1, sim.noise_bank_frames)
    total = frame * (pool + 4 * noise)  # (the noise frames are float32)
    if total <= MAX_CAMERA_BUFFER_BYTES:
        return ""
    return (f"the simulated camera's buffers would take {total / 2**30:.1f} GB, more than "
            f"{MAX_CAMERA_BUFFER_BYTES / 2**30:g} GB: {pool} frames of {sim.width_px}x"
            f"{sim.height_px}{' colour' if channels == 3 else ''} kept to serve late frames at "
            f"simulation.camera_rate_hz {sim.camera_rate_hz:g}, and {noise} noise frames "
            "(simulation.noise_bank_frames); expected a smaller camera, a lower rate, a shorter "
            "late_frames latency or fewer noise frames")


def sim_camera_model(config: LanewardenConfig, camera: CameraSpec | None = None) -> CameraModel:
    """The simulated camera: the scenario's camera block (default: CameraModel's geometry) at
    the configured resolution (see `effective_config`). With `simulation.rectified_frames` its
    frames come out rectified (no lens distortion), as from a driver that rectifies."""
    width, height = config.simulation.width_px, config.simulation.height_px
    if camera is not None and camera.width_px is not None and (
            camera.width_px, camera.height_px) != (width, height):
        raise ScenarioError(
            f"camera block: {camera.width_px}x{camera.height_px} px but the config renders "
            f"{width}x{height} px (build the config with effective_config)")
    model = camera_model_of(camera, width, height)
    if config.simulation.rectified_frames:
        model = replace(model, dist_coeffs=(0.0, 0.0, 0.0, 0.0, 0.0))
    return model


class Simulation:
    """One run of one scenario with one controller. Build, then `run()` once.

    `build_stack`: the composition root's `lanewarden.assembly.build_stack` (passed in, so this
    layer never imports the CLI side)."""

    def __init__(
        self,
        spec: ScenarioSpec,
        config: LanewardenConfig,
        build_stack: BuildStack,
        *,
        controller: str = "supervised",
        seed: int = 0,
        video_path: Path | None = None,
        record: Callable[[StepRecord], None] | None = None,
        progress: Callable[[float], None] | None = None,
        camera_frames: Callable[[U8, float], None] | None = None,
    ) -> None:
        """`record`, `progress` and `camera_frames` are the caller's: each step's record, the
        simulated time, and each captured camera image (the sensor's raw view, before any
        driver fault) with its time."""
        self.spec = spec
        self.config = config
        self.controller_name = controller
        self.seed = seed
        self._progress = progress
        self._camera_frames = camera_frames
        sim = config.simulation
        if problem := camera_buffers_problem(spec, config):
            raise ScenarioError(f"{spec.name}: {problem}")
        self.camera = sim_camera_model(config, spec.camera)
        self.world = build_world(spec, margin_m=sim.world_margin_m)
        # The painted floor depends only on these (and is reused by a campaign's worker); floor
        # faults are painted over a copy.
        # (The room's brightness, colour and changes are the camera's to answer, not painted: runs
        # under other light share the floor.)
        painted_light = spec.lighting.model_dump_json(include={"gradient", "glare"}) + repr(
            spec.lighting.ceiling is None)
        floor_key = spec.model_dump_json(include={"floor", "tape", "lane"}) + painted_light + repr(
            sim.world_margin_m)
        self.texture: GroundTexture = with_marks(
            paint_ground_cached(self.world, floor_key, sim.texture_mm_per_px / 1000.0, seed,
                                color=sim.perception_color),
            floor_marks(self.world, spec.faults))
        camera_spec = spec.camera or CameraSpec()
        channels = 3 if sim.perception_color else 1
        self.effects = CameraEffects(
            camera_spec, self.world.lighting, self.camera, channels=channels, seed=seed,
            noise_bank_frames=sim.noise_bank_frames, frame_period_s=1.0 / sim.camera_rate_hz)
        self.renderer = CameraRenderer(
            self.texture, self.camera, seed=seed, effects=self.effects,
            highlights=self._highlights())
        w, h = self.camera.width_px, self.camera.height_px
        self.calibration = self.camera.calibration()  # with its ground pose, as on a robot
        self.stack = build_stack(config, controller=controller, calibration=self.calibration,
                                 debug_tap=video_path is not None)
        self.detector = self.stack.detector
        self.base = SimBase(self.world.start_pose, SimBaseParams.from_config(config.actuation))
        self.link = FaultyLink(self.base, config.actuation.write_timeout_s, seed)
        shape: tuple[int, ...] = (h, w, 3) if sim.perception_color else (h, w)
        self.sim_camera = SimCamera(shape, camera_pool_size(spec.faults, sim.camera_rate_hz))
        self.faults = FaultSchedule(spec.faults, self.world, shape)
        self.loop = self.stack.connect(self.sim_camera, self.link, record)
        self.roi_polygon_px = self._roi_polygon()
        self.visibility = TapeVisibility(self.world, self.camera, self.roi_polygon_px)
        perception = config.perception
        self.lane_contrast = LaneContrast(
            self.world, self.camera, self.roi_polygon_px,
            perception.tape.min_contrast_levels / perception.contrast.max_gain,
            perception.gray.yellow_boost)
        self._contrast = np.full(self.lane_contrast.tapes, np.nan)
        self._video: VideoRecorder | None = None
        self._video_path = video_path
        self._view_bgr = np.empty((h, w, 3), np.uint8)
        # The video shows the undistorted view (what perception analyses, where its overlay
        # coordinates live), rendered directly from a colour painting of the same world at half
        # the resolution (same seed: same tiles, seams, tapes and light), without sensor noise
        # or motion blur: display only.
        self._display: CameraRenderer | None = None
        self.display_texture: GroundTexture | None = None
        if video_path is not None:
            self.display_texture = with_marks(paint_ground(
                self.world, DISPLAY_TEXTURE_FACTOR * sim.texture_mm_per_px / 1000.0, seed,
                color=True), floor_marks(self.world, spec.faults))
            self._display = CameraRenderer(
                self.display_texture, self.camera, seed=seed, distorted=False,
                effects=CameraEffects(camera_spec, self.world.lighting, self.camera,
                                      channels=3, frame_period_s=1.0 / sim.camera_rate_hz,
                                      display=True),
                highlights=self._highlights())

    def _highlights(self) -> Highlights | None:
        """The ceiling lights' highlights on this world's glossy surfaces (None: no lights)."""
        ceiling = self.world.lighting.ceiling
        if ceiling is None:
            return None
        return Highlights(ceiling, self.camera, self.world.floor.roughness_rad)

    def _roi_polygon(self) -> NDArray[np.float64]:
        """Perception's ROI in undistorted pixels, asked from the detector itself (one detection
        on the start frame, outside the run)."""
        w, h = self.camera.width_px, self.camera.height_px
        if self.config.simulation.perception_color:
            image = self.renderer.render_bgr(self.world.start_pose, np.empty((h, w, 3), np.uint8))
        else:
            image = self.renderer.render_gray(self.world.start_pose, np.empty((h, w), np.uint8))
        _, debug = self.detector.detect_debug(image, -1, 0.0)
        return np.asarray(debug.roi_polygon_px, dtype=np.float64)

    def run(self) -> SimulationResult:
        sim = self.config.simulation
        spec = self.spec
        dt = 1.0 / sim.camera_rate_hz
        ticks, overtime = tick_limits(spec.run.max_time_s, sim.camera_rate_hz,
                                      self.config.supervisor.degraded_budget_s)
        video_every = max(1, round(sim.camera_rate_hz / sim.video.fps))
        if self._video_path is not None:
            from lanewarden.scenarios.video import MapView, VideoRecorder, roi_ground_outline

            assert self.display_texture is not None
            map_view = MapView(self.world, self.display_texture, sim.video.map_size_px,
                               roi_ground_outline(self.camera, self.roi_polygon_px))
            self._video = VideoRecorder(
                self._video_path, (self.camera.width_px, self.camera.height_px), map_view,
                sim.camera_rate_hz / video_every, sim.video.crf,
                sim.video.preset, title=f"{spec.name}, {self.controller_name} controller")

        times: list[float] = []
        poses: list[tuple[float, float, float]] = []
        speeds: list[float] = []
        records: list[StepRecord] = []
        visible: list[bool] = []
        contrasts: list[NDArray[np.float64]] = []
        lane_ends = self.world.markings_end_s is not None
        ending = EndConditions(self.world, spec.run)
        end_reason = "time limit"
        try:
            for k in range(ticks + overtime):
                if k >= ticks and (not records or records[-1].state != "DEGRADED"):
                    break
                now = k * dt
                pose, velocity = self._capture(k, now)
                if k == 0:
                    self.loop.start(now)
                if self.faults.loop_stalled:
                    self.faults.stalled_tick(k, now)
                    continue
                record = self.loop.step(now)
                self.faults.observe(k, now, self.sim_camera, self.link, self.visibility, pose)
                records.append(record)
                times.append(now)
                poses.append((pose.x_m, pose.y_m, pose.theta_rad))
                speeds.append(abs(velocity.linear_m_s))
                contrasts.append(self._contrast)
                if lane_ends:
                    # Only the first frame without tape in view matters (metrics): stop there.
                    seen = not visible or visible[-1]
                    visible.append(self.visibility.visible(pose) if seen else False)
                if self._video is not None:
                    self._video.step(pose, record)
                    if k % video_every == 0:
                        self._add_video_frame(k, now, pose, record)
                if self._progress is not None:
                    self._progress(now)
                reason = ending.check(now, record.state, pose, self.base.velocity.linear_m_s)
                if reason == "halted" and self.faults.pending:
                    continue  # every fault is applied, even after a halt (or it is unproven)
                if reason is not None:
                    end_reason = reason
                    break
        finally:
            self.base.close()
            if self._video is not None:
                self._video.close()

        trace = RunTrace(
            time_s=np.asarray(times), poses=np.asarray(poses, dtype=np.float64).reshape(-1, 3),
            states=[r.state for r in records], halt_reasons=[r.halt_reason for r in records],
            events=[r.events for r in records], speed_m_s=np.asarray(speeds),
            lane_contrast=np.asarray(contrasts, dtype=np.float64).reshape(
                -1, self.lane_contrast.tapes),
            lane_visible=np.asarray([self.lane_contrast.visible(c) for c in contrasts],
                                    dtype=bool))
        metrics = compute_metrics(
            self.world, trace, np.asarray(visible, dtype=bool) if lane_ends else None,
            self.visibility.loss_arc_length(self.world) if lane_ends else None)
        metrics.update(false_lane_metrics(
            trace.time_s, frame_edge_errors(self.world, trace.time_s, trace.poses, records)))
        metrics["end_reason"] = end_reason
        halt = first_halt_index(trace.states)
        metrics["motion_after_halt"] = motion_after_halt(
            trace.time_s, trace.states, [not r.command.is_stop for r in records],
            float(trace.speed_m_s[-1]) if len(trace.speed_m_s) else 0.0)
        effects = sorted(self.faults.effects.items())
        metrics["fault_count"] = len(spec.faults)
        metrics["fault_effects"] = [e.as_json() for _, e in effects]
        metrics["fault_to_halt"] = fault_to_halt(
            [(i, e.kind, e.time_s) for i, e in effects],
            float(trace.time_s[halt]) if halt else None)
        metrics["before_halt"] = None if not halt else before_halt(
            records, halt, self.config.supervisor, self.config.perception.edges.max_abs_slope)
        if self._video is not None and self._video.poster_shows is not None:
            metrics["video_poster"] = {"shows": self._video.poster_shows,
                                       "time_s": self._video.poster_time_s}
        run_end = float(times[-1]) if times else 0.0
        return SimulationResult(spec, self.controller_name, self.seed, self.world, metrics,
                                records, trace, end_reason, dict(self.faults.effects),
                                self.faults.windows(run_end))

    def _capture(self, k: int, now: float) -> tuple[Pose2D, VelocityCommand]:
        """Faults due now, the base moved to now, and the camera's frame at the true pose."""
        self.faults.apply(now, self.sim_camera, self.link, self.loop, k)
        self.base.advance_to(now)
        pose = self.base.pose
        velocity = self.base.velocity
        motion = (velocity.linear_m_s, velocity.angular_rad_s)
        noise = self.renderer.next_noise_index()
        buffer = self.sim_camera.buffer()
        if self.config.simulation.perception_color:
            self.renderer.render_bgr(pose, buffer, motion, noise, now)
        else:
            self.renderer.render_gray(pose, buffer, motion, noise, now)
        # A real sensor's noise never repeats; the noise bank's dozen frames do, and a robot
        # standing still would show the watchdog an image it saw a few frames before.
        mark_capture(buffer, k)
        self.faults.after_render(k, now, buffer)
        # Ground truth: what the delivered frame shows of the lane (the campaign judge's).
        self._contrast = self.lane_contrast.measure(buffer, pose)
        self.sim_camera.capture(k, now)
        if self._camera_frames is not None:
            self._camera_frames(buffer, now)
        return pose, velocity

    def _add_video_frame(self, k: int, now: float, pose: Pose2D, record: StepRecord) -> None:
        assert self._video is not None
        assert self._display is not None
        velocity = self.base.velocity
        undistorted = self._display.render_bgr(
            pose, self._view_bgr, (velocity.linear_m_s, velocity.angular_rad_s), now=now)
        tap = self.stack.tap.last if self.stack.tap is not None else None
        detection = None
        if tap is not None and tap[0] == k and record.observation is not None:
            _, observation, debug = tap
            draw_detection(undistorted, observation, debug)
            detection = (observation, self.stack.decide(observation))
        self._video.add(undistorted, pose, now, record, detection)


def tick_limits(max_time_s: float, camera_rate_hz: float,
                degraded_budget_s: float) -> tuple[int, int]:
    """(ticks, overtime): a run steps ticks 0 .. ticks - 1 (to its time limit, s); one whose time
    is up while DEGRADED goes on until the supervisor decides (back to following, or HALT), at
    most `overtime` more ticks (its DEGRADED time budget, s, and two): otherwise undecided. No
    run steps a tick beyond these."""
    ticks = int(math.floor(max_time_s * camera_rate_hz + 1e-9)) + 1
    overtime = int(math.ceil(degraded_budget_s / (1.0 / camera_rate_hz))) + 2
    return ticks, overtime


def latest_time_s(config: LanewardenConfig, run: RunSpec) -> float:
    """The latest simulated time a run can reach (`tick_limits`), s: a bound on its length."""
    rate_hz = config.simulation.camera_rate_hz
    ticks, overtime = tick_limits(run.max_time_s, rate_hz, config.supervisor.degraded_budget_s)
    return (ticks + overtime - 1) / rate_hz


class EndConditions:
    """When a run is over (pure: fed each step's time, state, true pose and speed).

    - "halted": `halt_settle_s` after the first HALT that followed engagement, once at rest;
    - "never engaged": still not engaged after NOT_ENGAGED_LIMIT_S;
    - "left the painted floor": the robot came within WORLD_EDGE_MARGIN_M of its edge;
    - "<d> m past the lane end": `stop_past_lane_end_m` past the end of the markings (not
      halted). The time limit is the caller's loop bound.
    """

    def __init__(self, world: World, run: RunSpec) -> None:
        self._world = world
        self._run = run
        self._end = world.lane_end()
        self.engaged = False
        self.halt_time: float | None = None

    def check(self, now: float, state: str, pose: Pose2D, speed_m_s: float) -> str | None:
        if state != "HALT":
            self.engaged = True
        elif self.engaged and self.halt_time is None:
            self.halt_time = now
        if self.halt_time is not None:
            settled = now - self.halt_time >= self._run.halt_settle_s
            return "halted" if settled and abs(speed_m_s) < AT_REST_M_S else None
        if not self.engaged and now >= NOT_ENGAGED_LIMIT_S:
            return "never engaged"
        if not self._world.inside_bounds(pose.x_m, pose.y_m, WORLD_EDGE_MARGIN_M):
            return "left the painted floor"
        if self._end is not None:
            point, heading = self._end
            past = (pose.x_m - point[0]) * math.cos(heading) + (
                pose.y_m - point[1]) * math.sin(heading)
            if past >= self._run.stop_past_lane_end_m:
                return f"{self._run.stop_past_lane_end_m:g} m past the lane end"
        return None
