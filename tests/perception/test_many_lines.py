"""A textured floor's frame (terrazzo's chips at 320x240: 150-280 Hough segments within the edge
budget, `perception.canny.max_edge_share`, 500-odd without; 100-odd candidate lines a side)
takes a shortcut that must not change a result: the choice of tapes sifts a side's pairs with
numpy before its loop (`edge_choice._pairs_worth_checking`, from 16 lines), through a window over
the lines' sorted angles (`lines.pairs_within_angle`). Both are held here to the plain way, element
for element, on seeded random input that includes the ties at the tolerance's very edge."""

from __future__ import annotations

import numpy as np
import pytest

from lanewarden.perception import edge_choice
from lanewarden.perception.edge_choice import tape_candidates
from lanewarden.perception.lines import LineRow, pairs_within_angle
from tests.perception.test_tape_rules import CONFIG, floor_line
from tests.perception.test_unsigned_outer_edge import SETUP


@pytest.mark.parametrize(("count", "seed"), [(2, 0), (65, 0), (300, 1), (600, 2)])
def test_the_angle_window_finds_every_pair_within_the_tolerance(count: int, seed: int) -> None:
    """Angles on a 2.5° grid, so many pairs differ by exactly the 5° tolerance, or by nothing:
    the window gives each pair within it once, (smaller, larger), those at its very edge
    included, and no other."""
    angle = np.random.default_rng(seed).integers(8, 65, count) * 2.5  # 20°..160°
    i, j = pairs_within_angle(angle, 5.0)
    found = sorted(zip(i.tolist(), j.tolist(), strict=True))
    every = [(a, b) for a in range(count) for b in range(a + 1, count)
             if abs(angle[a] - angle[b]) <= 5.0]
    assert found == every
    if count > 2:  # not vacuous: ties at the edge are among them
        assert any(abs(angle[a] - angle[b]) == 5.0 for a, b in every)


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
