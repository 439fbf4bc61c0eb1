"""How close rendered frames come to real ones: a few statistics of a frame sequence, measured the
same way on both.

Per frame, inside the detector's region of interest (the floor it analyses): the mean grey
level, the RMS contrast (standard deviation over mean), a noise level (Immerkaer's estimator:
the mean absolute response of a Laplacian-difference kernel that ignores smooth shading, in grey
levels; fine texture counts too) and the edge density (the share of ROI pixels the detector's
own Canny marks, read from its edge buffer after `detect`). Over the sequence, run through the
detector frame by frame with the previous observation (as the control loop does): the share of
frames with both edges, the share that are confident (both edges and the supervisor's
`confidence_confident_min`), and the lengths of the confident runs (the supervisor engages only
after `engage_confident_frames` confident frames in a row).

`drive_sequence` renders what a camera sees driving along a world's lane with a gentle weave,
through the simulator's renderer and camera effects, for the same statistics on a rendered
course of the real one's kind.

Pure measurement: never writes files (the figure and table are `benchmarks/realism.py`'s),
never reads a clock (frame times are given).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D
from lanewarden.perception.detector import LaneDetector, perception_gray
from lanewarden.perception.observation import LaneObservation
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.camera_effects import CameraEffects
from lanewarden.scenarios.highlights import Highlights
from lanewarden.scenarios.render import CameraRenderer
from lanewarden.scenarios.spec import CameraSpec, ScenarioSpec, merge_overrides, parse_scenario
from lanewarden.scenarios.texture import paint_ground
from lanewarden.scenarios.world import World, build_world

U8 = NDArray[np.uint8]

#: Immerkaer's noise kernel: zero on planes and linear shading.
_NOISE_KERNEL = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], np.float32)


@dataclass(frozen=True)
class FrameStats:
    """One frame, inside the detector's ROI: grey levels (0..255) and shares (0..1)."""

    mean_level: float
    rms_contrast: float
    noise_levels: float
    edge_density: float


def noise_levels(gray: U8, mask: U8 | None = None) -> float:
    """Immerkaer's (1996) noise standard deviation estimate, grey levels, over `mask` (nonzero)
    where given."""
    response = np.abs(cv2.filter2D(gray.astype(np.float32), -1, _NOISE_KERNEL,
                                   borderType=cv2.BORDER_REFLECT))[1:-1, 1:-1]
    if mask is not None:
        inner = mask[1:-1, 1:-1] > 0
        if not inner.any():
            return 0.0
        response = response[inner]
    return float(math.sqrt(math.pi / 2.0) / 6.0 * float(np.mean(response)))


def frame_stats(detector: LaneDetector, gray: U8) -> FrameStats:
    """The statistics of `gray` (already analysed by `detector.detect`: its smoothed buffer
    holds this frame as Canny saw it) inside the detector's ROI. The edge density is Canny's at
    the configured thresholds, as the texture gives it, not what perception kept within its
    edge budget (`perception.canny.max_edge_share`): it compares rendered floors with real
    ones."""
    h, w = gray.shape[:2]
    setup = detector.setup_for(w, h)
    mask = setup.mask > 0
    values = gray[mask].astype(np.float64)
    mean = float(values.mean()) if values.size else 0.0
    canny = detector.config.canny
    edges = cv2.Canny(setup.smooth, canny.low_threshold, canny.high_threshold,
                      apertureSize=canny.aperture_px)
    return FrameStats(
        mean_level=mean,
        rms_contrast=float(values.std() / mean) if mean > 0 else 0.0,
        noise_levels=noise_levels(gray, setup.mask),
        edge_density=float(np.count_nonzero(edges[mask]) / max(values.size, 1)))


def confident_runs(confident: Iterable[bool]) -> list[int]:
    """Lengths of the runs of consecutive True values, in order."""
    runs: list[int] = []
    current = 0
    for value in confident:
        if value:
            current += 1
        elif current:
            runs.append(current)
            current = 0
    if current:
        runs.append(current)
    return runs


@dataclass(frozen=True)
class SequenceStats:
    """A sequence through the detector: per-frame means, and how its confidence came."""

    frames: int
    mean_level: float
    rms_contrast: float
    noise_levels: float
    edge_density: float
    both_edges_share: float
    confident_share: float
    runs: tuple[int, ...]
    #: photos, each judged on its own: `runs` mean nothing
    stills: bool = False

    @property
    def longest_run(self) -> int:
        return max(self.runs, default=0)

    def runs_at_least(self, frames: int) -> int:
        """How many confident runs are long enough to engage on (`frames` in a row)."""
        return sum(1 for r in self.runs if r >= frames)


def sequence_stats(detector: LaneDetector, frames: Iterable[U8], times_s: Sequence[float],
                   confident_min: float, stills: bool = False) -> SequenceStats:
    """Run `frames` (gray or BGR) through `detector` in order, each with the previous
    observation, and measure them (see the module docstring). `stills`: photos, not a
    sequence: each frame on its own (no previous observation; its runs mean nothing)."""
    per_frame: list[FrameStats] = []
    both: list[bool] = []
    confident: list[bool] = []
    previous: LaneObservation | None = None
    for index, (frame, time_s) in enumerate(zip(frames, times_s, strict=False)):
        observation = detector.detect(frame, index, time_s, previous)
        previous = None if stills else observation
        gray = perception_gray(frame, yellow_boost=detector.config.gray.yellow_boost)
        if detector.undistorter is not None:
            gray = detector.undistorter.apply(gray)
        per_frame.append(frame_stats(detector, np.asarray(gray, np.uint8)))
        both.append(observation.left is not None and observation.right is not None)
        confident.append(both[-1] and observation.confidence >= confident_min)
    n = len(per_frame)
    if n == 0:
        return SequenceStats(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, ())
    return SequenceStats(
        frames=n,
        mean_level=float(np.mean([s.mean_level for s in per_frame])),
        rms_contrast=float(np.mean([s.rms_contrast for s in per_frame])),
        noise_levels=float(np.mean([s.noise_levels for s in per_frame])),
        edge_density=float(np.mean([s.edge_density for s in per_frame])),
        both_edges_share=sum(both) / n,
        confident_share=sum(confident) / n,
        runs=tuple(confident_runs(confident)), stills=stills)


def drive_sequence(world: World, renderer: CameraRenderer, frames: int, rate_hz: float,
                   speed_m_s: float, seed: int, color: bool = False) -> list[U8]:
    """What `renderer`'s camera sees driving the lane from its start at `speed_m_s`, weaving
    gently (a few centimetres and degrees, seeded), one frame per 1 / `rate_hz`."""
    rng = np.random.default_rng([seed, 0xD21E])
    phase = rng.uniform(0.0, 2 * math.pi, 2)
    w, h = renderer.size
    out: list[U8] = []
    for k in range(frames):
        t = k / rate_hz
        s = min(0.05 + speed_m_s * t, world.centreline.length_m)
        point, heading = world.centreline.at(s)
        offset = 0.04 * math.sin(0.9 * t + phase[0])
        turn = math.radians(4.0) * math.sin(1.3 * t + phase[1])
        pose = Pose2D(point[0] - offset * math.sin(heading), point[1] + offset * math.cos(heading),
                      heading + turn)
        yaw_rate = math.radians(4.0) * 1.3 * math.cos(1.3 * t + phase[1])
        image = np.empty((h, w, 3) if color else (h, w), np.uint8)
        noise = renderer.next_noise_index()
        if color:
            renderer.render_bgr(pose, image, (speed_m_s, yaw_rate), noise, t)
        else:
            renderer.render_gray(pose, image, (speed_m_s, yaw_rate), noise, t)
        out.append(image)
    return out


# ---- a rendered course of the Donkeycar tub's kind ---------------------------------------------
#: The Donkeycar tub's track (../shared/data/donkeycar-tub) as a scenario: a yellow dashed line
#: on the left and a white line on the right, 50 mm wide, 0.60 m apart, on a dark olive-grey
#: sealed floor in a hall with lights 6 m up; its camera as `tests/perception/donkeycar_camera.
#: yaml` describes it (160x120, 100 deg, 0.23 m up, pitched 19.7 deg, no distortion model).
TUB_LIKE: dict[str, object] = {
    "name": "tub-like",
    "floor": {"kind": "concrete", "color": "#5f6356", "colors": ["#54574c"], "seam_m": 0.0,
              "cracks_per_m2": 0.05, "gloss": 0.04, "roughness_rad": 0.04},
    "tape": {"width_m": 0.05, "color": "#f0f0ec", "left": {"color": "#e6b422"}},
    "lane": {"width_m": 0.60, "dashes": {"tape": "left", "on_m": 0.2, "off_m": 0.2},
             "segments": [{"straight_m": 2.0}, {"arc_radius_m": 1.5, "turn_deg": 90},
                          {"straight_m": 1.0}, {"arc_radius_m": 1.5, "turn_deg": -90},
                          {"straight_m": 2.0}, {"arc_radius_m": 2.0, "turn_deg": 180},
                          {"straight_m": 4.0}]},
    "lighting": {"ceiling": {"height_m": 6.0, "spacing_m": [4.0, 4.0], "size_m": 1.0,
                             "reach_m": 40.0}},
    "camera": {"width_px": 160, "height_px": 120, "hfov_deg": 100.0, "height_m": 0.23,
               "pitch_deg": 19.7, "forward_m": 0.0, "distortion": [0.0, 0.0, 0.0, 0.0, 0.0]},
}

#: The rendered sets compared with the real frames: (name, changes to TUB_LIKE, camera effects
#: on). The first is the renderer as it was before camera effects, glossy floors and highlights.
RENDERED_SETS: tuple[tuple[str, dict[str, object], bool], ...] = (
    ("rendered, plain (no camera effects)",
     {"floor": {"kind": "plain", "color": "#5f6356"}, "lighting": {"ceiling": None}}, False),
    ("rendered, Pi camera, glossy floor", {}, True),
    ("rendered, USB camera (MJPEG), glossy floor",
     {"camera": {"compression": {"format": "jpeg", "quality": 60}, "rolling_shutter_s": 0.033,
                 "optics": {"vignetting": 0.4, "blur_mrad": 2.0}}}, True),
)


def rendered_tub_like(changes: dict[str, object], effects_on: bool, frames: int,
                      rate_hz: float = 20.0, speed_m_s: float = 1.0, seed: int = 0,
                      color: bool = False) -> tuple[list[U8], CameraModel]:
    """`frames` frames of the tub-like course with `changes`, through the camera effects (or, not
    `effects_on`, through the bare renderer as it was before them: 2 grey levels of noise, a
    10 ms shutter), and the camera they were taken with."""
    from lanewarden.scenarios.simulator import camera_model_of

    spec = parse_scenario(merge_overrides(TUB_LIKE, changes), "tub-like")
    assert spec.camera is not None and spec.camera.width_px and spec.camera.height_px
    camera = camera_model_of(spec.camera, spec.camera.width_px, spec.camera.height_px)
    return _render(spec, camera, effects_on, frames, rate_hz, speed_m_s, seed, color, 4.0)


def _render(spec: ScenarioSpec, camera: CameraModel, effects_on: bool, frames: int,
            rate_hz: float, speed_m_s: float, seed: int, color: bool,
            margin_m: float) -> tuple[list[U8], CameraModel]:
    world = build_world(spec, margin_m=margin_m)
    texture = paint_ground(world, 0.004, seed, color=color)
    effects = None
    highlights = None
    if effects_on:
        effects = CameraEffects(spec.camera or CameraSpec(), spec.lighting, camera,
                                channels=3 if color else 1, seed=seed,
                                frame_period_s=1.0 / rate_hz)
        ceiling = spec.lighting.ceiling
        if ceiling is not None:
            highlights = Highlights(ceiling, camera, spec.floor.roughness_rad)
    renderer = CameraRenderer(texture, camera, seed=seed, effects=effects, highlights=highlights)
    return drive_sequence(world, renderer, frames, rate_hz, speed_m_s, seed, color), camera


# ---- a rendered course of the JetBot tape lane's kind -----------------------------------------
#: The repo's real JetBot frames (data/real/jetbot-tape-lane) as a scenario: black 19 mm tape,
#: 0.19 m apart, with sharp corners, on a light wooden floor; its camera as that folder's
#: camera.yaml and calibration.yaml describe it (224x224, about 100 deg, 0.125 m up, pitched 18
#: deg; the real one is a squeezed fisheye, here square pixels and no distortion).
JETBOT_LIKE: dict[str, object] = {
    "name": "jetbot-like",
    "floor": {"kind": "wood", "color": "#c9ab8a"},
    "tape": {"width_m": 0.019, "color": "#1c1c1e"},
    "lane": {"width_m": 0.19,
             "segments": [{"straight_m": 0.8}, {"arc_radius_m": 0.2, "turn_deg": 90},
                          {"straight_m": 0.6}, {"arc_radius_m": 0.2, "turn_deg": -90},
                          {"straight_m": 0.8}]},
    "camera": {"width_px": 224, "height_px": 224, "hfov_deg": 100.0, "height_m": 0.125,
               "pitch_deg": 18.0, "forward_m": 0.0, "distortion": [0.0, 0.0, 0.0, 0.0, 0.0]},
}

#: The rendered sets compared with the real JetBot frames: (name, changes, camera effects on).
JETBOT_SETS: tuple[tuple[str, dict[str, object], bool], ...] = (
    ("rendered, no camera effects", {}, False),
    ("rendered, Pi camera", {}, True),
)


def rendered_jetbot_like(changes: dict[str, object], effects_on: bool, frames: int,
                         rate_hz: float = 20.0, speed_m_s: float = 0.2, seed: int = 0,
                         color: bool = False) -> tuple[list[U8], CameraModel]:
    """`frames` frames of the JetBot-like course with `changes` (see `rendered_tub_like`)."""
    from lanewarden.scenarios.simulator import camera_model_of

    spec = parse_scenario(merge_overrides(JETBOT_LIKE, changes), "jetbot-like")
    assert spec.camera is not None and spec.camera.width_px and spec.camera.height_px
    camera = camera_model_of(spec.camera, spec.camera.width_px, spec.camera.height_px)
    return _render(spec, camera, effects_on, frames, rate_hz, speed_m_s, seed, color, 1.5)


#: Floors compared through the simulator's default camera (320x240) on a straight lane: (name,
#: scenario changes, camera effects on). The first is the renderer before camera effects.
FLOOR_SETS: tuple[tuple[str, dict[str, object], bool], ...] = (
    ("tiles, no camera effects", {}, False),
    ("tiles", {}, True),
    ("ceramic, glossy tape", {"floor": {"kind": "ceramic"},
                              "tape": {"color": "#161618", "sheen": 0.8}}, True),
    ("terrazzo", {"floor": {"kind": "terrazzo"}, "tape": {"color": "#1c1c1e"}}, True),
    ("foam mats, white tape", {"floor": {"kind": "foam"}, "tape": {"color": "#eeeeea"}}, True),
    ("parquet", {"floor": {"kind": "parquet"}, "tape": {"color": "#1c1c1e"}}, True),
    ("carpet", {"floor": {"kind": "carpet"}, "tape": {"color": "#1c1c1e"}}, True),
    ("concrete, worn tape", {"floor": {"kind": "concrete"},
                             "tape": {"color": "#2a2a2e", "wear": 0.15, "tears_per_m": 2.0,
                                      "wrinkles_per_m": 4.0}}, True),
    ("tiles, dim room", {"lighting": {"brightness": 0.12}}, True),
)


def rendered_straight(changes: dict[str, object], effects_on: bool, frames: int,
                      rate_hz: float = 30.0, speed_m_s: float = 0.2,
                      seed: int = 0) -> tuple[list[U8], CameraModel]:
    """`frames` gray frames of a straight 8 m lane with `changes`, through the default camera at
    320x240 (with or without its effects: see `rendered_tub_like`)."""
    spec = parse_scenario(merge_overrides({"name": "straight", "lane": {
        "segments": [{"straight_m": 8.0}]}}, changes), "straight")
    return _render(spec, CameraModel(width_px=320, height_px=240), effects_on, frames, rate_hz,
                   speed_m_s, seed, False, 2.5)
