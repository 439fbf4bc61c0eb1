"""Every floor kind painted and measured in metres: tile, mat, block and plank seams where the
spec puts them, terrazzo's chips, foam's jigsaw teeth, parquet's alternating slats, concrete's
joints and cracks, carpet without seams; seeded; tape stands out on each."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import pytest

from lanewarden.scenarios.spec import KIND_DEFAULTS
from lanewarden.scenarios.texture import GroundTexture, paint_ground
from lanewarden.scenarios.world import build_world
from tests.scenarios.helpers import spec_from

RES = 0.0025
KINDS = ["tiles", "ceramic", "terrazzo", "foam", "wood", "parquet", "carpet", "concrete",
         "plain", "noisy"]


def painted(floor: dict[str, Any], seed: int = 0, length_m: float = 2.0, margin_m: float = 1.0,
            color: bool = False, **extra: Any) -> GroundTexture:
    spec = spec_from({"floor": floor, "lane": {"segments": [{"straight_m": length_m}]},
                      **extra})
    return paint_ground(build_world(spec, margin_m=margin_m), RES, seed=seed, color=color)


def off_lane(texture: GroundTexture) -> np.ndarray:
    """The floor beside the lane (rows left of the left tape), float."""
    top = texture.world_to_px(np.array([[0.0, 0.45]]))[0, 1]
    return texture.gray[: int(top)].astype(float)


def period_px(profile: np.ndarray, around_px: float) -> float:
    """The lag in [0.6, 1.4] x `around_px` where `profile`'s autocorrelation peaks, pixels."""
    p = profile - profile.mean()
    lags = np.arange(int(0.6 * around_px), int(1.4 * around_px) + 1)
    corr = [float((p[:-lag] * p[lag:]).mean()) for lag in lags]
    return float(lags[int(np.argmax(corr))])


def high_pass(profile: np.ndarray, sigma_px: float = 10.0) -> np.ndarray:
    smooth = cv2.GaussianBlur(profile.reshape(1, -1).astype(np.float64), (0, 0), sigma_px)
    return profile - smooth.ravel()


def seam_spacing_m(floor: np.ndarray, depth: float = 0.5, median: bool = True) -> float:
    """Lines of grout across `floor` (a texture region, rows x columns): each column's median
    (chips and grain are outliers) or mean, its sharp dips (at least `depth` of the deepest),
    the median spacing between them, metres."""
    dips = high_pass(np.median(floor, axis=0) if median else floor.mean(axis=0))
    low = dips < depth * dips.min()
    starts = np.nonzero(low & ~np.roll(low, 1))[0]
    ends = np.nonzero(low & ~np.roll(low, -1))[0]
    centres = (starts + ends) / 2.0
    return float(np.median(np.diff(centres))) * RES


@pytest.mark.parametrize("kind,tile_m", [("tiles", 0.30), ("ceramic", 0.45), ("terrazzo", 0.40),
                                         ("parquet", 0.24), ("concrete", 1.5)])
def test_seams_repeat_every_tile_m(kind: str, tile_m: float) -> None:
    """The floor beside the lane: the grout, block edges, saw-cut joints across it dip every
    `tile_m`."""
    floor: dict[str, Any] = {"kind": kind, "tile_m": tile_m}
    if kind == "concrete":
        floor.update(cracks_per_m2=0.0, stains_per_m2=0.0)
    if kind == "parquet":  # slats all of one shade, seams wider than a texture pixel
        floor.update(variation=0.0, grain=0.0, seam_m=0.005)
    texture = painted(floor, length_m=4.0 if tile_m < 1 else 8.0)
    if kind == "parquet":
        # two rows of blocks (y 0.48..0.96 m): a block edge runs along both, the slat seams at
        # the same x along one (half as deep in the mean)
        (_, r0), (_, r1) = texture.world_to_px(np.array([[0.0, 0.96], [0.0, 0.48]]))
        region = texture.gray[int(r0) + 1:int(r1)].astype(float)
        assert seam_spacing_m(region, 0.75, median=False) == pytest.approx(tile_m, abs=1.5 * RES)
    else:
        assert seam_spacing_m(off_lane(texture)) == pytest.approx(tile_m, abs=1.5 * RES)


def test_foam_mats_are_tile_m_square() -> None:
    texture = painted({"kind": "foam", "tile_m": 0.5, "colors": ["#808080"]}, length_m=4.0)
    mats = (off_lane(texture) > 70).astype(np.uint8)  # everything but the dark seams
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mats, connectivity=4)
    h, w = mats.shape
    inside = [stats[i, cv2.CC_STAT_AREA] for i in range(1, count)
              if stats[i, cv2.CC_STAT_LEFT] > 0 and stats[i, cv2.CC_STAT_TOP] > 0
              and stats[i, cv2.CC_STAT_LEFT] + stats[i, cv2.CC_STAT_WIDTH] < w
              and stats[i, cv2.CC_STAT_TOP] + stats[i, cv2.CC_STAT_HEIGHT] < h]
    # teeth move area between neighbours but keep it: each whole mat is 0.5 x 0.5 m
    whole = [area * RES * RES for area in inside if area * RES * RES > 0.05]
    assert len(whole) >= 5
    assert float(np.median(whole)) == pytest.approx(0.25, rel=0.03)


def test_the_kinds_sizes_are_their_own_unless_given() -> None:
    assert painted({"kind": "ceramic"}).gray.shape == painted({"kind": "tiles"}).gray.shape
    assert KIND_DEFAULTS["foam"]["tile_m"] == 0.60 and KIND_DEFAULTS["concrete"]["tile_m"] == 3.0


def test_wood_planks_and_butt_joints() -> None:
    texture = painted({"kind": "wood", "tile_m": 0.30, "variation": 0.0, "grain": 0.0},
                      length_m=4.0)
    floor = off_lane(texture)
    # planks 0.30 / 2.5 = 0.12 m wide along x: their seams run along rows
    assert seam_spacing_m(floor.T) == pytest.approx(0.12, abs=1.5 * RES)
    # each plank row is cut every 1.2 m
    (c0, r0), (c1, r1) = texture.world_to_px(np.array([[-1.2, 0.95], [5.2, 0.85]])).astype(int)
    assert seam_spacing_m(texture.gray[r0:r1, c0:c1].astype(float)) == pytest.approx(
        1.2, abs=1.5 * RES)


def test_terrazzo_chips_cover_their_fraction() -> None:
    matrix = KIND_DEFAULTS["terrazzo"]["color"]
    luma = 0.114 * int(matrix[5:7], 16) + 0.587 * int(matrix[3:5], 16) + 0.299 * int(
        matrix[1:3], 16)
    shares = []
    for fraction in (0.15, 0.45):
        floor = off_lane(painted({"kind": "terrazzo", "chip_fraction": fraction,
                                  "variation": 0.0, "grain": 0.0, "seam_m": 0.0}))
        shares.append(float((np.abs(floor - luma) > 12).mean()))
    # two of the five chip colours are within 12 grey levels of the cement: ~60 % are seen
    assert shares[0] == pytest.approx(0.6 * 0.15, abs=0.04)
    assert shares[1] == pytest.approx(0.6 * 0.45, abs=0.08)


def test_terrazzo_chips_are_chip_m_across() -> None:
    sizes = []
    for chip in (0.02, 0.05):
        floor = off_lane(painted({"kind": "terrazzo", "chip_m": chip, "colors": ["#000000"],
                                  "variation": 0.0, "grain": 0.0, "seam_m": 0.0}))
        count, _, stats, _ = cv2.connectedComponentsWithStats((floor < 60).astype(np.uint8))
        areas = stats[1:, cv2.CC_STAT_AREA] * RES * RES
        sizes.append(float(np.sqrt(np.median(areas[areas > 4 * RES * RES]))))
    assert sizes[1] / sizes[0] == pytest.approx(2.5, rel=0.25)


def test_foam_mats_interlock_with_jigsaw_teeth() -> None:
    tooth = 0.03
    texture = painted({"kind": "foam", "tile_m": 0.6, "tooth_m": tooth, "colors": ["#808080"],
                       "variation": 0.0, "grain": 0.0}, length_m=4.0)
    # the vertical mat edge at x = 1.2 m, over a mat's height (y from 0.6 to 1.2 m) less the
    # horizontal seams' teeth
    (c0, r0), (c1, r1) = texture.world_to_px(np.array([[1.1, 1.165], [1.3, 0.635]])).astype(int)
    window = texture.gray[r0:r1, c0:c1] < 60  # the dark seam
    cols = np.array([np.nonzero(row)[0].mean() for row in window if row.any()])
    depth_m = (cols.max() - cols.min()) * RES / 2
    assert depth_m == pytest.approx(tooth, abs=2 * RES)
    # five teeth per 0.6 m edge (one per four tooth depths): the seam steps out or in every
    # 0.06 m, 9 times between y = 0.635 and 1.165 m
    middle, half_depth = (cols.max() + cols.min()) / 2, 0.5 * tooth / RES
    sides = [1 if c > middle + half_depth / 2 else -1 for c in cols
             if abs(c - middle) > half_depth / 2]
    assert sum(a != b for a, b in zip(sides, sides[1:], strict=False)) == 9


def test_parquet_slats_alternate_direction_block_by_block() -> None:
    texture = painted({"kind": "parquet", "tile_m": 0.24, "slats": 4, "variation": 0.0,
                       "grain": 0.0}, length_m=4.0)
    gray = texture.gray.astype(np.float32)
    gx = np.abs(cv2.Sobel(gray, cv2.CV_32F, 1, 0))
    gy = np.abs(cv2.Sobel(gray, cv2.CV_32F, 0, 1))
    ratios = []
    for centre_x in (0.12, 0.36):  # two neighbouring blocks beside the lane
        (c, r), = texture.world_to_px(np.array([[centre_x, 0.84]])).astype(int)
        inner = np.s_[r - 20:r + 20, c - 20:c + 20]
        # a block with no x-seam has no y-gradient at all: its ratio is large, not a division by 0
        ratios.append(float(gx[inner].sum() / max(float(gy[inner].sum()), 1e-6)))
    # slats along y (seams along y: x-gradients) in one block, along x in the other
    assert max(ratios) > 5 and min(ratios) < 0.2
    # four slats: seams every 0.06 m inside a block
    (c, r), = texture.world_to_px(np.array([[0.12, 0.84]])).astype(int)
    block = gray[r - 40:r + 40, c - 40:c + 40]
    assert seam_spacing_m(block if ratios[0] > 1 else block.T) == pytest.approx(
        0.06, abs=1.5 * RES)


def test_concrete_cracks_and_stains() -> None:
    cracked = painted({"kind": "concrete", "cracks_per_m2": 2.0, "stains_per_m2": 0.0,
                       "variation": 0.0, "grain": 0.0, "seam_m": 0.0}, length_m=6.0)
    joint_free = cracked.gray.astype(float)
    dark = joint_free < joint_free.mean() - 20
    # thin dark jagged lines: many pixels, none wider than a few
    assert dark.mean() > 0.002
    stained = off_lane(painted({"kind": "concrete", "cracks_per_m2": 0.0, "stains_per_m2": 3.0,
                                "variation": 0.0, "grain": 0.0, "seam_m": 0.0}, length_m=6.0))
    assert stained.std() > off_lane(painted({"kind": "concrete", "cracks_per_m2": 0.0,
                                             "stains_per_m2": 0.0, "variation": 0.0,
                                             "grain": 0.0, "seam_m": 0.0}, length_m=6.0)).std() + 2


def test_carpet_has_texture_and_no_seams() -> None:
    floor = off_lane(painted({"kind": "carpet"}, length_m=4.0))
    assert floor.std() > 8.0
    # no line across the floor: no sharp dip in the column or row means (grout dips by 50)
    assert np.abs(high_pass(floor.mean(axis=0))).max() < 8
    assert np.abs(high_pass(floor.mean(axis=1))).max() < 8


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_is_seeded(kind: str) -> None:
    a = painted({"kind": kind}, seed=3, length_m=1.0, margin_m=0.6)
    b = painted({"kind": kind}, seed=3, length_m=1.0, margin_m=0.6)
    c = painted({"kind": kind}, seed=4, length_m=1.0, margin_m=0.6)
    assert np.array_equal(a.gray, b.gray)
    assert not np.array_equal(a.gray, c.gray)


@pytest.mark.parametrize("kind", KINDS)
def test_dark_tape_stands_out_on_every_kind(kind: str) -> None:
    texture = painted({"kind": kind}, tape={"color": "#141414"})
    tape = texture.world_to_px(np.array([[1.0, 0.3]])).round().astype(int)[0]
    floor = off_lane(texture)
    assert texture.gray[tape[1], tape[0]] < np.percentile(floor, 50) - 25


@pytest.mark.parametrize("kind", ["ceramic", "terrazzo", "parquet", "concrete"])
def test_glossy_kinds_paint_their_gloss_and_matte_seams(kind: str) -> None:
    texture = painted({"kind": kind})
    assert texture.gloss is not None
    gloss = off_lane(GroundTexture(gray=texture.gloss, bgr=None, m_per_px=RES,
                                   x_min=texture.x_min, y_max=texture.y_max, fill_gray=0,
                                   fill_bgr=(0, 0, 0)))
    expected = KIND_DEFAULTS[kind]["gloss"] / 0.25 * 255
    assert np.median(gloss) == pytest.approx(expected, abs=1.5)
    if kind in ("ceramic", "terrazzo", "parquet"):
        assert gloss.min() < expected - 8  # grout, joints: matte


def test_matte_floors_and_no_ceiling_paint_no_gloss() -> None:
    assert painted({"kind": "foam"}).gloss is None
    assert painted({"kind": "ceramic"}, lighting={"ceiling": None}).gloss is None
