"""The rendered survey set: labelled frames of what a real floor survey needs and the shared real
set lacks, drawn by the simulator's own camera (`scenarios.render.CameraRenderer`, the default
`scenarios.camera.CameraModel` at 640x480, its ideal pinhole view: no calibration needed).

    python -m tests.survey.rendered_set data/survey/rendered     # rewrites lane/ and no-lane/

writes `lane/*.jpg` (two tapes: straight, both bends, off-centre, on tiles, dashed, a dim frame, and
two different tapes: a 25 mm dashed yellow line on the left, a 48 mm white line on the right, also
in a bend) and `no-lane/*.jpg` (bare tiles, tiles whose seams are a lane width apart, a plain
floor, one tape alone in three places, the end of one tape, the white line alone, the yellow
dashes alone, a dark frame). The committed set in data/survey/rendered/ was made by this module
with `SEED`; the survey's CI test reads that committed set (so a change of the renderer does not
silently move the figures), and `test_rendered_set.py` checks that this module still draws the same
scenes (its labels and geometry).

Each frame: the scene's world (a `ScenarioSpec`, built and painted in colour by the simulator's
code; the second kind of tape is painted over it as floor marks with `scenarios.texture.
with_marks`), seen at the robot's pose at twice the size, area-averaged down, then seeded Gaussian
sensor noise (sigma 3 grey levels), saved as JPEG quality 92 (what a camera or a phone delivers).
World frame = lane frame: the lane's centre line starts 0.5 m behind the robot and runs along +x.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

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
    TapeSpec,
)
from lanewarden.scenarios.texture import FloorMark, paint_ground, with_marks
from lanewarden.scenarios.world import Tape, World, build_world

SEED = 20261105
WIDTH, HEIGHT = 640, 480
SUPERSAMPLE = 2
NOISE_SIGMA = 3.0
JPEG_QUALITY = 92
#: Painted floor resolution (the simulator's default `simulation.texture_mm_per_px`).
TEXTURE_M_PER_PX = 0.0025
LANE_WIDTH_M = 0.60  # between the tapes' centres
LANE_START_M = -0.5
LANE_LENGTH_M = 6.0
MARGIN_M = 2.5

LIGHT_FLOOR = "#c9c5bd"
DARK_TAPE = "#26262a"
ROAD_GREY = "#5c5c5e"
WHITE_TAPE = "#ededed"
YELLOW_BGR = (20, 200, 235)


@dataclass(frozen=True)
class PaintedLine:
    """A tape of its own kind painted over the scene's floor: `offset_m` left (+) of the lane's
    centre line, `width_m` wide, solid or dashed (`dash_m` = (on, off)), from s = 0 to `end_m`."""

    offset_m: float
    width_m: float
    color_bgr: tuple[int, int, int]
    dash_m: tuple[float, float] | None = None
    end_m: float | None = None


@dataclass(frozen=True)
class RenderedScene:
    """One labelled frame: its file name (without suffix), label and what it shows."""

    name: str
    expect: str  # "lane" or "none"
    note: str
    floor: FloorSpec = FloorSpec(kind="plain", color=LIGHT_FLOOR)
    tape: TapeSpec = TapeSpec(width_m=0.048, color=DARK_TAPE)
    tapes: tuple[str, ...] = ("left", "right")
    dash_m: tuple[float, float] | None = None
    bend: tuple[float, float] | None = None  # (turn_deg, radius_m) starting 0.3 m ahead
    tape_end_m: float | None = None  # along the lane from the robot
    lateral_m: float = 0.0
    yaw_deg: float = 0.0
    painted: tuple[PaintedLine, ...] = field(default_factory=tuple)

    @property
    def folder(self) -> str:
        return "lane" if self.expect == "lane" else "no-lane"


TILES = FloorSpec(kind="tiles", color="#cfcbc3", seam_color="#7a766e", tile_m=0.30, seam_m=0.004,
                  grid_offset_m=(0.102, 0.102))
#: Seams exactly a lane width apart (and wider, darker grout): the classic false lane.
WIDE_TILES = FloorSpec(kind="tiles", color="#cfcbc3", seam_color="#5a564f", tile_m=0.60,
                       seam_m=0.010, grid_offset_m=(0.005, 0.305))
ROAD = FloorSpec(kind="plain", color=ROAD_GREY)
YELLOW_DASHES = PaintedLine(LANE_WIDTH_M / 2.0, 0.025, YELLOW_BGR, dash_m=(0.10, 0.08))
WHITE_LINE = TapeSpec(width_m=0.048, color=WHITE_TAPE)

SCENES: tuple[RenderedScene, ...] = (
    RenderedScene("straight", "lane", "two dark 48 mm tapes, straight, on a plain light floor"),
    RenderedScene("bend-left", "lane", "two tapes bending left (0.8 m radius) just ahead",
                  bend=(90.0, 0.8)),
    RenderedScene("bend-right", "lane", "two tapes bending right (0.8 m radius) just ahead",
                  bend=(-90.0, 0.8)),
    RenderedScene("off-centre", "lane", "two tapes, the robot 8 cm right of centre, turned 8 deg",
                  lateral_m=-0.08, yaw_deg=8.0),
    RenderedScene("tiles-lane", "lane", "two tapes on a tiled floor (30 cm tiles, 4 mm seams)",
                  floor=TILES),
    RenderedScene("dashed", "lane", "two dashed tapes (15 cm dashes, 10 cm gaps)",
                  dash_m=(0.15, 0.10)),
    RenderedScene("dim", "lane", "two tapes in a dim, low-contrast frame",
                  floor=FloorSpec(kind="plain", color="#3c3a38"),
                  tape=TapeSpec(width_m=0.048, color="#1c1c1e")),
    RenderedScene("two-tapes", "lane", "25 mm dashed yellow line left, 48 mm white line right, "
                  "grey floor", floor=ROAD, tape=WHITE_LINE, tapes=("right",),
                  painted=(YELLOW_DASHES,)),
    RenderedScene("two-tapes-bend", "lane", "the two different tapes bending left (1.2 m radius)",
                  floor=ROAD, tape=WHITE_LINE, tapes=("right",), bend=(90.0, 1.2),
                  painted=(YELLOW_DASHES,)),
    RenderedScene("tiles", "none", "bare tiled floor: 30 cm tiles, 4 mm seams", floor=TILES,
                  tapes=()),
    RenderedScene("tiles-lane-apart", "none", "bare tiles whose 10 mm seams are 0.60 m apart, a "
                  "lane's width", floor=WIDE_TILES, tapes=()),
    RenderedScene("plain-floor", "none", "bare plain floor", tapes=()),
    RenderedScene("one-tape-left", "none", "one dark tape alone, left of the robot",
                  tapes=("left",)),
    RenderedScene("one-tape-ahead", "none", "one dark tape alone, straight ahead under the robot",
                  tapes=("left",), lateral_m=LANE_WIDTH_M / 2.0),
    RenderedScene("one-tape-tiles", "none", "one dark tape alone on tiles", floor=TILES,
                  tapes=("right",)),
    RenderedScene("tape-end", "none", "the end of one tape, 0.9 m ahead, then bare tiles",
                  floor=TILES, tapes=("right",), tape_end_m=0.9, lateral_m=-0.15),
    RenderedScene("white-line-alone", "none", "the 48 mm white line alone on grey floor",
                  floor=ROAD, tape=WHITE_LINE, tapes=("right",)),
    RenderedScene("yellow-dashes-alone", "none", "the 25 mm yellow dashed line alone on grey "
                  "floor", floor=ROAD, tape=WHITE_LINE, tapes=(), painted=(YELLOW_DASHES,)),
    RenderedScene("dark", "none", "a dark frame (lights off): bare floor near black",
                  floor=FloorSpec(kind="plain", color="#0e0e0e"), tapes=()),
)


def scenario_spec(scene: RenderedScene) -> ScenarioSpec:
    """The scenario world of `scene` (its floor and the tapes of the one kind the simulator's
    tape spec describes; `painted` lines are added by `render`)."""
    segments = [SegmentSpec(straight_m=0.3 - LANE_START_M)]
    if scene.bend is not None:
        turn, radius = scene.bend
        segments.append(SegmentSpec(arc_radius_m=radius, turn_deg=turn))
    segments.append(SegmentSpec(straight_m=LANE_LENGTH_M))
    length = sum(s.length_m for s in segments)
    gaps = [GapSpec(tape=side, from_m=0.0, to_m=length)
            for side in ("left", "right") if side not in scene.tapes]
    dashes = None
    if scene.dash_m is not None:
        on, off = scene.dash_m
        dashes = DashSpec(tape="both", on_m=on, off_m=off, from_m=(-LANE_START_M) % (on + off))
    ends = EndsSpec()
    if scene.tape_end_m is not None:
        end = scene.tape_end_m - LANE_START_M
        ends = EndsSpec(left_m=end, right_m=end)
    return ScenarioSpec(
        name=f"survey-{scene.name}", floor=scene.floor, tape=scene.tape,
        lane=LaneSpec(width_m=LANE_WIDTH_M, start=PoseSpec(x_m=LANE_START_M, y_m=0.0),
                      segments=segments, gaps=gaps, dashes=dashes, ends=ends))


def painted_marks(world: World, line: PaintedLine) -> list[FloorMark]:
    """The pieces of `line` as floor marks (ribbon polygons along the lane's centre line)."""
    centre = world.centreline
    start = -LANE_START_M - 0.5  # from behind the camera's view
    stop = centre.length_m if line.end_m is None else min(centre.length_m,
                                                           line.end_m - LANE_START_M)
    intervals: list[tuple[float, float]] = []
    if line.dash_m is None:
        intervals.append((start, stop))
    else:
        on, off = line.dash_m
        s = start
        while s < stop:
            intervals.append((s, min(s + on, stop)))
            s += on + off
    pieces = tuple(centre.offset(a, b, line.offset_m) for a, b in intervals)
    tape = Tape("painted", line.offset_m, line.width_m, line.color_bgr, tuple(intervals), pieces)
    return [FloorMark(polygon=outline, mode="paint", color_bgr=line.color_bgr)
            for outline in tape.outlines()]


def render(scene: RenderedScene, seed: int = SEED) -> np.ndarray:
    """The BGR uint8 (HEIGHT, WIDTH, 3) frame of `scene`: the simulator's camera at the robot's
    pose (x = 0, `lateral_m` left of the centre line, turned `yaw_deg`), seeded noise."""
    world = build_world(scenario_spec(scene), margin_m=MARGIN_M)
    texture = paint_ground(world, TEXTURE_M_PER_PX, seed=seed, color=True)
    marks = [mark for line in scene.painted for mark in painted_marks(world, line)]
    texture = with_marks(texture, marks)
    camera = CameraModel(width_px=WIDTH * SUPERSAMPLE, height_px=HEIGHT * SUPERSAMPLE)
    renderer = CameraRenderer(texture, camera, noise_sigma=0.0, exposure_s=0.0, distorted=False)
    pose = Pose2D(0.0, scene.lateral_m, math.radians(scene.yaw_deg))
    big = renderer.render_bgr(pose, np.empty((camera.height_px, camera.width_px, 3), np.uint8))
    small = cv2.resize(big.astype(np.float32), (WIDTH, HEIGHT), interpolation=cv2.INTER_AREA)
    index = [s.name for s in SCENES].index(scene.name) if scene in SCENES else 0
    rng = np.random.default_rng([seed, index])
    small += rng.normal(0.0, NOISE_SIGMA, small.shape[:2]).astype(np.float32)[:, :, None]
    return np.clip(np.rint(small), 0, 255).astype(np.uint8)


def write_set(folder: Path, scenes: Sequence[RenderedScene] = SCENES, seed: int = SEED) -> None:
    """Write every scene as folder/lane/NAME.jpg or folder/no-lane/NAME.jpg."""
    for sub in ("lane", "no-lane"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
        for old in (folder / sub).glob("*.jpg"):
            old.unlink()
    for scene in scenes:
        target = folder / scene.folder / f"{scene.name}.jpg"
        if not cv2.imwrite(str(target), render(scene, seed),
                           [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY]):
            raise OSError(f"{target}: cannot write")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: python -m tests.survey.rendered_set FOLDER")
    write_set(Path(sys.argv[1]))
