"""The floor as the camera sees it from above: the world painted into a top-down texture, once.

Texture frame: pixel (col, row) covers the world square whose centre is
(x_min + (col + 0.5) * m_per_px, y_max - (row + 0.5) * m_per_px): rows go DOWN in y, so the
texture reads like a map. Painting order: floor albedo (tiles and seams, planks, plain, speckle),
tapes on top (anti-aliased polygons), then the light (brightness, gradient, glare).

Deterministic for a given (world, m_per_px, seed). Never renders a camera view, never reads a
clock. Floats are used only while painting; the result is uint8.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.spec import color_bgr
from lanewarden.scenarios.world import World

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]

#: Largest floor texture painted, pixels: painting takes ~35 bytes per pixel at its peak, so this
#: bounds it at ~1.8 GB (the lecture's course is 27 Mpx at the default 2.5 mm per pixel).
MAX_TEXTURE_PIXELS = 50_000_000

#: OpenCV's BGR -> gray weights, so a gray texture equals the gray of the colour texture.
GRAY_WEIGHTS = (0.114, 0.587, 0.299)


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

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.gray.shape[0]), int(self.gray.shape[1]))

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


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, int], cell_px: float) -> F32:
    """Zero-mean, unit-ish noise varying over `cell_px` pixels (upsampled random grid)."""
    h, w = shape
    gh, gw = max(2, int(h / cell_px) + 2), max(2, int(w / cell_px) + 2)
    small = rng.standard_normal((gh, gw)).astype(np.float32)
    return np.asarray(cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC), dtype=np.float32)


def _fine_noise(rng: np.random.Generator, shape: tuple[int, int], period_px: int = 1024) -> F32:
    """Unit white noise; a random `period_px` square repeated (cheap, and invisible under the
    floor's other variation)."""
    h, w = shape
    tile = rng.standard_normal((min(h, period_px), min(w, period_px)), dtype=np.float32)
    reps = (-(-h // tile.shape[0]), -(-w // tile.shape[1]))
    return np.tile(tile, reps)[:h, :w]


def _coverage_1d(coord: F32, period: float, width: float, m_per_px: float) -> F32:
    """Fraction of each pixel (1-D, along one axis) covered by seams of `width` every `period`."""
    if width <= 0:
        return np.zeros_like(coord)
    # Distance from the pixel centre to the nearest seam centre line.
    phase = np.mod(coord, period)
    dist = np.minimum(phase, period - phase)
    cover = np.clip((width / 2.0 + m_per_px / 2.0 - dist) / m_per_px, 0.0, 1.0)
    return np.minimum(cover, width / m_per_px).astype(np.float32)


def _floor_layers(world: World, m_per_px: float, rng: np.random.Generator,
                  xs: F32, ys: F32) -> tuple[F32, F32]:
    """(shade, seam coverage), both (H, W) float32: shade ~1.0 multiplies the floor colour,
    coverage in [0, 1] blends towards the seam colour."""
    floor = world.floor
    h, w = len(ys), len(xs)
    shade = np.ones((h, w), np.float32)
    seams = np.zeros((h, w), np.float32)
    ox, oy = floor.grid_offset_m
    if floor.kind == "tiles":
        a = math.radians(floor.grid_angle_deg)
        ca, sa = math.cos(a), math.sin(a)
        if abs(sa) < 1e-9:
            u1 = (xs - ox).astype(np.float32)
            v1 = (ys - oy).astype(np.float32)
            cu = _coverage_1d(u1, floor.tile_m, floor.seam_m, m_per_px)
            cv = _coverage_1d(v1, floor.tile_m, floor.seam_m, m_per_px)
            np.maximum(cv[:, None], cu[None, :], out=seams)
            iu = np.floor(u1 / floor.tile_m).astype(np.int64)
            iv = np.floor(v1 / floor.tile_m).astype(np.int64)
        else:
            gx, gy = np.meshgrid(xs - ox, ys - oy)
            u = (ca * gx + sa * gy).astype(np.float32)
            v = (-sa * gx + ca * gy).astype(np.float32)
            cu2 = _coverage_1d(u, floor.tile_m, floor.seam_m, m_per_px)
            cv2_ = _coverage_1d(v, floor.tile_m, floor.seam_m, m_per_px)
            np.maximum(cu2, cv2_, out=seams)
            iu = np.floor(u / floor.tile_m).astype(np.int64)
            iv = np.floor(v / floor.tile_m).astype(np.int64)
        nu = int(iu.max() - iu.min() + 1)
        nv = int(iv.max() - iv.min() + 1)
        table = (1.0 + floor.variation * rng.standard_normal((nv, nu))).astype(np.float32)
        if iu.ndim == 1:
            shade[:] = np.take(table[iv - iv.min()], iu - iu.min(), axis=1)
        else:
            shade[:] = table[iv - iv.min(), iu - iu.min()]
        shade *= 1.0 + 0.5 * floor.grain * _smooth_noise(rng, (h, w), 0.05 / m_per_px)
    elif floor.kind == "wood":
        plank = floor.tile_m / 2.5
        v = (ys - oy).astype(np.float32)
        seams[:] = _coverage_1d(v, plank, floor.seam_m, m_per_px)[:, None]
        rows = np.floor(v / plank).astype(np.int64)
        nrows = int(rows.max() - rows.min() + 1)
        plank_shade = (1.0 + floor.variation * rng.standard_normal(nrows)).astype(np.float32)
        shade *= plank_shade[rows - rows.min()][:, None]
        # Butt joints: each plank row is cut every 1.2 m, staggered.
        stagger = rng.uniform(0.0, 1.2, nrows).astype(np.float32)
        for r in range(nrows):
            sel = rows - rows.min() == r
            joint = _coverage_1d((xs - ox + stagger[r]).astype(np.float32), 1.2, floor.seam_m,
                                 m_per_px)
            seams[sel] = np.maximum(seams[sel], joint[None, :])
        warp = _smooth_noise(rng, (h, w), 0.3 / m_per_px)
        gy = (ys[:, None] + 0.01 * warp).astype(np.float32)
        shade *= 1.0 + 1.5 * floor.grain * np.sin(gy * (2 * math.pi / 0.006)).astype(np.float32)
        shade *= 1.0 + floor.grain * _smooth_noise(rng, (h, w), 0.04 / m_per_px)
    elif floor.kind == "plain":
        shade *= 1.0 + floor.variation * _smooth_noise(rng, (h, w), 0.4 / m_per_px)
        shade *= 1.0 + floor.grain * _smooth_noise(rng, (h, w), 0.02 / m_per_px)
    else:  # noisy
        shade *= 1.0 + floor.variation * _smooth_noise(rng, (h, w), 0.2 / m_per_px)
        shade *= 1.0 + 3.0 * floor.grain * _smooth_noise(rng, (h, w), 0.006 / m_per_px)
    grain = _fine_noise(rng, (h, w))
    cv2.scaleAdd(grain, 0.5 * floor.grain, np.ones_like(shade), dst=grain)
    cv2.multiply(shade, grain, dst=shade)
    return shade, seams


def _tape_coverage(world: World, texture: GroundTexture, shape: tuple[int, int],
                   block_px: int = 256, supersample: int = 4) -> F32:
    """Fraction of each texture pixel covered by tape, exact to 1/supersample^2: the tape
    outlines are filled at `supersample` x resolution block by block (only blocks the tapes touch)
    and area-averaged back down."""
    coverage = np.zeros(shape, np.float32)
    outlines = [texture.world_to_px(o) for tape in world.tapes for o in tape.outlines()]
    if not outlines:
        return coverage
    h, w = shape
    touched: set[tuple[int, int]] = set()
    for outline in outlines:
        cells = np.floor(outline / block_px).astype(np.int64)
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                touched.update(zip((cells[:, 0] + dx).tolist(), (cells[:, 1] + dy).tolist(),
                                   strict=True))
    shift = 3
    big = np.zeros((block_px * supersample, block_px * supersample), np.uint8)
    scale = supersample * (1 << shift)
    for bx, by in sorted(touched):
        x0, y0 = bx * block_px, by * block_px
        if x0 >= w or y0 >= h or x0 + block_px <= 0 or y0 + block_px <= 0:
            continue
        big[:] = 0
        for outline in outlines:
            # Pixel centres sit at integers; the supersampled grid's cells start at -0.5.
            local = (outline - (x0, y0) + 0.5) * scale - (1 << shift) * 0.5
            poly = np.round(local).astype(np.int32).reshape(-1, 1, 2)
            cv2.fillPoly(big, [poly], 255, lineType=cv2.LINE_8, shift=shift)
        small = cv2.resize(big, (block_px, block_px), interpolation=cv2.INTER_AREA)
        ys, xs = slice(max(y0, 0), min(y0 + block_px, h)), slice(max(x0, 0), min(x0 + block_px, w))
        part = small[ys.start - y0:ys.stop - y0, xs.start - x0:xs.stop - x0]
        np.maximum(coverage[ys, xs], part.astype(np.float32) * (1.0 / 255.0), out=coverage[ys, xs])
    return coverage


def _illumination(world: World, xs: F32, ys: F32) -> tuple[F32 | None, F32 | None]:
    """(multiplicative light (H, W), additive glare (H, W) in [0, 1.5]); None where uniform."""
    light = world.lighting
    start = world.centreline.points[0]
    a = math.radians(light.gradient.direction_deg)
    gx = ((xs - start[0]) * math.cos(a)).astype(np.float32)
    gy = ((ys - start[1]) * math.sin(a)).astype(np.float32)
    field: F32 | None = None
    if light.brightness != 1.0 or light.gradient.per_m != 0.0:
        field = np.empty((len(ys), len(xs)), np.float32)
        np.add(gy[:, None], gx[None, :], out=field)
        field *= light.gradient.per_m
        field += 1.0
        field *= light.brightness
        np.maximum(field, 0.0, out=field)
    if not light.glare:
        return field, None
    glare = np.zeros((len(ys), len(xs)), np.float32)
    for spot in light.glare:
        point, heading = world.centreline.at(spot.at_m)
        cx = point[0] - spot.offset_m * math.sin(heading)
        cy = point[1] + spot.offset_m * math.cos(heading)
        dx2 = ((xs - cx) ** 2).astype(np.float32)
        dy2 = ((ys - cy) ** 2).astype(np.float32)
        cols = np.nonzero(dx2 < (4 * spot.radius_m) ** 2)[0]
        rows = np.nonzero(dy2 < (4 * spot.radius_m) ** 2)[0]
        if len(cols) == 0 or len(rows) == 0:
            continue
        r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
        blob = np.exp(-(dy2[r0:r1, None] + dx2[None, c0:c1]) / (2 * spot.radius_m**2))
        glare[r0:r1, c0:c1] += (spot.strength * blob).astype(np.float32)
    return field, glare


def paint_ground(world: World, m_per_px: float, seed: int, color: bool = True) -> GroundTexture:
    """Paint the world's floor, tapes and light into a texture of `m_per_px` metres per pixel."""
    rng = np.random.default_rng([seed, 0x5CE7])
    xs, ys, width, height = _grid_coords(world, m_per_px)
    shade, seams = _floor_layers(world, m_per_px, rng, xs, ys)
    texture = GroundTexture(
        gray=np.zeros((1, 1), np.uint8), bgr=None, m_per_px=m_per_px,
        x_min=world.bounds[0], y_max=world.bounds[3], fill_gray=0, fill_bgr=(0, 0, 0),
    )
    tape = _tape_coverage(world, texture, (height, width))
    light, glare = _illumination(world, xs, ys)
    floor_bgr = color_bgr(world.floor.color)
    seam_bgr = color_bgr(world.floor.seam_color)
    tape_bgr = world.tapes[0].color_bgr if world.tapes else floor_bgr
    # value = floor * P + seam * Q + tape * R + 255 * glare, per channel, with
    #   P = light * shade * (1 - seams) * (1 - tape), Q = light * shade * seams * (1 - tape),
    #   R = light * tape * (1 + 0.3 * (shade - 1))   (tape is smoother than the floor).
    not_tape = np.subtract(np.float32(1.0), tape)
    lit_shade = cv2.multiply(shade, light) if light is not None else shade
    lit_shade = cv2.multiply(lit_shade, not_tape)
    q = cv2.multiply(lit_shade, seams)
    p = cv2.subtract(lit_shade, q)
    r = cv2.multiply(cv2.addWeighted(shade, 0.3, shade, 0.0, 0.7), tape)
    if light is not None:
        r = cv2.multiply(r, light)
    del lit_shade, not_tape, seams, tape
    work = np.empty_like(p)

    def channel(floor_v: float, seam_v: float, tape_v: float) -> U8:
        cv2.addWeighted(p, floor_v, q, seam_v, 0.0, dst=work)
        cv2.scaleAdd(r, tape_v, work, dst=work)
        if glare is not None:
            cv2.scaleAdd(glare, 255.0, work, dst=work)
        return np.asarray(cv2.convertScaleAbs(work), dtype=np.uint8)

    def luma(c: tuple[int, int, int]) -> float:
        return float(sum(wt * v for wt, v in zip(GRAY_WEIGHTS, c, strict=True)))

    # The gray texture is painted the same way with or without colour, so what perception sees
    # does not depend on whether a video is recorded.
    gray = channel(luma(floor_bgr), luma(seam_bgr), luma(tape_bgr))
    bgr = None
    if color:
        bgr = np.dstack([channel(floor_bgr[c], seam_bgr[c], tape_bgr[c]) for c in range(3)])
    fill_gray = int(np.median(gray[:: max(1, height // 64), :: max(1, width // 64)]))
    if bgr is not None:
        sample = bgr[:: max(1, height // 64), :: max(1, width // 64)].reshape(-1, 3)
        fill_bgr = tuple(int(v) for v in np.median(sample, axis=0))
    else:
        fill_bgr = (fill_gray, fill_gray, fill_gray)
    return GroundTexture(
        gray=gray, bgr=bgr, m_per_px=m_per_px, x_min=world.bounds[0], y_max=world.bounds[3],
        fill_gray=fill_gray, fill_bgr=(fill_bgr[0], fill_bgr[1], fill_bgr[2]),
    )
