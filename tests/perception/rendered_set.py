"""A labelled set of rendered frames for the classes real footage rarely shows: one tape on its own
(beside the robot, straight ahead, at an angle), tape ends, seams only, a light floor strip
beside a tape, two different tapes (a thin dashed line and a wide solid one), dim and
low-contrast frames. Every frame is ours (the simulator's renderer through
`tests.perception.synthetic`), so it is generated on demand, not stored.

Each `Labelled` frame says what it shows and what a detector should make of it: `lane` (two
tapes of a lane: a decision expected, both reported edges on the tapes) or `none` (no lane: any
decision is a false lane). `edges_on_tapes` checks a reported edge against the scene's own world
(the tape centre lines, in metres), as `test_camera_family.py` does.

Frames: the lane frame is the world frame (`synthetic.Scene`); the camera is the simulator's
default (0.40 m high, 35 deg down, 70 deg lens), ideal pinhole. Pure functions of their
arguments: the same frame every time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Literal

import numpy as np

from lanewarden.perception.ground import GroundModel
from lanewarden.perception.observation import LaneEdge
from tests.perception import synthetic as syn
from tests.perception.synthetic import Bend, Scene

Expect = Literal["lane", "none"]

#: A Duckietown-like road: a 25 mm dashed light centre line on the left, a 48 mm solid white
#: edge line on the right, on a dark floor; lane 0.30 m between the lines' centres.
THIN_WIDTH_M = 0.025
WIDE_WIDTH_M = 0.048


@dataclass(frozen=True)
class TwoTapes:
    """Two different tapes: the left tape of `left` and the right tape of `right` (scenes alike
    but for their tapes) on the one floor they share."""

    left: Scene
    right: Scene

    def scenes(self) -> tuple[Scene, Scene]:
        return self.left, self.right


@dataclass(frozen=True)
class Dim:
    """A scene under poor light: its noiseless picture times `gain`, plus `offset` grey levels,
    plus sensor noise (the scene's own `noise_sigma`)."""

    scene: Scene | TwoTapes
    gain: float
    offset: float = 0.0


Picture = Scene | TwoTapes | Dim


#: The perception config a user describes the Duckietown-like road with.
DUCKIE_CONFIG: dict[str, dict[str, float]] = {
    "tape": {"width_m": WIDE_WIDTH_M, "left_width_m": THIN_WIDTH_M,
             "right_width_m": WIDE_WIDTH_M},
    "lane": {"width_m": 0.30},
}


@dataclass(frozen=True)
class Labelled:
    """One labelled frame: `name` (unique), `expect`, `shows` (what is in the picture, in
    words), the picture to render and the perception config (overrides of the defaults) a user
    describes that floor with (`config`, as a `perception:` mapping)."""

    name: str
    expect: Expect
    shows: str
    picture: Picture
    config: tuple[tuple[str, tuple[tuple[str, float], ...]], ...] = ()

    def perception_overrides(self) -> dict[str, dict[str, float]]:
        return {section: dict(values) for section, values in self.config}


def _frozen(config: dict[str, dict[str, float]]) -> tuple[
        tuple[str, tuple[tuple[str, float], ...]], ...]:
    return tuple((k, tuple(sorted(v.items()))) for k, v in sorted(config.items()))


DUCKIE = _frozen(DUCKIE_CONFIG)


def _scenes(picture: Picture) -> tuple[Scene, ...]:
    if isinstance(picture, Dim):
        return _scenes(picture.scene)
    if isinstance(picture, TwoTapes):
        return picture.scenes()
    return (picture,)


def render(picture: Picture, width: int = 640, height: int = 480) -> np.ndarray:
    """BGR uint8 frame of a labelled picture (noise as its scenes say)."""
    if isinstance(picture, Scene):
        return np.array(syn.frame(picture, width, height))
    base = _scenes(picture)[0]
    sigma, seed = base.noise_sigma, base.seed
    clean = _clean(picture, width, height)
    if isinstance(picture, Dim):
        clean = clean * picture.gain + picture.offset
    noisy = clean + np.random.default_rng(seed).normal(0.0, sigma, clean.shape)
    gray = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    return np.dstack([gray, gray, gray])


def _clean(picture: Picture, width: int, height: int) -> np.ndarray:
    """Noiseless gray float picture."""
    if isinstance(picture, Dim):
        return _clean(picture.scene, width, height)
    if isinstance(picture, Scene):
        return _noiseless(picture, width, height)
    left, right = picture.scenes()
    floor = _noiseless(replace(left, tapes=()), width, height)
    return (_noiseless(replace(left, tapes=("left",)), width, height)
            + _noiseless(replace(right, tapes=("right",)), width, height) - floor)


@lru_cache(maxsize=128)
def _noiseless(scene: Scene, width: int, height: int) -> np.ndarray:
    image = syn.render(replace(scene, noise_sigma=0.0), width, height)
    gray = image[..., 1].astype(np.float64)  # the green channel carries no colour cast
    gray.setflags(write=False)
    return gray


def edges_on_tapes(edge: LaneEdge, picture: Picture, ground: GroundModel) -> bool:
    """The reported segment lies on a tape of the picture's world: its points, put on the floor,
    lie within half that side's tape width of the tape's centre line (the lane's centre line
    offset by half the lane; dashes count with their gaps), plus 2 pixels (at that point) and
    3 mm. Checked at both ends and, where the lane is straight, at three points between (in a
    bend the reported chord leaves the curving tape between its ends)."""
    scenes = _scenes(picture)
    scene = scenes[0]
    straight = all(piece.bend is None for piece in scenes)
    t = np.linspace(0.0, 1.0, 5) if straight else np.array([0.0, 1.0])
    pix = np.column_stack([edge.x1 + t * (edge.x2 - edge.x1), edge.y1 + t * (edge.y2 - edge.y1)])
    floor = ground.image_to_floor(pix)
    if not np.isfinite(floor).all():
        return False
    c, s = math.cos(math.radians(scene.yaw_deg)), math.sin(math.radians(scene.yaw_deg))
    world = np.column_stack([c * floor[:, 0] - s * floor[:, 1],
                             scene.lateral_m + s * floor[:, 0] + c * floor[:, 1]])
    tol = np.array([2.0 * ground.metres_per_px_across(u, v) for u, v in pix]) + 0.003
    on = np.zeros(len(world), bool)
    for index, piece in enumerate(scenes):
        sides = piece.tapes if len(scenes) == 1 else (("left",) if index == 0 else ("right",))
        along, lateral, _ = syn.world_of(piece).centreline.project(world)
        along = along + piece.lane_start_m  # the scene's s (0 at the robot)
        ends = math.inf if piece.lane_end_m is None else piece.lane_end_m
        inside = (along >= piece.lane_start_m) & (along <= ends)
        for side in sides:
            centre = piece.lane_width_m / 2.0 * (1.0 if side == "left" else -1.0)
            on |= inside & (np.abs(lateral - centre) <= piece.tape_width_m / 2.0 + tol)
    return bool(on.all())


def labelled_frames() -> tuple[Labelled, ...]:
    """The set: lane frames (a decision expected) and no-lane frames (none expected)."""
    tiles = Scene(tiles=True)
    one_left = Scene(tapes=("left",))
    duck_floor = {"floor_level": 45.0, "tape_level": 215.0, "lane_width_m": 0.30}
    thin = Scene(tape_width_m=THIN_WIDTH_M, dash_m=(0.10, 0.10), **duck_floor)
    wide = Scene(tape_width_m=WIDE_WIDTH_M, **duck_floor)
    frames = [
        # Two tapes of a lane.
        Labelled("lane-straight", "lane", "dark tape on a light floor, robot centred",
                 syn.STRAIGHT),
        Labelled("lane-offset-left", "lane", "robot 8 cm left of the lane centre",
                 syn.OFFSET_LEFT),
        Labelled("lane-offset-right", "lane", "robot 8 cm right of the lane centre",
                 syn.OFFSET_RIGHT),
        Labelled("lane-turned", "lane", "robot turned 8 deg left", Scene(yaw_deg=8.0)),
        Labelled("lane-bend-left", "lane", "a left bend of 0.8 m radius ahead", syn.BEND_LEFT),
        Labelled("lane-bend-right", "lane", "a right bend of 0.8 m radius ahead",
                 syn.BEND_RIGHT),
        Labelled("lane-dashed", "lane", "both tapes dashed (0.15 m on, 0.10 m off)", syn.DASHED),
        Labelled("lane-on-tiles", "lane", "the lane on a tiled floor (4 mm grout)", tiles),
        Labelled("lane-light-on-dark", "lane", "light tape on a dark floor", syn.LIGHT_ON_DARK),
        Labelled("lane-two-tapes", "lane", "25 mm dashed light line left, 48 mm solid white "
                 "line right, dark floor, lane 0.30 m", TwoTapes(thin, wide),
                 config=DUCKIE),
        Labelled("lane-two-tapes-offset", "lane", "the same, robot 4 cm right of centre",
                 TwoTapes(replace(thin, lateral_m=-0.04), replace(wide, lateral_m=-0.04)),
                 config=DUCKIE),
        Labelled("lane-dim", "lane", "the straight lane under poor light (a quarter of the "
                 "exposure)", Dim(replace(syn.STRAIGHT, noise_sigma=1.5), 0.25)),
        Labelled("lane-dim-two-tapes", "lane", "the two different tapes, dim (a third of the "
                 "exposure)", Dim(TwoTapes(replace(thin, noise_sigma=1.5), wide), 0.33),
                 config=DUCKIE),
        Labelled("lane-low-contrast", "lane", "grey tape 40 levels darker than the floor",
                 Scene(floor_level=170.0, tape_level=130.0)),
        # One tape, no lane.
        Labelled("one-tape-left", "none", "the left tape only, robot where the lane would be",
                 one_left),
        Labelled("one-tape-right", "none", "the right tape only", Scene(tapes=("right",))),
        Labelled("one-tape-ahead", "none", "one tape straight ahead under the robot",
                 replace(one_left, lateral_m=0.30)),
        Labelled("one-tape-ahead-turned", "none", "one tape under the robot, robot turned "
                 "6 deg", replace(one_left, lateral_m=0.30, yaw_deg=6.0)),
        Labelled("one-tape-near-centre", "none", "one tape 12 cm left of the robot",
                 replace(one_left, lateral_m=0.18)),
        Labelled("one-tape-near-centre-right", "none", "one tape 12 cm right of the robot",
                 replace(Scene(tapes=("right",)), lateral_m=-0.18)),
        Labelled("one-tape-light-ahead", "none", "one light tape on a dark floor under the "
                 "robot", replace(syn.LIGHT_ON_DARK, tapes=("left",), lateral_m=0.30)),
        Labelled("one-tape-on-tiles", "none", "one tape on a tiled floor under the robot",
                 replace(tiles, tapes=("left",), lateral_m=0.30)),
        Labelled("one-tape-bend", "none", "one tape curving left ahead of the robot",
                 replace(syn.BEND_LEFT, tapes=("left",), lateral_m=0.30)),
        Labelled("one-wide-tape-ahead", "none", "one 48 mm white line under the robot on a "
                 "dark floor", replace(wide, tapes=("right",), lateral_m=-0.15),
                 config=DUCKIE),
        Labelled("one-thin-tape-ahead", "none", "one 25 mm dashed line under the robot on a "
                 "dark floor", replace(thin, tapes=("left",), lateral_m=0.15),
                 config=DUCKIE),
        Labelled("one-tape-dim", "none", "one tape under the robot, dim",
                 Dim(replace(one_left, lateral_m=0.30, noise_sigma=1.5), 0.25)),
        # Tape ends, seams, bare floor.
        Labelled("tape-ends", "none", "the robot 0.2 m past the end of both tapes, tiles",
                 replace(tiles, lane_start_m=-2.0, lane_end_m=-0.2)),
        Labelled("one-tape-ends-ahead", "none", "one tape ending 0.7 m ahead of the robot, "
                 "which stands on it", replace(one_left, lateral_m=0.30, lane_end_m=0.7)),
        Labelled("seams-only", "none", "tiles only (4 mm grout)", syn.TILES_ONLY),
        Labelled("seams-wide", "none", "tiles with 20 mm dark grout",
                 Scene(tiles=True, tapes=(), grout_m=0.020, grout_level=60.0)),
        Labelled("seams-lane-tiles", "none", "tiles as wide as the lane, grout where tapes "
                 "would run", Scene(tiles=True, tapes=(), tile_offset_m=(0.0, 0.30 - 0.002))),
        Labelled("seams-dim", "none", "tiles only, dim",
                 Dim(replace(syn.TILES_ONLY, noise_sigma=1.5), 0.25)),
        Labelled("bare-floor", "none", "a plain floor", syn.NO_LANE),
        Labelled("dark-floor", "none", "a plain floor, nearly black",
                 Dim(replace(syn.NO_LANE, noise_sigma=1.5), 0.12)),
        Labelled("floor-strip", "none", "one tape with a 30 mm light floor strip and a wide "
                 "dark seam beside it, under the robot",
                 Scene(tiles=True, tapes=("left",), lateral_m=0.30, grout_m=0.030,
                       grout_level=50.0, tile_offset_m=(0.0, 0.30 + 0.024 + 0.030 - 0.60))),
        Labelled("bend-one-tape-right", "none", "the outer tape of a right bend alone",
                 Scene(tapes=("left",), bend=Bend("right", radius_m=0.8, start_m=0.3))),
    ]
    return tuple(frames)
