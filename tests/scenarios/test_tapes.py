"""Tape as painted, measured in metres: dashed lines at their period, two different tapes per
lane, sheen as gloss, worn patches, tears and creases at their rates, ends cut at an angle, a
single-line track; seeded by the floor's seed."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from lanewarden.scenarios.tapes import CREASE_KEEPS, tape_damage
from lanewarden.scenarios.texture import GroundTexture, paint_ground
from lanewarden.scenarios.world import World, build_world
from tests.scenarios.helpers import spec_from

RES = 0.002
DARK_FLOOR = {"kind": "plain", "color": "#303030", "variation": 0.0, "grain": 0.0}


def world_of(tape: dict[str, Any], lane: dict[str, Any] | None = None,
             length_m: float = 3.0) -> World:
    spec = spec_from({"floor": DARK_FLOOR, "tape": tape,
                      "lane": {"segments": [{"straight_m": length_m}], **(lane or {})}})
    return build_world(spec, margin_m=0.5)


def painted(world: World, seed: int = 0) -> GroundTexture:
    return paint_ground(world, RES, seed=seed, color=True)


def along(texture: GroundTexture, y_m: float, x0: float = 0.0, x1: float = 3.0) -> np.ndarray:
    """Gray levels along the line y = `y_m` from x0 to x1 (texture pixels)."""
    (c0, r), (c1, _) = texture.world_to_px(np.array([[x0, y_m], [x1, y_m]])).round().astype(int)
    return texture.gray[r, c0:c1].astype(float)


def across(texture: GroundTexture, x_m: float, y0: float, y1: float) -> np.ndarray:
    (c, r0), (_, r1) = texture.world_to_px(np.array([[x_m, y1], [x_m, y0]])).round().astype(int)
    return texture.gray[r0:r1, c].astype(float)


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, length) of each run of True."""
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    return list(zip(starts.tolist(), (ends - starts).tolist(), strict=True))


def test_dashed_centre_line_repeats_at_its_period() -> None:
    world = world_of({"color": "#f0f0f0"}, {"dashes": {"tape": "left", "on_m": 0.3,
                                                       "off_m": 0.2}})
    texture = painted(world)
    dashes = runs(along(texture, 0.3) > 150)
    starts = np.array([s for s, _ in dashes]) * RES
    lengths = np.array([n for _, n in dashes[:-1]]) * RES
    assert np.diff(starts) == pytest.approx(0.5, abs=RES)  # period: 0.3 on + 0.2 off
    assert lengths == pytest.approx(0.3, abs=RES)
    assert len(runs(along(texture, -0.3) > 150)) == 1  # the right tape is whole


def test_two_different_tapes_per_lane() -> None:
    world = world_of({"color": "#f2f2ee", "width_m": 0.048,
                      "left": {"color": "#e8b818", "width_m": 0.025}},
                     {"dashes": {"tape": "left", "on_m": 0.3, "off_m": 0.3}})
    left, right = world.tapes
    assert (left.width_m, right.width_m) == (0.025, 0.048)
    texture = painted(world)
    assert texture.bgr is not None
    for tape, colour in ((left, (0x18, 0xB8, 0xE8)), (right, (0xEE, 0xF2, 0xF2))):
        profile = across(texture, 0.15, tape.offset_m - 0.05, tape.offset_m + 0.05)
        covered = np.clip((profile - 0x30) / (profile.max() - 0x30), 0.0, 1.0).sum() * RES
        assert covered == pytest.approx(tape.width_m, abs=RES)
        (c, r), = texture.world_to_px(np.array([[0.15, tape.offset_m]])).round().astype(int)
        assert tuple(texture.bgr[r, c]) == pytest.approx(colour, abs=3)
    # beside a dash (1.2..1.5 m) the nearest edge is the narrow left tape's
    assert world.clearance_to_edges(np.array([[1.35, 0.1], [1.35, -0.1]])) == pytest.approx(
        [0.2 - 0.025 / 2, 0.2 - 0.048 / 2], abs=1e-3)


def test_sheen_makes_the_tape_glossy() -> None:
    glossy = painted(world_of({"color": "#111111", "sheen": 1.0}))
    assert glossy.gloss is not None
    (c, r), = glossy.world_to_px(np.array([[1.0, 0.3]])).round().astype(int)
    assert glossy.gloss[r, c] == pytest.approx(0.1 / 0.25 * 255, abs=1)  # 10 % of the light
    assert glossy.gloss[r + 50, c] == 0  # the plain floor beside it is matte
    assert painted(world_of({"color": "#111111"})).gloss is None


def worn_share(texture: GroundTexture, y_m: float, length_m: float) -> float:
    line = along(texture, y_m, 0.0, length_m)
    return float(((line > 60) & (line < 200)).mean())


def test_wear_fades_its_share_of_the_tape() -> None:
    length = 10.0
    world = world_of({"color": "#f0f0f0", "wear": 0.3}, length_m=length)
    patches = tape_damage(world.tapes[0], np.random.default_rng(0))
    assert patches and all(0.3 <= p.keeps <= 0.6 for p in patches)
    sizes = [float(np.ptp(p.polygon[:, 0])) for p in patches]  # along x on a straight lane
    assert 0.3 * length <= sum(sizes) < 0.3 * length + 0.2
    # painted: about that share of the tape's centre line shows the floor through it
    share = worn_share(painted(world), 0.3, length)
    assert share == pytest.approx(0.3, abs=0.1)
    assert worn_share(painted(world_of({"color": "#f0f0f0"}, length_m=length)), 0.3,
                      length) < 0.01


def test_tears_and_creases_at_their_rates_per_metre() -> None:
    length = 20.0
    world = world_of({"color": "#f0f0f0", "tears_per_m": 3.0, "wrinkles_per_m": 5.0},
                     length_m=length)
    damage = tape_damage(world.tapes[0], np.random.default_rng(1))
    tears = [d for d in damage if d.keeps == 0.0]
    creases = [d for d in damage if d.keeps == CREASE_KEEPS]
    assert len(tears) == pytest.approx(3.0 * length, rel=0.25)
    assert len(creases) == pytest.approx(5.0 * length, rel=0.25)
    # painted: the tape's outer edge (1 mm inside it) shows the floor in torn notches
    texture = painted(world, seed=1)
    edge = along(texture, 0.3 + 0.048 / 2 - 0.001, 0.0, length)
    notches = runs(edge < 150)
    assert len(notches) >= 0.25 * len(tears)  # a tear takes one edge or the other


def test_tape_ends_are_cut_at_an_angle() -> None:
    world = world_of({"end_angle_deg": 30.0}, {"ends": {"left_m": 2.0}})
    tape = world.tapes[0]
    outline = tape.outlines()[0]
    n = len(tape.pieces[0])
    # left corner, then right corner, at the piece's end: the cut is at atan(dx / width)
    left_end, right_end = outline[n - 1], outline[n]
    angle = math.degrees(math.atan2(left_end[0] - right_end[0], tape.width_m))
    assert 1.0 < abs(angle) <= 30.0 + 1e-9
    assert world_of({}, {"ends": {"left_m": 2.0}}).tapes[0].outlines()[0][n - 1, 0] == (
        pytest.approx(2.0))


def test_single_line_track() -> None:
    world = world_of({"color": "#f0f0f0"}, {"lines": "centre", "ends": {"left_m": 2.5}})
    assert [t.side for t in world.tapes] == ["centre"]
    assert world.tapes[0].intervals == ((0.0, 2.5),)
    texture = painted(world)
    assert along(texture, 0.0, 0.5, 2.0).min() > 200  # the line along the centre
    assert along(texture, 0.3, 0.5, 2.0).max() < 60  # nothing at the lane's sides
    # the robot must stay within the lane's sides, where nothing is taped
    assert world.clearance_to_edges(np.array([[1.0, 0.0], [1.0, 0.25]])) == pytest.approx(
        [0.3, 0.05])


def test_damage_is_seeded_by_the_floor_seed() -> None:
    world = world_of({"color": "#f0f0f0", "wear": 0.2, "tears_per_m": 2.0})
    assert np.array_equal(painted(world, 5).gray, painted(world, 5).gray)
    assert not np.array_equal(painted(world, 5).gray, painted(world, 6).gray)
