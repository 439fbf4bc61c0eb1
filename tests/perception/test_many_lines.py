"""A textured floor's frame (terrazzo's chips at 320x240: 150-280 Hough segments within the edge
budget, `perception.canny.max_edge_share`, 500-odd without; 100-odd candidate lines a side)
takes two shortcuts that must not change a result: clustering compares only segments whose
directions are within the angle tolerance (`lines._compatible_pairs`, beyond 64 segments), and
the choice of tapes sifts a side's pairs with numpy before its loop
(`edge_choice._pairs_worth_checking`, from 16 lines). Each is held here to the plain way, element
for element, on seeded random input that includes the ties at the tolerance's very edge."""

from __future__ import annotations

import numpy as np
import pytest

from lanewarden.perception import edge_choice
from lanewarden.perception.edge_choice import tape_candidates
from lanewarden.perception.lines import LineRow, _compatible_dense, _compatible_pairs, _Pieces
from tests.perception.test_tape_rules import CONFIG, floor_line
from tests.perception.test_unsigned_outer_edge import SETUP


def random_pieces(count: int, seed: int) -> _Pieces:
    """`count` segments at random places and directions; their angles on a 2.5° grid, so many
    pairs differ by exactly the 5° tolerance used below, or by nothing."""
    rng = np.random.default_rng(seed)
    angle = rng.integers(8, 65, count) * 2.5  # 20°..160°
    length = rng.uniform(4.0, 40.0, count)
    x0, y0 = rng.uniform(0.0, 320.0, count), rng.uniform(40.0, 240.0, count)
    rad = np.radians(angle)
    seg = np.column_stack([x0, y0, x0 + length * np.cos(rad), y0 - length * np.sin(rad)])
    return _Pieces.of(seg, angle)


@pytest.mark.parametrize(("count", "seed"), [(65, 0), (300, 1), (600, 2)])
@pytest.mark.parametrize("offset_tol_px", [3.0, 1000.0])
def test_clustering_by_angle_window_is_the_whole_matrix(count: int, seed: int,
                                                         offset_tol_px: float) -> None:
    pieces = random_pieces(count, seed)
    dense = _compatible_dense(pieces, 5.0, offset_tol_px)
    rows, columns = _compatible_pairs(pieces, 5.0, offset_tol_px)
    windowed = np.zeros_like(dense)
    windowed[rows, columns] = True
    assert np.array_equal(windowed, dense)
    assert len(rows) == dense.sum()  # each pair once
    assert dense.sum() > count  # not vacuous: more than each segment with itself
    if offset_tol_px > 320.0:  # every pair within the angle: those exactly at it are compatible
        at_edge = np.abs(pieces.angle[None, :] - pieces.angle[:, None]) == 5.0
        assert (dense & at_edge).any()


def random_side(count: int, seed: int) -> list[LineRow]:
    """`count` candidate lines left of the robot: floor lines 0.05-0.6 m out on a grid of half
    the default tape's width (so many pairs are a tape's width apart), slightly turned, of random
    polarity (a third without), two of them with no floor position (with seed 2, one more
    without an angle)."""
    rng = np.random.default_rng(seed)
    half_tape = 0.5 * CONFIG.tape.width_m
    rows = []
    for k in range(count):
        y = 0.05 + half_tape * int(rng.integers(0, 24))
        x0 = float(rng.uniform(0.45, 0.8))
        x1 = x0 + float(rng.uniform(0.15, 0.5))
        turn = float(rng.uniform(-0.02, 0.02))
        polarity = float(rng.choice([-1.0, 0.0, 1.0]))
        rows.append(floor_line((x0, y), (x1, y + turn), polarity, line_id=k))
    rows[3] = rows[3]._replace(near_fx=float("nan"), near_fy=float("nan"))
    rows[7] = rows[7]._replace(far_fx=float("nan"))
    if seed == 2:  # a line made by hand without a direction: its pairs as the loop sees them
        rows[11] = rows[11]._replace(angle_deg=float("nan"))
    return rows


@pytest.mark.parametrize("unsigned_outer", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sifted_pairs_give_the_loops_tapes(seed: int, unsigned_outer: bool,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    rows = random_side(40, seed)
    monkeypatch.setattr(edge_choice, "_MAX_TAPE_CHECKS", 10_000)  # every tape, not the best 4

    def tapes() -> list[tuple[int, int, float, float]]:
        found = tape_candidates(rows, "left", SETUP.view, CONFIG, SETUP.look_ahead_m,
                                unsigned_outer=unsigned_outer)
        return [(t.inner.line_id, t.outer.line_id, t.score, t.width_m) for t in found]

    sifted = tapes()
    monkeypatch.setattr(edge_choice, "_SIFT_FROM_LINES", 10_000)  # the plain loop
    assert sifted == tapes()
    assert len(sifted) >= 3  # not vacuous
