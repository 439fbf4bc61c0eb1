"""The floor painted strip by strip: the same floor whatever the strip size, cached per world and
seed without sharing mutations, and floor faults painted over a copy."""

from __future__ import annotations

import numpy as np
import pytest

from lanewarden.scenarios import texture as texture_module
from lanewarden.scenarios.faults import floor_marks
from lanewarden.scenarios.spec import FaultSpec, parse_scenario
from lanewarden.scenarios.texture import paint_ground, paint_ground_cached, with_marks
from lanewarden.scenarios.world import build_world


def small_world(kind: str = "tiles", angle: float = 0.0):  # type: ignore[no-untyped-def]
    spec = parse_scenario({"name": "t", "floor": {"kind": kind, "grid_angle_deg": angle},
                           "lane": {"segments": [{"straight_m": 1.0},
                                                 {"arc_radius_m": 1.0, "turn_deg": 60}]},
                           "lighting": {"gradient": {"per_m": 0.05},
                                        "glare": [{"at_m": 0.8}]}}, "t.yaml")
    return build_world(spec, margin_m=1.0)


@pytest.mark.parametrize("kind,angle", [("tiles", 0.0), ("tiles", 20.0), ("wood", 0.0),
                                        ("plain", 0.0), ("noisy", 0.0)])
def test_the_strip_size_does_not_change_the_floor(monkeypatch: pytest.MonkeyPatch, kind: str,
                                                  angle: float) -> None:
    world = small_world(kind, angle)
    reference = paint_ground(world, 0.01, seed=3, color=True)
    monkeypatch.setattr(texture_module, "STRIP_ROWS", 64)
    other = paint_ground(world, 0.01, seed=3, color=True)
    assert np.array_equal(reference.gray, other.gray)
    assert reference.bgr is not None and other.bgr is not None
    assert np.array_equal(reference.bgr, other.bgr)
    # a different seed paints a different floor
    assert not np.array_equal(reference.gray, paint_ground(world, 0.01, seed=4).gray)


def test_cached_floor_is_shared_and_marks_go_on_a_copy() -> None:
    world = small_world()
    first = paint_ground_cached(world, "small", 0.01, 3)
    assert paint_ground_cached(world, "small", 0.01, 3) is first
    before = first.gray.copy()
    mark = FaultSpec(kind="floor_mark", at_m=0.5, width_m=0.05, intensity=1.0)
    marked = with_marks(first, floor_marks(world, [mark]))
    assert np.array_equal(first.gray, before)
    changed = marked.gray != first.gray
    assert changed.sum() > 100  # a 5 cm stripe across the lane, at 1 cm per pixel
    assert marked.gray[changed].mean() < first.gray[changed].mean()  # darker, like the tape
