"""The painted floors a process keeps (`scenarios.texture.paint_ground_cached`): up to two gray
floors, a colour floor alone, and room made before a floor is painted, so a campaign worker
never holds more than that while painting (it held two floors and painted a third, and colour
floors took a worker past its memory limit: docs/campaigns.md, the twenty-second run)."""

from __future__ import annotations

import pytest

from lanewarden.scenarios import texture
from lanewarden.scenarios.texture import paint_ground_cached
from lanewarden.scenarios.world import World, build_world
from tests.scenarios.helpers import spec_from

M_PER_PX = 0.02  # coarse: tiny floors, fast to paint


def _world(length_m: float) -> World:
    return build_world(spec_from({"lane": {"segments": [{"straight_m": length_m}]}}),
                       margin_m=0.5)


@pytest.fixture(autouse=True)
def empty_cache() -> None:
    texture._cache.clear()


def test_two_gray_floors_are_kept_and_the_oldest_goes_first() -> None:
    a, b, c = _world(1.0), _world(1.5), _world(2.0)
    first = paint_ground_cached(a, "a", M_PER_PX, 0)
    paint_ground_cached(b, "b", M_PER_PX, 0)
    assert paint_ground_cached(a, "a", M_PER_PX, 0) is first  # kept, and now the newest
    paint_ground_cached(c, "c", M_PER_PX, 0)
    assert [k[0] for k in texture._cache] == ["a", "c"]


def test_a_colour_floor_is_kept_alone_and_room_is_made_before_painting(
        monkeypatch: pytest.MonkeyPatch) -> None:
    a, b = _world(1.0), _world(1.5)
    paint_ground_cached(a, "a", M_PER_PX, 0)
    paint_ground_cached(b, "b", M_PER_PX, 0)
    held_while_painting = []
    real_paint = texture.paint_ground

    def counting(*args: object, **kwargs: object) -> texture.GroundTexture:
        held_while_painting.append(len(texture._cache))
        return real_paint(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(texture, "paint_ground", counting)
    colour = paint_ground_cached(a, "a", M_PER_PX, 0, color=True)
    assert colour.bgr is not None
    assert held_while_painting == [0]  # both gray floors let go before the colour one
    assert [k[0] for k in texture._cache] == ["a"]
    paint_ground_cached(b, "b", M_PER_PX, 0)  # a gray floor after it: the colour one goes
    assert held_while_painting == [0, 0]
    assert [(k[0], k[3]) for k in texture._cache] == [("b", False)]
