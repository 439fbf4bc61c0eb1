"""The floor as the camera sees it from above: the world painted into a top-down texture, once.

Texture frame: pixel (col, row) covers the world square whose centre is
(x_min + (col + 0.5) * m_per_px, y_max - (row + 0.5) * m_per_px): rows go DOWN in y, so the
texture reads like a map. Painting order: the floor's own surface (`scenarios.floors`: tiles and
grout, chips, mats, planks, carpet, concrete), tapes on top (`scenarios.tapes`: anti-aliased
polygons, worn, torn, creased), then the painted light (gradient, glare). The room's brightness and
colour are not painted: the camera's exposure answers them (`scenarios.camera_effects`). Where
something is glossy and ceiling lights shine, a gloss layer too (`scenarios.highlights`).

Deterministic for a given (world, m_per_px, seed). Never renders a camera view, never reads a
clock. Floats are used only while painting; the result is uint8.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.detector import GRAY_WEIGHTS_BGR
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.floors import FloorPainter
from lanewarden.scenarios.spec import MAX_GLOSS, TAPE_GLOSS_AT_FULL_SHEEN
from lanewarden.scenarios.tapes import TapeCoverage, tape_damage
from lanewarden.scenarios.world import World

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]

#: Largest floor texture painted, pixels: the result is 1 byte per pixel (4 with colour) and the
#: painting's float layers exist for one strip of rows at a time, so this bounds it at ~50 MB
#: gray (the lecture's course is 27 Mpx at the default 2.5 mm per pixel).
MAX_TEXTURE_PIXELS = 50_000_000

#: Perception's gray as weights of (b, g, r) (`perception.detector.perception_gray`), so a gray
#: texture equals perception's gray of the colour texture.
GRAY_WEIGHTS = GRAY_WEIGHTS_BGR


@dataclass(frozen=True, eq=False)
class GroundTexture:
    """The painted floor. `gray` always; `bgr` only when colour was asked for."""

    gray: U8
    bgr: U8 | None
    m_per_px: float
    x_min: float
    y_max: float
    #: What the camera sees beyond the painted floor (the floor's mean), gray and BGR.
    fill_gray: int
    fill_bgr: tuple[int, int, int]
    #: How glossy each pixel is (0..255 for gloss 0..`highlights.GLOSS_FULL_SCALE`); None where
    #: nothing is glossy (no highlights are drawn).
    gloss: U8 | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.gray.shape[0]), int(self.gray.shape[1]))

    @cached_property
    def gray_transposed(self) -> U8:
        """`gray` stored transposed (columns as rows), made once per texture: the renderer reads
        it when the robot faces along x (see `CameraRenderer`)."""
        return np.ascontiguousarray(self.gray.T)

    @cached_property
    def bgr_transposed(self) -> U8 | None:
        """`bgr` stored transposed, made once per texture (None without colour)."""
        return None if self.bgr is None else np.ascontiguousarray(self.bgr.transpose(1, 0, 2))

    @cached_property
    def gloss_transposed(self) -> U8 | None:
        """`gloss` stored transposed, made once per texture (None without gloss)."""
        return None if self.gloss is None else np.ascontiguousarray(self.gloss.T)

    def world_to_px(self, points: FloatArray) -> FloatArray:
        """World metres (N, 2) -> texture pixel coordinates (N, 2) (col, row), pixel centres at
        integers."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        col = (pts[:, 0] - self.x_min) / self.m_per_px - 0.5
        row = (self.y_max - pts[:, 1]) / self.m_per_px - 0.5
        return np.column_stack([col, row])

    def px_from_world_matrix(self) -> FloatArray:
        """3x3 affine: homogeneous world (x, y, 1) -> texture (col, row, 1)."""
        r = self.m_per_px
        return np.array(
            [[1.0 / r, 0.0, -self.x_min / r - 0.5], [0.0, -1.0 / r, self.y_max / r - 0.5],
             [0.0, 0.0, 1.0]]
        )


def _grid_coords(world: World, m_per_px: float) -> tuple[F32, F32, int, int]:
    x0, y0, x1, y1 = world.bounds
    width = int(math.ceil((x1 - x0) / m_per_px))
    height = int(math.ceil((y1 - y0) / m_per_px))
    if width * height > MAX_TEXTURE_PIXELS:
        raise ScenarioError(
            f"{world.name}: the floor texture would be {width} x {height} px at "
            f"{m_per_px * 1000:g} mm per pixel, expected at most {MAX_TEXTURE_PIXELS} px (a "
            "larger simulation.texture_mm_per_px, or a smaller world)"
        )
    xs = (x0 + (np.arange(width, dtype=np.float32) + 0.5) * m_per_px).astype(np.float32)
    ys = (y1 - (np.arange(height, dtype=np.float32) + 0.5) * m_per_px).astype(np.float32)
    return xs, ys, width, height


#: Rows painted at a time: every float layer exists for one strip only, never for the whole floor
#: (a whole-floor float32 layer of a large world is ~100 MB; ten of them were the old peak).
STRIP_ROWS = 128


class _Illumination:
    """Multiplicative light (the gradient) and additive glare for any strip of rows; None where
    uniform. The room's overall brightness and colour are not painted: the camera's exposure
    answers them (`scenarios.camera_effects`)."""

    def __init__(self, world: World, xs: F32, ys: F32) -> None:
        light = world.lighting
        start = world.centreline.points[0]
        a = math.radians(light.gradient.direction_deg)
        self._gx = ((xs - start[0]) * math.cos(a)).astype(np.float32)
        self._gy = ((ys - start[1]) * math.sin(a)).astype(np.float32)
        self._light = light
        self.uniform = light.gradient.per_m == 0.0
        self._xs, self._ys = xs, ys
        self._spots = []
        for spot in light.glare:
            point, heading = world.centreline.at(spot.at_m)
            cx = point[0] - spot.offset_m * math.sin(heading)
            cy = point[1] + spot.offset_m * math.cos(heading)
            self._spots.append((cx, cy, spot.radius_m, spot.strength))

    @property
    def has_glare(self) -> bool:
        return bool(self._spots)

    def rows(self, r0: int, r1: int) -> tuple[F32 | None, F32 | None]:
        light = self._light
        field: F32 | None = None
        if not self.uniform:
            field = np.empty((r1 - r0, len(self._xs)), np.float32)
            np.add(self._gy[r0:r1, None], self._gx[None, :], out=field)
            field *= light.gradient.per_m
            field += 1.0
            np.maximum(field, 0.0, out=field)
        if not self._spots:
            return field, None
        xs, ys = self._xs, self._ys[r0:r1]
        glare = np.zeros((r1 - r0, len(xs)), np.float32)
        for cx, cy, radius, strength in self._spots:
            dx2 = ((xs - cx) ** 2).astype(np.float32)
            dy2 = ((ys - cy) ** 2).astype(np.float32)
            cols = np.nonzero(dx2 < (4 * radius) ** 2)[0]
            rows = np.nonzero(dy2 < (4 * radius) ** 2)[0]
            if len(cols) == 0 or len(rows) == 0:
                continue
            a0, a1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
            blob = np.exp(-(dy2[a0:a1, None] + dx2[None, c0:c1]) / (2 * radius**2))
            glare[a0:a1, c0:c1] += (strength * blob).astype(np.float32)
        return field, glare


def _luma(c: tuple[int, int, int] | tuple[float, float, float]) -> float:
    return float(sum(wt * v for wt, v in zip(GRAY_WEIGHTS, c, strict=True)))


def paint_ground(world: World, m_per_px: float, seed: int, color: bool = True) -> GroundTexture:
    """Paint the world's floor (`scenarios.floors`), tapes (`scenarios.tapes`) and light into a
    texture of `m_per_px` metres per pixel, and how glossy each pixel is when anything is
    glossy and ceiling lights shine on it.

    Painted in strips of STRIP_ROWS rows: the float layers exist for one strip at a time, so the
    peak memory is the uint8 result plus a few strips (and a floor kind's own layers)."""
    rng = np.random.default_rng([seed, 0x5CE7])
    xs, ys, width, height = _grid_coords(world, m_per_px)
    floor = FloorPainter(world.floor, m_per_px, rng, xs, ys)
    frame = GroundTexture(
        gray=np.zeros((1, 1), np.uint8), bgr=None, m_per_px=m_per_px,
        x_min=world.bounds[0], y_max=world.bounds[3], fill_gray=0, fill_bgr=(0, 0, 0),
    )
    # One coverage per look of tape (tapes of one colour and sheen share theirs).
    damage_rng = np.random.default_rng([seed, 0x7A9E])
    looks: dict[tuple[tuple[int, int, int], float], tuple[list[FloatArray],
                                                          list[tuple[FloatArray, float]]]] = {}
    for tape in world.tapes:
        outlines, damage = looks.setdefault((tape.color_bgr, tape.look.sheen), ([], []))
        outlines += [frame.world_to_px(o) for o in tape.outlines()]
        damage += [(frame.world_to_px(d.polygon), d.keeps) for d in tape_damage(tape, damage_rng)]
    tapes = [(TapeCoverage(outlines, damage, (height, width)), tape_bgr, sheen)
             for (tape_bgr, sheen), (outlines, damage) in looks.items()]
    lighting = _Illumination(world, xs, ys)
    glossy = world.lighting.ceiling is not None and (
        world.floor.gloss > 0 or any(sheen > 0 for _, _, sheen in tapes))

    # The gray texture is painted the same way with or without colour, so what perception sees
    # does not depend on whether a video is recorded: channel 0 is perception's gray of the colours.
    channels: list[Callable[[tuple[int, int, int]], float]] = [_luma]
    if color:
        channels += [lambda c, i=i: float(c[i]) for i in range(3)]  # type: ignore[misc]
    gray = np.empty((height, width), np.uint8)
    bgr = np.empty((height, width, 3), np.uint8) if color else None
    gloss = np.empty((height, width), np.uint8) if glossy else None
    for r0 in range(0, height, STRIP_ROWS):
        r1 = min(height, r0 + STRIP_ROWS)
        strip = floor.rows(r0, r1)
        covers = [(cover.rows(r0, r1), tape_bgr, sheen) for cover, tape_bgr, sheen in tapes]
        light, glare = lighting.rows(r0, r1)
        # value = light * (floor * (1 - tape) + sum(tape_k * colour_k) * (1 + 0.3 (shade - 1)))
        #         + 255 * glare      (tape is smoother than the floor under it)
        not_tape = np.ones_like(strip.shade)
        for cover, _, _ in covers:
            cv2.subtract(not_tape, cover, dst=not_tape)
        base = not_tape if light is None else cv2.multiply(not_tape, light)
        weights = [(cv2.multiply(weight, base), colour) for weight, colour in strip.parts]
        smooth = cv2.addWeighted(strip.shade, 0.3, strip.shade, 0.0, 0.7)
        if light is not None:
            smooth = cv2.multiply(smooth, light)
        tape_weights = [(cv2.multiply(cover, smooth), tape_bgr) for cover, tape_bgr, _ in covers]
        work = np.empty_like(strip.shade)
        for index, value_of in enumerate(channels):
            work[:] = 0.0
            for weight, colour in (*weights, *tape_weights):
                cv2.scaleAdd(weight, value_of(colour), work, dst=work)
            if glare is not None:
                cv2.scaleAdd(glare, 255.0, work, dst=work)
            out = gray[r0:r1] if index == 0 else bgr[r0:r1, :, index - 1]  # type: ignore[index]
            out[:] = cv2.convertScaleAbs(work)
        if gloss is not None:
            shine = np.zeros_like(strip.shade) if strip.gloss is None else cv2.multiply(
                strip.gloss, not_tape)
            for cover, _, sheen in covers:
                if sheen > 0:
                    cv2.scaleAdd(cover, sheen * TAPE_GLOSS_AT_FULL_SHEEN, shine, dst=shine)
            gloss[r0:r1] = cv2.convertScaleAbs(shine, alpha=255.0 / MAX_GLOSS)
    fill_gray = int(np.median(gray[:: max(1, height // 64), :: max(1, width // 64)]))
    if bgr is not None:
        sample = bgr[:: max(1, height // 64), :: max(1, width // 64)].reshape(-1, 3)
        fill_bgr = tuple(int(v) for v in np.median(sample, axis=0))
    else:
        fill_bgr = (fill_gray, fill_gray, fill_gray)
    return GroundTexture(
        gray=gray, bgr=bgr, m_per_px=m_per_px, x_min=world.bounds[0], y_max=world.bounds[3],
        fill_gray=fill_gray, fill_bgr=(fill_bgr[0], fill_bgr[1], fill_bgr[2]), gloss=gloss,
    )


@dataclass(frozen=True, eq=False)
class FloorMark:
    """Something painted over a finished floor (a fault on the floor): `polygon` (N, 2) world
    metres; `paint` blends towards `color_bgr` by `opacity`, `shade` multiplies the light by
    `factor` (a shadow)."""

    polygon: FloatArray
    mode: str
    color_bgr: tuple[int, int, int] = (0, 0, 0)
    opacity: float = 1.0
    factor: float = 1.0


def with_marks(texture: GroundTexture, marks: list[FloorMark],
               supersample: int = 4) -> GroundTexture:
    """A copy of `texture` with `marks` painted over it (anti-aliased, only around each mark);
    `texture` itself is left as it is (it may be shared through the cache)."""
    if not marks:
        return texture
    gray = texture.gray.copy()
    bgr = None if texture.bgr is None else texture.bgr.copy()
    h, w = gray.shape
    shift = 3
    scale = supersample * (1 << shift)
    for mark in marks:
        outline = texture.world_to_px(mark.polygon)
        c0, r0 = np.floor(outline.min(axis=0)).astype(int) - 1
        c1, r1 = np.ceil(outline.max(axis=0)).astype(int) + 2
        c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, w), min(r1, h)
        if c0 >= c1 or r0 >= r1:
            continue
        big = np.zeros(((r1 - r0) * supersample, (c1 - c0) * supersample), np.uint8)
        local = (outline - (c0, r0) + 0.5) * scale - (1 << shift) * 0.5
        cv2.fillPoly(big, [np.round(local).astype(np.int32).reshape(-1, 1, 2)], 255,
                     lineType=cv2.LINE_8, shift=shift)
        cover = cv2.resize(big, (c1 - c0, r1 - r0), interpolation=cv2.INTER_AREA).astype(
            np.float32) * (1.0 / 255.0)
        targets: list[tuple[U8, float]] = [(gray[r0:r1, c0:c1], float(
            sum(wt * v for wt, v in zip(GRAY_WEIGHTS, mark.color_bgr, strict=True))))]
        if bgr is not None:
            targets += [(bgr[r0:r1, c0:c1, c], float(mark.color_bgr[c])) for c in range(3)]
        for region, value in targets:
            pixels = region.astype(np.float32)
            if mark.mode == "shade":
                pixels *= 1.0 - (1.0 - mark.factor) * cover
            else:
                alpha = mark.opacity * cover
                pixels += alpha * (value - pixels)
            region[...] = np.clip(np.rint(pixels), 0, 255).astype(np.uint8)
    return GroundTexture(gray=gray, bgr=bgr, m_per_px=texture.m_per_px, x_min=texture.x_min,
                         y_max=texture.y_max, fill_gray=texture.fill_gray,
                         fill_bgr=texture.fill_bgr, gloss=texture.gloss)


#: Painted floors kept per process (a campaign worker runs the same world and seed many times),
#: counted in gray floors: a colour floor (about four times the bytes, and a transposed copy of
#: each: 270 MB for `wide-bends` at 2.5 mm) counts as this many, so it is kept alone. Room is
#: made before a floor is painted, not after: the floors kept while a colour floor was painted
#: took a campaign worker past its 1 GB limit (seed 4's r00569, r00626 of the twenty-second run).
TEXTURE_CACHE_SIZE = 2
#: (world key, resolution, seed, colour) -> (the painted floor, the gray floors it counts as)
_cache: dict[tuple[object, ...], tuple[GroundTexture, int]] = {}


def paint_ground_cached(world: World, key: object, m_per_px: float, seed: int,
                        color: bool = False) -> GroundTexture:
    """`paint_ground`, remembered for the last (world, resolution, seed) combinations, up to
    TEXTURE_CACHE_SIZE gray floors (a colour floor fills the cache alone). `key` must identify
    everything of the world that is painted (the caller's scenario floor, tape, lane, lighting
    and margin). The texture is shared: never modify it (`with_marks` copies)."""
    full = (key, m_per_px, seed, color)
    slots = TEXTURE_CACHE_SIZE if color else 1
    kept = _cache.pop(full, None)
    if kept is None:
        # room first: the floors kept and the one being painted are never more than it holds
        while _cache and sum(n for _, n in _cache.values()) + slots > TEXTURE_CACHE_SIZE:
            _cache.pop(next(iter(_cache)))
        texture = paint_ground(world, m_per_px, seed, color=color)
    else:
        texture = kept[0]
    _cache[full] = (texture, slots)
    return texture
