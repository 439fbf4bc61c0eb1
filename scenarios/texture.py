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
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.spec import color_bgr
from lanewarden.scenarios.world import World

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]

#: Largest floor texture painted, pixels: the result is 1 byte per pixel (4 with colour) and the
#: painting's float layers exist for one strip of rows at a time, so this bounds it at ~50 MB
#: gray (the lecture's course is 27 Mpx at the default 2.5 mm per pixel).
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

    @cached_property
    def gray_transposed(self) -> U8:
        """`gray` stored transposed (columns as rows), made once per texture: the renderer reads
        it when the robot faces along x (see `CameraRenderer`)."""
        return np.ascontiguousarray(self.gray.T)

    @cached_property
    def bgr_transposed(self) -> U8 | None:
        """`bgr` stored transposed, made once per texture (None without colour)."""
        return None if self.bgr is None else np.ascontiguousarray(self.bgr.transpose(1, 0, 2))

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


class _SmoothNoise:
    """Zero-mean, unit-ish noise varying over `cell_px` pixels: a random grid (drawn once),
    bicubic-upsampled to the floor's size once (float32: the one full-size float layer kept,
    so the floor is the same as when it was painted whole) and read one strip at a time."""

    def __init__(self, rng: np.random.Generator, shape: tuple[int, int], cell_px: float) -> None:
        h, w = shape
        gh, gw = max(2, int(h / cell_px) + 2), max(2, int(w / cell_px) + 2)
        grid = rng.standard_normal((gh, gw)).astype(np.float32)
        self._full = np.asarray(cv2.resize(grid, (w, h), interpolation=cv2.INTER_CUBIC),
                                dtype=np.float32)

    def rows(self, r0: int, r1: int) -> F32:
        return self._full[r0:r1]


class _FineNoise:
    """Unit white noise; a random `period_px` square repeated (cheap, and invisible under the
    floor's other variation)."""

    def __init__(self, rng: np.random.Generator, shape: tuple[int, int],
                 period_px: int = 1024) -> None:
        h, w = shape
        self._tile = rng.standard_normal((min(h, period_px), min(w, period_px)),
                                         dtype=np.float32)
        self._w = w

    def rows(self, r0: int, r1: int) -> F32:
        th, tw = self._tile.shape
        rows = self._tile[np.arange(r0, r1) % th]
        return np.tile(rows, (1, -(-self._w // tw)))[:, :self._w]


def _coverage_1d(coord: F32, period: float, width: float, m_per_px: float) -> F32:
    """Fraction of each pixel (1-D, along one axis) covered by seams of `width` every `period`."""
    if width <= 0:
        return np.zeros_like(coord)
    # Distance from the pixel centre to the nearest seam centre line.
    phase = np.mod(coord, period)
    dist = np.minimum(phase, period - phase)
    cover = np.clip((width / 2.0 + m_per_px / 2.0 - dist) / m_per_px, 0.0, 1.0)
    return np.minimum(cover, width / m_per_px).astype(np.float32)


class _FloorLayers:
    """The floor's albedo as (shade, seam coverage) for any strip of rows: shade ~1.0 multiplies
    the floor colour, coverage in [0, 1] blends towards the seam colour. Every random draw happens
    in __init__, so a strip's values do not depend on which strips were painted before."""

    def __init__(self, world: World, m_per_px: float, rng: np.random.Generator,
                 xs: F32, ys: F32) -> None:
        floor = world.floor
        self._floor = floor
        self._m = m_per_px
        self._xs, self._ys = xs, ys
        shape = (len(ys), len(xs))
        ox, oy = floor.grid_offset_m
        self._noise: list[tuple[float, _SmoothNoise]] = []
        if floor.kind == "tiles":
            a = math.radians(floor.grid_angle_deg)
            self._ca, self._sa = math.cos(a), math.sin(a)
            if abs(self._sa) < 1e-9:
                iu_all = np.floor((xs - ox) / floor.tile_m).astype(np.int64)
                iv_all = np.floor((ys - oy) / floor.tile_m).astype(np.int64)
                umin, umax = int(iu_all.min()), int(iu_all.max())
                vmin, vmax = int(iv_all.min()), int(iv_all.max())
            else:
                corners_x = np.array([xs[0], xs[-1], xs[0], xs[-1]]) - ox
                corners_y = np.array([ys[0], ys[0], ys[-1], ys[-1]]) - oy
                u = self._ca * corners_x + self._sa * corners_y
                v = -self._sa * corners_x + self._ca * corners_y
                umin, umax = int(np.floor(u.min() / floor.tile_m)), int(
                    np.floor(u.max() / floor.tile_m))
                vmin, vmax = int(np.floor(v.min() / floor.tile_m)), int(
                    np.floor(v.max() / floor.tile_m))
            self._umin, self._vmin = umin, vmin
            self._table = (1.0 + floor.variation * rng.standard_normal(
                (vmax - vmin + 1, umax - umin + 1))).astype(np.float32)
            self._noise.append((0.5 * floor.grain, _SmoothNoise(rng, shape, 0.05 / m_per_px)))
        elif floor.kind == "wood":
            self._plank = floor.tile_m / 2.5
            rows = np.floor((ys - oy) / self._plank).astype(np.int64)
            self._rmin = int(rows.min())
            nrows = int(rows.max() - rows.min() + 1)
            self._plank_shade = (1.0 + floor.variation * rng.standard_normal(nrows)).astype(
                np.float32)
            # Butt joints: each plank row is cut every 1.2 m, staggered.
            self._stagger = rng.uniform(0.0, 1.2, nrows).astype(np.float32)
            self._warp = _SmoothNoise(rng, shape, 0.3 / m_per_px)
            self._noise.append((floor.grain, _SmoothNoise(rng, shape, 0.04 / m_per_px)))
        elif floor.kind == "plain":
            self._noise.append((floor.variation, _SmoothNoise(rng, shape, 0.4 / m_per_px)))
            self._noise.append((floor.grain, _SmoothNoise(rng, shape, 0.02 / m_per_px)))
        else:  # noisy
            self._noise.append((floor.variation, _SmoothNoise(rng, shape, 0.2 / m_per_px)))
            self._noise.append((3.0 * floor.grain, _SmoothNoise(rng, shape, 0.006 / m_per_px)))
        self._fine = _FineNoise(rng, shape)

    def rows(self, r0: int, r1: int) -> tuple[F32, F32]:
        floor, m = self._floor, self._m
        xs, ys = self._xs, self._ys[r0:r1]
        h, w = r1 - r0, len(xs)
        shade = np.ones((h, w), np.float32)
        seams = np.zeros((h, w), np.float32)
        ox, oy = floor.grid_offset_m
        noise = iter(self._noise)
        if floor.kind == "tiles":
            if abs(self._sa) < 1e-9:
                u1 = (xs - ox).astype(np.float32)
                v1 = (ys - oy).astype(np.float32)
                cu = _coverage_1d(u1, floor.tile_m, floor.seam_m, m)
                cv = _coverage_1d(v1, floor.tile_m, floor.seam_m, m)
                np.maximum(cv[:, None], cu[None, :], out=seams)
                iu = np.floor(u1 / floor.tile_m).astype(np.int64) - self._umin
                iv = np.floor(v1 / floor.tile_m).astype(np.int64) - self._vmin
                shade[:] = np.take(self._table[iv], iu, axis=1)
            else:
                gx, gy = np.meshgrid(xs - ox, ys - oy)
                u = (self._ca * gx + self._sa * gy).astype(np.float32)
                v = (-self._sa * gx + self._ca * gy).astype(np.float32)
                np.maximum(_coverage_1d(u, floor.tile_m, floor.seam_m, m),
                           _coverage_1d(v, floor.tile_m, floor.seam_m, m), out=seams)
                iu = np.floor(u / floor.tile_m).astype(np.int64) - self._umin
                iv = np.floor(v / floor.tile_m).astype(np.int64) - self._vmin
                shade[:] = self._table[np.clip(iv, 0, self._table.shape[0] - 1),
                                       np.clip(iu, 0, self._table.shape[1] - 1)]
            amp, smooth = next(noise)
            shade *= 1.0 + amp * smooth.rows(r0, r1)
        elif floor.kind == "wood":
            v = (ys - oy).astype(np.float32)
            seams[:] = _coverage_1d(v, self._plank, floor.seam_m, m)[:, None]
            rows = np.floor(v / self._plank).astype(np.int64) - self._rmin
            shade *= self._plank_shade[rows][:, None]
            for r in np.unique(rows):
                sel = rows == r
                joint = _coverage_1d((xs - ox + self._stagger[r]).astype(np.float32), 1.2,
                                     floor.seam_m, m)
                seams[sel] = np.maximum(seams[sel], joint[None, :])
            gy = (ys[:, None] + 0.01 * self._warp.rows(r0, r1)).astype(np.float32)
            shade *= 1.0 + 1.5 * floor.grain * np.sin(gy * (2 * math.pi / 0.006)).astype(
                np.float32)
            amp, smooth = next(noise)
            shade *= 1.0 + amp * smooth.rows(r0, r1)
        else:  # plain, noisy: two smooth noises
            for amp, smooth in noise:
                shade *= 1.0 + amp * smooth.rows(r0, r1)
        grain = self._fine.rows(r0, r1)
        cv2.scaleAdd(grain, 0.5 * floor.grain, np.ones_like(shade), dst=grain)
        cv2.multiply(shade, grain, dst=shade)
        return shade, seams


class _TapeCoverage:
    """Fraction of each texture pixel covered by tape, exact to 1/supersample^2, for any strip of
    rows: the tape outlines are filled at `supersample` x resolution in blocks of `block_px`
    (only blocks the tapes touch) and area-averaged back down."""

    def __init__(self, outlines: list[FloatArray], shape: tuple[int, int],
                 block_px: int = 128, supersample: int = 4) -> None:
        self._outlines = outlines
        self._shape = shape
        self._block = block_px
        self._supersample = supersample
        touched: set[tuple[int, int]] = set()
        for outline in outlines:
            cells = np.floor(outline / block_px).astype(np.int64)
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    touched.update(zip((cells[:, 0] + dx).tolist(),
                                       (cells[:, 1] + dy).tolist(), strict=True))
        self._touched = sorted(touched)
        self._big = np.zeros((block_px * supersample, block_px * supersample), np.uint8)
        self._done: dict[tuple[int, int], U8] = {}

    def rows(self, r0: int, r1: int) -> F32:
        """Coverage of rows [r0, r1) (strips may cut blocks: a block is filled once and kept
        until the strips have passed it)."""
        h, w = self._shape
        block = self._block
        coverage = np.zeros((r1 - r0, w), np.float32)
        for key in [k for k in self._done if (k[1] + 1) * block <= r0]:
            del self._done[key]
        for bx, by in self._touched:
            x0, y0 = bx * block, by * block
            if y0 >= r1 or y0 + block <= r0 or y0 >= h or x0 >= w or x0 + block <= 0:
                continue
            small = self._done.get((bx, by))
            if small is None:
                small = self._fill(x0, y0)
                self._done[(bx, by)] = small
            ys = slice(max(y0, r0), min(y0 + block, h, r1))
            xs = slice(max(x0, 0), min(x0 + block, w))
            part = small[ys.start - y0:ys.stop - y0, xs.start - x0:xs.stop - x0]
            target = coverage[ys.start - r0:ys.stop - r0, xs]
            np.maximum(target, part.astype(np.float32) * (1.0 / 255.0), out=target)
        return coverage

    def _fill(self, x0: int, y0: int) -> U8:
        shift = 3
        scale = self._supersample * (1 << shift)
        self._big[:] = 0
        for outline in self._outlines:
            # Pixel centres sit at integers; the supersampled grid's cells start at -0.5.
            local = (outline - (x0, y0) + 0.5) * scale - (1 << shift) * 0.5
            poly = np.round(local).astype(np.int32).reshape(-1, 1, 2)
            cv2.fillPoly(self._big, [poly], 255, lineType=cv2.LINE_8, shift=shift)
        return np.asarray(cv2.resize(self._big, (self._block, self._block),
                                     interpolation=cv2.INTER_AREA), dtype=np.uint8)


class _Illumination:
    """Multiplicative light (brightness, gradient) and additive glare for any strip of rows;
    None where uniform."""

    def __init__(self, world: World, xs: F32, ys: F32) -> None:
        light = world.lighting
        start = world.centreline.points[0]
        a = math.radians(light.gradient.direction_deg)
        self._gx = ((xs - start[0]) * math.cos(a)).astype(np.float32)
        self._gy = ((ys - start[1]) * math.sin(a)).astype(np.float32)
        self._light = light
        self.uniform = light.brightness == 1.0 and light.gradient.per_m == 0.0
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
            field *= light.brightness
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


def paint_ground(world: World, m_per_px: float, seed: int, color: bool = True) -> GroundTexture:
    """Paint the world's floor, tapes and light into a texture of `m_per_px` metres per pixel.

    Painted in strips of STRIP_ROWS rows: the float layers exist for one strip at a time, so the
    peak memory is the uint8 result plus a few strips."""
    rng = np.random.default_rng([seed, 0x5CE7])
    xs, ys, width, height = _grid_coords(world, m_per_px)
    layers = _FloorLayers(world, m_per_px, rng, xs, ys)
    frame = GroundTexture(
        gray=np.zeros((1, 1), np.uint8), bgr=None, m_per_px=m_per_px,
        x_min=world.bounds[0], y_max=world.bounds[3], fill_gray=0, fill_bgr=(0, 0, 0),
    )
    tapes = _TapeCoverage([frame.world_to_px(o) for tape in world.tapes
                           for o in tape.outlines()], (height, width))
    lighting = _Illumination(world, xs, ys)
    floor_bgr = color_bgr(world.floor.color)
    seam_bgr = color_bgr(world.floor.seam_color)
    tape_bgr = world.tapes[0].color_bgr if world.tapes else floor_bgr

    def luma(c: tuple[int, int, int]) -> float:
        return float(sum(wt * v for wt, v in zip(GRAY_WEIGHTS, c, strict=True)))

    # The gray texture is painted the same way with or without colour, so what perception sees
    # does not depend on whether a video is recorded.
    channels = [(luma(floor_bgr), luma(seam_bgr), luma(tape_bgr))]
    if color:
        channels += [(floor_bgr[c], seam_bgr[c], tape_bgr[c]) for c in range(3)]
    gray = np.empty((height, width), np.uint8)
    bgr = np.empty((height, width, 3), np.uint8) if color else None
    for r0 in range(0, height, STRIP_ROWS):
        r1 = min(height, r0 + STRIP_ROWS)
        shade, seams = layers.rows(r0, r1)
        tape = tapes.rows(r0, r1)
        light, glare = lighting.rows(r0, r1)
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
        work = np.empty_like(p)
        for index, (floor_v, seam_v, tape_v) in enumerate(channels):
            cv2.addWeighted(p, floor_v, q, seam_v, 0.0, dst=work)
            cv2.scaleAdd(r, tape_v, work, dst=work)
            if glare is not None:
                cv2.scaleAdd(glare, 255.0, work, dst=work)
            out = gray[r0:r1] if index == 0 else bgr[r0:r1, :, index - 1]  # type: ignore[index]
            out[:] = cv2.convertScaleAbs(work)
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
                         fill_bgr=texture.fill_bgr)


#: Painted floors kept per process (a campaign worker runs the same world and seed many times).
TEXTURE_CACHE_SIZE = 2
_cache: dict[tuple[object, ...], GroundTexture] = {}


def paint_ground_cached(world: World, key: object, m_per_px: float, seed: int,
                        color: bool = False) -> GroundTexture:
    """`paint_ground`, remembered for the last TEXTURE_CACHE_SIZE (world, resolution, seed)
    combinations. `key` must identify everything of the world that is painted (the caller's
    scenario floor, tape, lane, lighting and margin). The texture is shared: never modify it
    (`with_marks` copies)."""
    full = (key, m_per_px, seed, color)
    texture = _cache.pop(full, None)
    if texture is None:
        texture = paint_ground(world, m_per_px, seed, color=color)
        while len(_cache) >= TEXTURE_CACHE_SIZE:
            _cache.pop(next(iter(_cache)))
    _cache[full] = texture
    return texture
