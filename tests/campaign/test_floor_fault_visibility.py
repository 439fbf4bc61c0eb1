"""A floor fault counts as in view when what it changes is in view. Run 477 of a default
campaign shaded the whole lane from an edge 0.43 m left of its centre: in a left bend the edge
left the region of interest while the shaded lane filled it, the fault's window closed, and the
LANE_LOST that followed was filed as a false halt."""

from __future__ import annotations

import numpy as np

from lanewarden.scenarios.faults import floor_mark
from lanewarden.scenarios.library import resolve_scenario
from lanewarden.scenarios.spec import FaultSpec
from lanewarden.scenarios.world import build_world


def _seen_laterals(side: str) -> set[float]:
    """Where a shadow edge 0.43 m left of the centre of a straight lane, shading towards `side`,
    counts as in view: the lateral offsets of its visibility samples (m, rounded to mm)."""
    world = build_world(resolve_scenario("straight"), margin_m=1.0)
    spec = FaultSpec(kind="shadow_edge", at_m=1.0, length_m=1.0, offset_m=0.43, side=side,
                     intensity=0.5)
    _, samples = floor_mark(world, spec)
    start = world.centreline.at(1.0)[0]
    # the straight lane runs along x: the lateral offset is the y difference
    return set(np.round(samples[:, 1] - start[1], 3).tolist())


def test_a_shadow_over_the_lane_is_seen_where_the_lane_is() -> None:
    # the edge (0.43 m left) and, inside the shade, both tapes (+-0.30 m) and the centre
    assert _seen_laterals("right") == {0.43, 0.3, 0.0, -0.3}


def test_a_shadow_beside_the_lane_is_seen_by_its_edge_only() -> None:
    assert _seen_laterals("left") == {0.43}
