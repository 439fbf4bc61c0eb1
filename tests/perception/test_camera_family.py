"""Tape vs seam on random cameras and floors: the claim the robot's safety rests on, tested over
the family of setups a user may build (seeded, so every run sees the same family).

Each floor is a tiled floor with a straight taped lane whose tape ends 2.3 m along it; tiles
0.2-0.6 m (a third of the floors: tiles exactly as wide as the lane, so seams run where a lane's
tapes would), seams 2 mm up to half the tape's width, tape 19-50 mm, lanes 0.3-0.8 m, dark tape
on light tiles or light tape on dark tiles, seams 40-110 grey levels darker than the tiles (well
within what Canny sees). Each floor is painted once and seen by two random cameras, one at
320x240 and one at 640x480: height 0.15-0.50 m, pitch 20-55 deg, horizontal field of view
55-90 deg, 0.05-0.25 m ahead of the robot's centre, rendered by the simulator's renderer (ideal
pinhole, sensor noise, no lens distortion: perception's ground model is for undistorted pixels).

Perception gets what a user gives it: the camera's ground model from its mount (the rendered
camera's `CameraPose`, which `lanewarden calibrate ground --height-m ... --pitch-deg ...` writes)
and the tape's and the lane's widths in metres; everything else default, the look-ahead too
(`auto`: the detector picks the farthest one this camera can work with, and says which). A camera
refused outright (nothing in its view resolves tape from seam) or one that cannot see both tapes
of the lane is replaced by another (counted and printed). For every camera, the look-ahead a
refusal advises is accepted as given: a fixed look-ahead too far for the camera is refused with
advice, and that advice, set, is accepted (the auto value).

Per camera, frames of two classes:
- tiles only: the robot past the end of the tape (turned up to 20 deg, off-centre): no tape in
  view (checked against the world). Must give 0 confident lanes (confidence >= 0.45).
- lane: the robot on the lane, up to 20% of the half lane off-centre and turned up to 6 deg,
  both tapes in view nearer than the look-ahead (a camera that sees the lane only farther away
  cannot tell its tape from a seam: it never engages, which is safe, and is replaced here). At
  least 95% must give a decision (both edges, confidence >= 0.45) with both reported edges on
  tape (each edge's points, projected to the floor, within the tape plus
  2 pixels and 3 mm of its centre line in the renderer's world).
The figures (also at the supervisor's engage threshold 0.6, and per resolution) are printed.
Takes about 20-30 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from lanewarden.actuation.base import Pose2D
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.errors import PerceptionConfigError
from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.metrics import points_in_polygon
from lanewarden.scenarios.render import CameraRenderer
from lanewarden.scenarios.spec import (
    EndsSpec,
    FloorSpec,
    LaneSpec,
    PoseSpec,
    ScenarioSpec,
    SegmentSpec,
    TapeSpec,
)
from lanewarden.scenarios.texture import GroundTexture, paint_ground
from lanewarden.scenarios.world import World, build_world

SEED = 9
FLOORS = 24
FRAMES_PER_CLASS = 5  # per camera: 24 floors x 2 cameras x 5 = 240 frames per class
SIZES = ((320, 240), (640, 480))
CONFIDENT = 0.45  # counts as a confident lane (a decision)
ENGAGE = 0.6  # the supervisor's confidence_confident_min
LANE_START_X = -0.4
TAPE_END_S = 2.7  # along the lane from its start: the tape ends 2.3 m ahead of x = 0
TEXTURE_M_PER_PX = 0.002
#: Camera draws per floor and size before the floor is replaced.
MAX_CAMERA_DRAWS = 40
#: Per floor, cameras that work but cannot see the lane's tapes nearer than their look-ahead
#: also look at the tiles (SPARE_TILES_FRAMES each): more seams seen by more cameras.
SPARE_CAMERAS = 4
SPARE_TILES_FRAMES = 2
#: Cameras on which a too-far fixed look-ahead is refused and its advice set (each costs a
#: second start-up).
ADVICE_CHECKS = 40


@dataclass(frozen=True)
class Floor:
    lane_m: float
    tape_m: float
    seam_m: float
    tile_m: float
    tile_level: int
    seam_level: int
    tape_level: int
    offset_m: tuple[float, float]


def _grey(level: int) -> str:
    return f"#{level:02x}{level:02x}{level:02x}"


def sample_floor(rng: np.random.Generator) -> Floor:
    lane = float(rng.uniform(0.3, 0.8))
    tape = float(rng.uniform(0.019, 0.050))
    seam = float(rng.uniform(0.002, tape / 2.0))
    tile = lane if rng.random() < 1.0 / 3.0 else float(rng.uniform(0.2, 0.6))
    if rng.random() < 0.7:  # dark tape on light tiles
        tile_level = int(rng.integers(150, 211))
        seam_level = tile_level - int(rng.integers(50, 111))
        tape_level = int(rng.integers(20, 71))
    else:  # light tape on dark tiles
        tile_level = int(rng.integers(80, 121))
        seam_level = tile_level - int(rng.integers(40, 61))
        tape_level = int(rng.integers(200, 246))
    offset = (float(rng.uniform(0.0, tile)), float(rng.uniform(0.0, tile)))
    return Floor(lane, tape, seam, tile, tile_level, seam_level, tape_level, offset)


def world_of(floor: Floor) -> World:
    spec = ScenarioSpec(
        name="camera-family",
        floor=FloorSpec(kind="tiles", color=_grey(floor.tile_level),
                        seam_color=_grey(floor.seam_level), tile_m=floor.tile_m,
                        seam_m=floor.seam_m, grid_offset_m=floor.offset_m, variation=0.03,
                        grain=0.02),
        tape=TapeSpec(width_m=floor.tape_m, color=_grey(floor.tape_level)),
        lane=LaneSpec(width_m=floor.lane_m, start=PoseSpec(x_m=LANE_START_X),
                      segments=[SegmentSpec(straight_m=4.6)],
                      ends=EndsSpec(left_m=TAPE_END_S, right_m=TAPE_END_S)),
    )
    return build_world(spec, margin_m=1.0)


def sample_camera(rng: np.random.Generator, size: tuple[int, int]) -> CameraModel:
    return CameraModel(
        width_px=size[0], height_px=size[1], hfov_deg=float(rng.uniform(55.0, 90.0)),
        height_m=float(rng.uniform(0.15, 0.50)), pitch_down_deg=float(rng.uniform(20.0, 55.0)),
        forward_offset_m=float(rng.uniform(0.05, 0.25)), dist_coeffs=(0.0, 0.0, 0.0, 0.0, 0.0),
    )


@dataclass
class Tally:
    frames: int = 0
    confident: int = 0
    engaged: int = 0
    on_tape: int = 0
    good: int = 0
    max_confidence: float = 0.0
    bad: list[str] = field(default_factory=list)


@dataclass
class Family:
    tiles: dict[int, Tally] = field(default_factory=dict)
    lanes: dict[int, Tally] = field(default_factory=dict)
    cameras: int = 0
    refused: int = 0
    look_aheads: list[float] = field(default_factory=list)
    advice_checked: int = 0
    lane_out_of_view: int = 0
    floors_without_camera: int = 0
    spare_cameras: int = 0


def detector_for(camera: CameraModel, floor: Floor, family: Family) -> LaneDetector | None:
    """The detector a user ends up with: ground model from the mount, tape and lane widths, no
    look-ahead (auto). None: refused outright (then auto names no look-ahead either). Checks on
    the way that the look-ahead auto chose is in the description it prints, and that a fixed
    look-ahead beyond it is refused with exactly that advice, which is then accepted."""
    overrides: dict[str, dict[str, float]] = {
        "tape": {"width_m": floor.tape_m}, "lane": {"width_m": floor.lane_m}}
    try:
        detector = LaneDetector(PerceptionConfig.model_validate(overrides), ground=camera.ground)
    except PerceptionConfigError as exc:
        assert exc.suggested_look_ahead_m is None, str(exc)
        family.refused += 1
        return None
    size = (camera.width_px, camera.height_px)
    chosen = detector.setup_for(*size).look_ahead_m
    family.look_aheads.append(chosen)
    assert f"look-ahead {chosen:.2f} m (auto" in detector.describe_ground()
    if family.advice_checked < ADVICE_CHECKS and chosen + 0.05 <= 1.6:
        family.advice_checked += 1
        too_far = {**overrides, "edges": {"look_ahead_m": round(chosen + 0.05, 2)}}
        try:
            LaneDetector(PerceptionConfig.model_validate(too_far), ground=camera.ground)
        except PerceptionConfigError as exc:
            assert exc.suggested_look_ahead_m == chosen, str(exc)
            advised = {**overrides, "edges": {"look_ahead_m": exc.suggested_look_ahead_m}}
            fixed = LaneDetector(PerceptionConfig.model_validate(advised), ground=camera.ground)
            assert fixed.setup_for(*size).look_ahead_m == chosen
        else:  # beyond max_look_ahead_m (0.87) a farther look-ahead may well work
            assert chosen == detector.config.edges.max_look_ahead_m
    return detector


def tape_edges_in_view(world: World, detector: LaneDetector, camera: CameraModel,
                       pose: Pose2D) -> bool:
    """Both tapes (all four edges) run inside the ROI over at least 0.2 m of floor each, nearer
    than the look-ahead (where the detector has to tell them from seams)."""
    ground = camera.ground
    setup = detector.setup_for(camera.width_px, camera.height_px)
    roi = setup.polygon_px.astype(np.float64)
    look_ahead = setup.look_ahead_m
    half, tape = world.lane_width_m / 2.0, world.tapes[0].width_m
    c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
    xs = np.arange(pose.x_m - 0.5, pose.x_m + 2.5, 0.01)
    for lateral in (half - tape / 2, half + tape / 2, -half + tape / 2, -half - tape / 2):
        wx, wy = xs, np.full_like(xs, lateral)
        rx = c * (wx - pose.x_m) + s * (wy - pose.y_m)  # world -> robot frame
        ry = -s * (wx - pose.x_m) + c * (wy - pose.y_m)
        px = ground.floor_to_image(np.column_stack([rx, ry]))
        ok = np.isfinite(px).all(axis=1)
        inside = np.zeros(len(xs), bool)
        inside[ok] = points_in_polygon(px[ok], roi)
        inside &= rx <= look_ahead
        if inside.sum() * 0.01 < 0.2:
            return False
    return True


def no_tape_in_view(world: World, camera: CameraModel, pose: Pose2D) -> bool:
    c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
    pts = world.tape_samples
    rx = c * (pts[:, 0] - pose.x_m) + s * (pts[:, 1] - pose.y_m)
    ry = -s * (pts[:, 0] - pose.x_m) + c * (pts[:, 1] - pose.y_m)
    px = camera.ground.floor_to_image(np.column_stack([rx, ry]))
    ok = np.isfinite(px).all(axis=1)
    w, h = camera.width_px, camera.height_px
    seen = ok.copy()
    seen[ok] = (px[ok, 0] >= 0) & (px[ok, 0] < w) & (px[ok, 1] >= 0) & (px[ok, 1] < h)
    return not bool(seen.any())


def edge_on_tape(edge: LaneEdge, world: World, camera: CameraModel, pose: Pose2D) -> bool:
    """Every fifth of the reported segment, put on the floor, lies on a tape: within half the
    tape's width of its centre line, plus 2 pixels (at that point) and 3 mm."""
    ground = camera.ground
    t = np.linspace(0.0, 1.0, 5)
    pix = np.column_stack([edge.x1 + t * (edge.x2 - edge.x1), edge.y1 + t * (edge.y2 - edge.y1)])
    floor = ground.image_to_floor(pix)
    if not np.isfinite(floor).all():
        return False
    c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
    world_pts = np.column_stack([pose.x_m + c * floor[:, 0] - s * floor[:, 1],
                                 pose.y_m + s * floor[:, 0] + c * floor[:, 1]])
    distance = world.distance_to_tape(world_pts)
    tol = np.array([2.0 * ground.metres_per_px_across(u, v) for u, v in pix]) + 0.003
    return bool(np.all(distance <= world.tapes[0].width_m / 2.0 + tol))


def lane_pose(rng: np.random.Generator, floor: Floor) -> Pose2D:
    return Pose2D(float(rng.uniform(-0.2, 0.1)), float(rng.uniform(-0.2, 0.2)) * floor.lane_m / 2,
                  math.radians(float(rng.uniform(-6.0, 6.0))))


def tiles_pose(rng: np.random.Generator) -> Pose2D:
    x = LANE_START_X + TAPE_END_S + float(rng.uniform(0.2, 0.5))
    return Pose2D(x, float(rng.uniform(-0.3, 0.3)), math.radians(float(rng.uniform(-20, 20))))


def run_camera(family: Family, floor: Floor, world: World, texture: GroundTexture,
               camera: CameraModel, detector: LaneDetector, rng: np.random.Generator,
               lane_frames: bool = True, tiles_frames: int = FRAMES_PER_CLASS) -> None:
    renderer = CameraRenderer(texture, camera, noise_sigma=2.0, exposure_s=0.0,
                              seed=int(rng.integers(0, 2**31)), noise_bank_frames=3,
                              distorted=False)
    image = np.empty((camera.height_px, camera.width_px), np.uint8)
    width = camera.width_px
    tiles = family.tiles.setdefault(width, Tally())
    lanes = family.lanes.setdefault(width, Tally())
    label = (f"{width}px h={camera.height_m:.2f} pitch={camera.pitch_down_deg:.0f} "
             f"hfov={camera.hfov_deg:.0f} tape={1000 * floor.tape_m:.0f}mm "
             f"seam={1000 * floor.seam_m:.1f}mm tile={floor.tile_m:.2f} lane={floor.lane_m:.2f}")
    for _ in range(tiles_frames):
        pose = tiles_pose(rng)
        assert no_tape_in_view(world, camera, pose)
        obs = detector.detect(_render(renderer, pose, image), 0, 0.0)
        _count(tiles, obs)
        if obs.confidence >= CONFIDENT:
            tiles.bad.append(f"{label}: tiles only, confidence {obs.confidence:.2f} "
                             f"{dict(obs.components)}")
    for _ in range(FRAMES_PER_CLASS if lane_frames else 0):
        pose = lane_pose(rng, floor)
        for _ in range(10):
            if tape_edges_in_view(world, detector, camera, pose):
                break
            pose = lane_pose(rng, floor)
        else:
            pose = Pose2D(0.0, 0.0, 0.0)
        obs = detector.detect(_render(renderer, pose, image), 0, 0.0)
        _count(lanes, obs)
        on_tape = (obs.left is not None and obs.right is not None
                   and edge_on_tape(obs.left, world, camera, pose)
                   and edge_on_tape(obs.right, world, camera, pose))
        lanes.on_tape += on_tape
        decided = obs.both_edges and obs.confidence >= CONFIDENT
        lanes.good += decided and on_tape
        if not (decided and on_tape):
            lanes.bad.append(f"{label}: lane, confidence {obs.confidence:.2f}, on tape "
                             f"{on_tape} {dict(obs.components)}")


def _render(renderer: CameraRenderer, pose: Pose2D, image: np.ndarray) -> np.ndarray:
    return renderer.render_gray(pose, image, noise_index=renderer.next_noise_index())


def _count(tally: Tally, obs: LaneObservation) -> None:
    tally.frames += 1
    tally.confident += obs.both_edges and obs.confidence >= CONFIDENT
    tally.engaged += obs.both_edges and obs.confidence >= ENGAGE
    tally.max_confidence = max(tally.max_confidence, obs.confidence)


Setup = tuple[CameraModel, LaneDetector]


def cameras_for(floor: Floor, world: World, family: Family,
                rng: np.random.Generator) -> tuple[list[Setup], list[Setup]] | None:
    """One usable camera per size for this floor (the lane's tapes in view nearer than the
    look-ahead), or None when MAX_CAMERA_DRAWS draws give none at some size; and up to
    SPARE_CAMERAS of the cameras that work but cannot see this lane (for tiles-only frames)."""
    chosen: list[Setup] = []
    spare: list[Setup] = []
    for size in SIZES:
        for _ in range(MAX_CAMERA_DRAWS):
            camera = sample_camera(rng, size)
            detector = detector_for(camera, floor, family)
            if detector is None:
                continue
            if not tape_edges_in_view(world, detector, camera, Pose2D(0.0, 0.0, 0.0)):
                family.lane_out_of_view += 1
                if len(spare) < SPARE_CAMERAS:
                    spare.append((camera, detector))
                continue
            chosen.append((camera, detector))
            break
        else:
            return None
    return chosen, spare


def run_family() -> Family:
    rng = np.random.default_rng(SEED)
    family = Family()
    floors = 0
    while floors < FLOORS:
        floor = sample_floor(rng)
        world = world_of(floor)
        found = cameras_for(floor, world, family, rng)
        if found is None:
            family.floors_without_camera += 1
            continue
        floors += 1
        cameras, spare = found
        texture = paint_ground(world, TEXTURE_M_PER_PX, seed=int(rng.integers(0, 2**31)),
                               color=False)
        for camera, detector in cameras:
            family.cameras += 1
            run_camera(family, floor, world, texture, camera, detector, rng)
        for camera, detector in spare:
            family.spare_cameras += 1
            run_camera(family, floor, world, texture, camera, detector, rng, lane_frames=False,
                       tiles_frames=SPARE_TILES_FRAMES)
    return family


def _total(tallies: dict[int, Tally]) -> Tally:
    total = Tally()
    for t in tallies.values():
        total.frames += t.frames
        total.confident += t.confident
        total.engaged += t.engaged
        total.on_tape += t.on_tape
        total.good += t.good
        total.max_confidence = max(total.max_confidence, t.max_confidence)
        total.bad += t.bad
    return total


def test_tape_vs_seam_holds_on_random_cameras_and_floors(
    capsys: pytest.CaptureFixture[str],
) -> None:
    family = run_family()
    tiles, lanes = _total(family.tiles), _total(family.lanes)
    with capsys.disabled():
        looks = np.array(family.look_aheads)
        print(f"\n[camera family, seed {SEED}] {family.cameras} cameras on {FLOORS} floors (and "
              f"{family.spare_cameras} more on tiles only); look-ahead chosen by auto "
              f"{looks.min():.2f}-{looks.max():.2f} m (median {np.median(looks):.2f}, "
              f"{(looks < 0.87).sum()} of {len(looks)} nearer than 0.87 m; advice checked "
              f"{family.advice_checked}x), cameras refused outright {family.refused}, lane not "
              f"in view {family.lane_out_of_view}, floors no camera of the family could see in "
              f"{MAX_CAMERA_DRAWS} draws {family.floors_without_camera}")
        for width in sorted(family.tiles):
            t, ln = family.tiles[width], family.lanes[width]
            print(f"  {width}px: tiles only {t.confident}/{t.frames} confident (max "
                  f"{t.max_confidence:.2f}); lane {ln.good}/{ln.frames} decided on tape "
                  f"({ln.confident} >= {CONFIDENT}, {ln.engaged} >= {ENGAGE}, {ln.on_tape} on "
                  f"tape)")
        print(f"  all: tiles only {tiles.confident}/{tiles.frames} confident, max confidence "
              f"{tiles.max_confidence:.2f}; lane {lanes.good}/{lanes.frames} = "
              f"{lanes.good / lanes.frames:.1%} decided with both edges on tape "
              f"({lanes.confident / lanes.frames:.1%} >= {CONFIDENT}, "
              f"{lanes.engaged / lanes.frames:.1%} >= {ENGAGE})")
        for line in (tiles.bad + lanes.bad)[:12]:
            print("   ", line)
    assert tiles.frames >= 200 and lanes.frames >= 200
    assert tiles.confident == 0 and tiles.max_confidence < CONFIDENT, tiles.bad[:5]
    # The misses are grout running flush along a tape's inner edge (seams up to half the
    # tape): the band measures tape plus grout and the reported edge sits on the grout, 5-20 mm
    # off the tape. With the look-ahead chosen per camera (auto) the family keeps cameras the
    # refuse-then-advise loop used to discard, these floors among them (seeds 1-4, 9: 95.4-100%).
    assert lanes.good >= 0.95 * lanes.frames, lanes.bad[:5]
