"""Synthetic camera frames of a taped lane with known geometry, for perception tests.

Each `Scene` is turned into a scenario world with the simulator's own pieces: a
`scenarios.spec.ScenarioSpec` (lane centre line of straight segments and arcs, tape width and
colour, gaps for missing tapes, dashes, tape ends, the floor's kind and colours), built by
`scenarios.world.build_world`, painted top-down by `scenarios.texture.paint_ground` and seen by
`scenarios.render.CameraRenderer` (the simulator's camera, `scenarios.camera.CameraModel`) at the
robot's pose. So the geometry in the image is exactly the camera's: straight floor lines are
straight in the undistorted view and bent by the lens in the distorted one.

Frames: the LANE frame is the world frame: the lane's centre line runs along +x on y = 0 (s along
it = x until a bend starts), the robot stands at x = 0, `lateral_m` to the left of it, turned
`yaw_deg`. The renderer draws at 2x the resolution (no noise, no motion blur), the result is
area-averaged down, then seeded Gaussian sensor noise and a faint colour cast are added. Pure
function of its arguments (no clock, no global randomness); the floor texture is painted once per
world (seed 0) and shared between poses and noise seeds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Literal

import cv2
import numpy as np

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.render import CameraRenderer
from lanewarden.scenarios.spec import (
    DashSpec,
    EndsSpec,
    FloorSpec,
    GapSpec,
    LaneSpec,
    PoseSpec,
    ScenarioSpec,
    SegmentSpec,
    TapeLook,
    TapeSpec,
)
from lanewarden.scenarios.texture import GroundTexture, paint_ground
from lanewarden.scenarios.world import World, build_world

TAPE_WIDTH_M = 0.048
TAPE_SPACING_M = 0.60  # between the two tapes' centres
TILE_M = 0.30
GROUT_M = 0.004
#: The painted floor's resolution (the simulator's default, `simulation.texture_mm_per_px`).
TEXTURE_M_PER_PX = 0.0025
#: How far ahead of the robot the lane (and its tape) runs: beyond the farthest floor point even
#: the distorted view sees (about 7.6 m), so the lane never visibly stops unless asked to.
LANE_AHEAD_M = 8.0
#: Floor painted beyond the lane on every side (the camera sees about 2 m to each side).
WORLD_MARGIN_M = 2.5


@dataclass(frozen=True)
class Bend:
    """The lane turns `direction` with centreline radius `radius_m`, starting `start_m` ahead."""

    direction: Literal["left", "right"]
    radius_m: float = 0.8
    start_m: float = 0.5


@dataclass(frozen=True)
class Scene:
    """A floor, an optional lane on it, and the robot's pose relative to the lane.

    - `lateral_m`: robot position left (+) / right (-) of the lane centreline.
    - `yaw_deg`: robot heading relative to the lane, counter-clockwise (to the left) positive.
    - `tapes`: which tapes exist ("left", "right"); empty for no lane.
    - `dash_m`: (dash, gap) lengths for dashed tape, None for solid.
    - `lane_start_m` / `lane_end_m`: tape starts / stops this far along the lane (None: never
      stops).
    - levels are grey levels (0-255) of the floor, the tile grout and the tape;
      `left_tape_level`: the left tape's where it differs (None: `tape_level`).
    - `floor_variation` / `floor_grain`: the scenario floor's brightness spread between tiles (or
      blotches on a plain floor) and its fine texture, fractions (`scenarios.spec.FloorSpec`);
      0 by default: the flat floors these scenes have always had.
    - `wall_level`: kept for compatibility; the camera never sees above the horizon (its top row
      looks at the floor about 3 m ahead), and beyond the painted floor the renderer shows the
      floor's median, so it has no effect.
    - `seed`: the sensor noise (the floor texture is the same for every seed).
    - `tape_width_m`, `lane_width_m` (between the tapes' centres), `grout_m`: the world's
      geometry (the lecture's 48 mm tape, 0.60 m lane and 4 mm grout by default).
    """

    floor_level: float = 175.0
    tiles: bool = False
    grout_level: float = 115.0
    tile_offset_m: tuple[float, float] = (0.10, 0.10)
    tapes: tuple[str, ...] = ("left", "right")
    tape_level: float = 45.0
    left_tape_level: float | None = None
    dash_m: tuple[float, float] | None = None
    bend: Bend | None = None
    lane_start_m: float = -0.5
    lane_end_m: float | None = None
    lateral_m: float = 0.0
    yaw_deg: float = 0.0
    noise_sigma: float = 3.0
    wall_level: float = 90.0
    seed: int = 0
    floor_variation: float = 0.0
    floor_grain: float = 0.0
    tape_width_m: float = TAPE_WIDTH_M
    lane_width_m: float = TAPE_SPACING_M
    grout_m: float = GROUT_M


def _grey(level: float) -> str:
    v = int(np.clip(round(level), 0, 255))
    return f"#{v:02x}{v:02x}{v:02x}"


def scenario_spec(scene: Scene) -> ScenarioSpec:
    """The scenario world a scene's floor and lane are (its pose and noise are not part of it).

    World = lane frame: the centre line starts at (lane_start_m, 0) heading +x, so arc length s
    in the world is the scene's s minus `lane_start_m`.
    """
    origin = scene.lane_start_m
    segments: list[SegmentSpec] = []
    if scene.bend is None:
        segments.append(SegmentSpec(straight_m=LANE_AHEAD_M - origin))
    else:
        bend = scene.bend
        if bend.start_m > origin:
            segments.append(SegmentSpec(straight_m=bend.start_m - origin))
        turn = 180.0 if bend.direction == "left" else -180.0
        segments.append(SegmentSpec(arc_radius_m=bend.radius_m, turn_deg=turn))
        if bend.start_m < origin:
            raise ValueError("a bend must start after the tape does (bend.start_m > lane_start_m)")
    length = sum(s.length_m for s in segments)
    gaps = [GapSpec(tape=side, from_m=0.0, to_m=length)
            for side in ("left", "right") if side not in scene.tapes]
    dashes = None
    if scene.dash_m is not None:
        on, off = scene.dash_m
        # Dashes start where the scene's s is a whole number of periods (as s = 0 at the robot).
        dashes = DashSpec(tape="both", on_m=on, off_m=off, from_m=(-origin) % (on + off))
    ends = EndsSpec()
    if scene.lane_end_m is not None:
        end = min(scene.lane_end_m - origin, length)
        ends = EndsSpec(left_m=end, right_m=end)
    if scene.tiles:
        ox, oy = scene.tile_offset_m
        # Scenario seams are centred on the grid lines; a scene's grout starts at them.
        floor = FloorSpec(kind="tiles", color=_grey(scene.floor_level),
                          seam_color=_grey(scene.grout_level), tile_m=TILE_M,
                          seam_m=scene.grout_m,
                          grid_offset_m=(ox + scene.grout_m / 2.0, oy + scene.grout_m / 2.0),
                          variation=scene.floor_variation, grain=scene.floor_grain)
    else:
        floor = FloorSpec(kind="plain", color=_grey(scene.floor_level),
                          variation=scene.floor_variation, grain=scene.floor_grain)
    return ScenarioSpec(
        name="perception-synthetic",
        floor=floor,
        tape=TapeSpec(width_m=scene.tape_width_m, color=_grey(scene.tape_level),
                      left=(None if scene.left_tape_level is None
                            else TapeLook(color=_grey(scene.left_tape_level)))),
        lane=LaneSpec(width_m=scene.lane_width_m, start=PoseSpec(x_m=origin, y_m=0.0),
                      segments=segments, gaps=gaps, dashes=dashes, ends=ends),
    )


def _world_key(scene: Scene) -> Scene:
    """The scene with everything that does not change the painted floor set to defaults."""
    return replace(scene, lateral_m=0.0, yaw_deg=0.0, noise_sigma=0.0, wall_level=0.0, seed=0)


@lru_cache(maxsize=8)
def world_of(world_key: Scene) -> World:
    """The scenario world of a scene (lane frame = world frame, see `scenario_spec`)."""
    return build_world(scenario_spec(_world_key(world_key)), margin_m=WORLD_MARGIN_M)


@lru_cache(maxsize=4)
def _texture(world_key: Scene) -> GroundTexture:
    return paint_ground(world_of(world_key), TEXTURE_M_PER_PX, seed=0, color=False)


@lru_cache(maxsize=4)
def _renderer(world_key: Scene, width: int, height: int, distorted: bool) -> CameraRenderer:
    """The simulator's camera (same field of view and mount) at another resolution, noiseless."""
    camera = replace(CameraModel(), width_px=width, height_px=height)
    return CameraRenderer(_texture(world_key), camera, noise_sigma=0.0, exposure_s=0.0,
                          distorted=distorted)


def render(
    scene: Scene,
    width: int = 640,
    height: int = 480,
    *,
    distorted: bool = False,
    supersample: int = 2,
) -> np.ndarray:
    """A BGR uint8 (height, width, 3) frame of `scene` seen by the default camera.

    `distorted=True` renders what the real lens delivers (barrel distortion of `CameraModel`);
    otherwise the ideal pinhole view.
    """
    big_w, big_h = width * supersample, height * supersample
    renderer = _renderer(_world_key(scene), big_w, big_h, distorted)
    pose = Pose2D(0.0, scene.lateral_m, math.radians(scene.yaw_deg))
    big = renderer.render_gray(pose, np.empty((big_h, big_w), np.uint8))
    small = cv2.resize(big.astype(np.float32), (width, height), interpolation=cv2.INTER_AREA)
    rng = np.random.default_rng(scene.seed)
    small = small + np.asarray(rng.normal(0.0, scene.noise_sigma, small.shape), np.float32)
    gray = np.clip(np.rint(small), 0, 255).astype(np.uint8)
    # A faint colour cast so the detector's BGR->gray path is exercised, not just gray input.
    bgr = np.dstack([gray, gray, gray]).astype(np.int16)
    bgr[..., 0] -= 6
    bgr[..., 2] += 6
    return np.clip(bgr, 0, 255).astype(np.uint8)


@lru_cache(maxsize=64)
def _cached(scene: Scene, width: int, height: int, distorted: bool) -> np.ndarray:
    image = render(scene, width, height, distorted=distorted)
    image.setflags(write=False)
    return image


def frame(
    scene: Scene, width: int = 640, height: int = 480, *, distorted: bool = False
) -> np.ndarray:
    """`render`, memoised (read-only result): tests share frames instead of re-rendering."""
    return _cached(scene, width, height, distorted)


# The acceptance scenes (named so tests, the benchmark and the docs use the same pictures).
STRAIGHT = Scene()
# The robot at the entrance of a bend of 0.8 m radius (lane centreline), which starts 0.3 m ahead
# of its centre, i.e. just below the bottom of the image (the camera sees from 0.36 m on).
BEND_LEFT = Scene(bend=Bend("left", radius_m=0.8, start_m=0.3))
BEND_RIGHT = Scene(bend=Bend("right", radius_m=0.8, start_m=0.3))
ONE_EDGE = Scene(tapes=("left",))
NO_LANE = Scene(tapes=())
TILES_ONLY = Scene(tiles=True, tapes=())
TILES_WITH_TAPE = Scene(tiles=True)
DASHED = Scene(dash_m=(0.15, 0.10))
LIGHT_ON_DARK = Scene(floor_level=70.0, tape_level=225.0, wall_level=40.0)
DARK_ON_LIGHT = Scene(floor_level=200.0, tape_level=35.0)
OFFSET_LEFT = Scene(lateral_m=0.08)  # robot left of the centreline: lane centre right in image
OFFSET_RIGHT = Scene(lateral_m=-0.08)
