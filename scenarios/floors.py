"""The floor's own surface, kind by kind: what each texture pixel reflects, before tape and light.

`FloorPainter(floor, m_per_px, rng, xs, ys).rows(r0, r1)` paints any strip of texture rows
(`xs`, `ys`: the world coordinates of the texture's pixel centres, `scenarios.texture`) as a
`FloorStrip`: the floor's colour as a mix of a few colours with per-pixel weights (tile and
grout, chip and cement, one mat colour or another), a `shade` (the fine brightness variation,
which tape lying on the floor takes on a little) and how glossy each pixel is. Every size is in
metres (`scenarios.spec.FloorSpec`), every random draw happens in `__init__` (seeded by the
caller's generator), so a strip does not depend on which strips were painted before and a floor
is the same painted whole or in strips.

Kinds: tiles and ceramic (grid, grout, per-tile shade), terrazzo (two sizes of angular stone
chips in a cement matrix, tiles with thin grout), foam (interlocking mats with jigsaw seams, a
colour per mat), wood (planks, butt joints, grain), parquet (basket-weave blocks of slats, grain
along each slat), carpet (fibre texture, no seams), concrete (blotches, stains, cracks, saw-cut
joints), plain and noisy.

Never paints tape or light (`scenarios.texture` does), never renders a camera view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.scenarios.spec import FloorSpec, color_bgr

F32 = NDArray[np.float32]
BGR = tuple[int, int, int]

#: Terrazzo's and carpet's random cells repeat after this many cells (a repeat metres away
#: is invisible among thousands of chips, and the tables stay small).
CELL_PERIOD = 512


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


def coverage_1d(coord: F32, period: float, width: float, m_per_px: float) -> F32:
    """Fraction of each pixel (1-D, along one axis) covered by seams of `width` every `period`
    (seam centres at multiples of `period`)."""
    if width <= 0:
        return np.zeros_like(coord)
    # Distance from the pixel centre to the nearest seam centre line.
    phase = np.mod(coord, period)
    dist = np.minimum(phase, period - phase)
    cover = np.clip((width / 2.0 + m_per_px / 2.0 - dist) / m_per_px, 0.0, 1.0)
    return np.minimum(cover, width / m_per_px).astype(np.float32)


@dataclass
class FloorStrip:
    """One strip of the floor: colour `sum(weight * colour)` per channel over `parts`
    (weights (h, w) float32, colours BGR 0..255), `shade` (h, w) around 1 (the fine variation,
    for the tape on top), `gloss` (h, w) or None (matte)."""

    parts: list[tuple[F32, BGR]]
    shade: F32
    gloss: F32 | None


class FloorPainter:
    """Paints one floor kind strip by strip (see the module docstring)."""

    def __init__(self, floor: FloorSpec, m_per_px: float, rng: np.random.Generator,
                 xs: F32, ys: F32) -> None:
        self.floor = floor
        self._m = m_per_px
        self._xs, self._ys = xs, ys
        shape = (len(ys), len(xs))
        self._shape = shape
        self._noise: list[tuple[float, _SmoothNoise]] = []
        self._floor_bgr = color_bgr(floor.color)
        self._seam_bgr = color_bgr(floor.seam_color)
        self._palette = [color_bgr(c) for c in floor.colors] or [self._floor_bgr]
        kind = floor.kind
        if kind in ("tiles", "ceramic", "terrazzo"):
            self._init_tiles(rng, shape)
        if kind == "terrazzo":
            self._init_chips(rng)
        elif kind == "foam":
            self._init_foam(rng)
        elif kind == "wood":
            self._init_wood(rng, shape)
        elif kind == "parquet":
            self._init_parquet(rng, shape)
        elif kind == "carpet":
            self._noise.append((floor.variation, _SmoothNoise(rng, shape, 0.3 / m_per_px)))
            self._noise.append((0.5 * floor.grain, _SmoothNoise(rng, shape, 0.012 / m_per_px)))
        elif kind == "concrete":
            self._init_concrete(rng, shape)
        elif kind == "plain":
            self._noise.append((floor.variation, _SmoothNoise(rng, shape, 0.4 / m_per_px)))
            self._noise.append((floor.grain, _SmoothNoise(rng, shape, 0.02 / m_per_px)))
        elif kind == "noisy":
            self._noise.append((floor.variation, _SmoothNoise(rng, shape, 0.2 / m_per_px)))
            self._noise.append((3.0 * floor.grain, _SmoothNoise(rng, shape, 0.006 / m_per_px)))
        self._fine = _FineNoise(rng, shape)

    # ---- set-up, kind by kind ----------------------------------------------------------------
    def _init_tiles(self, rng: np.random.Generator, shape: tuple[int, int]) -> None:
        floor, xs, ys = self.floor, self._xs, self._ys
        ox, oy = floor.grid_offset_m
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
        self._noise.append((0.5 * floor.grain, _SmoothNoise(rng, shape, 0.05 / self._m)))

    def _init_chips(self, rng: np.random.Generator) -> None:
        """Two grids of cells (big chips `chip_m` across, small ones 2.2 times smaller), at most
        one angular chip per cell: its centre, half-axes, angle, colour and whether it is
        there, in tables that repeat every CELL_PERIOD cells."""
        floor = self.floor
        self._chips = []
        n = CELL_PERIOD
        for cell_m, share in ((1.25 * floor.chip_m, 0.7), (1.25 * floor.chip_m / 2.2, 0.3)):
            # a chip covers about 0.27 pi of its cell on average (half-axes 0.35..0.7 cells)
            present = min(1.0, floor.chip_fraction * share / 0.85)
            table = np.empty((7, n, n), np.float32)
            table[0] = rng.uniform(0.25, 0.75, (n, n))  # centre, in cells
            table[1] = rng.uniform(0.25, 0.75, (n, n))
            half_a = rng.uniform(0.35, 0.7, (n, n))
            table[2] = 1.0 / half_a**2
            table[3] = 1.0 / (half_a * rng.uniform(0.5, 1.0, (n, n))) ** 2
            angle = rng.uniform(0.0, math.pi, (n, n))
            table[4], table[5] = np.cos(angle), np.sin(angle)
            table[6] = np.where(rng.random((n, n)) < present,
                                rng.integers(0, len(self._palette), (n, n)), -1)
            self._chips.append((cell_m, table))

    def _init_foam(self, rng: np.random.Generator) -> None:
        floor, xs, ys = self.floor, self._xs, self._ys
        size = floor.tile_m
        self._mat_i0 = int(math.floor(float(xs.min()) / size)) - 1
        self._mat_j0 = int(math.floor(float(ys.min()) / size)) - 1
        ni = int(math.ceil(float(xs.max()) / size)) - self._mat_i0 + 2
        nj = int(math.ceil(float(ys.max()) / size)) - self._mat_j0 + 2
        self._mat_colour = rng.integers(0, len(self._palette), (nj, ni))
        self._mat_shade = (1.0 + floor.variation * rng.standard_normal((nj, ni))).astype(
            np.float32)
        # Teeth per edge: about one every 4 tooth depths, at least two.
        self._teeth = max(2, round(size / (4.0 * max(floor.tooth_m, 1e-3))))

    def _init_wood(self, rng: np.random.Generator, shape: tuple[int, int]) -> None:
        floor = self.floor
        oy = floor.grid_offset_m[1]
        self._plank = floor.tile_m / 2.5
        rows = np.floor((self._ys - oy) / self._plank).astype(np.int64)
        self._rmin = int(rows.min())
        nrows = int(rows.max() - rows.min() + 1)
        self._plank_shade = (1.0 + floor.variation * rng.standard_normal(nrows)).astype(
            np.float32)
        # Butt joints: each plank row is cut every 1.2 m, staggered.
        self._stagger = rng.uniform(0.0, 1.2, nrows).astype(np.float32)
        self._warp = _SmoothNoise(rng, shape, 0.3 / self._m)
        self._noise.append((floor.grain, _SmoothNoise(rng, shape, 0.04 / self._m)))

    def _init_parquet(self, rng: np.random.Generator, shape: tuple[int, int]) -> None:
        floor = self.floor
        size = floor.tile_m
        self._block_i0 = int(math.floor(float(self._xs.min()) / size))
        self._block_j0 = int(math.floor(float(self._ys.min()) / size))
        ni = int(math.ceil(float(self._xs.max()) / size)) - self._block_i0 + 1
        nj = int(math.ceil(float(self._ys.max()) / size)) - self._block_j0 + 1
        self._slat_shade = (1.0 + floor.variation * rng.standard_normal(
            (nj, ni, floor.slats))).astype(np.float32)
        self._slat_phase = rng.uniform(0.0, 2 * math.pi, (nj, ni, floor.slats)).astype(
            np.float32)
        self._warp = _SmoothNoise(rng, shape, 0.08 / self._m)
        self._noise.append((0.5 * floor.grain, _SmoothNoise(rng, shape, 0.03 / self._m)))

    def _init_concrete(self, rng: np.random.Generator, shape: tuple[int, int]) -> None:
        floor = self.floor
        m = self._m
        self._noise.append((floor.variation, _SmoothNoise(rng, shape, 0.6 / m)))
        self._noise.append((0.4 * floor.variation, _SmoothNoise(rng, shape, 0.06 / m)))
        x0, x1 = float(self._xs.min()), float(self._xs.max())
        y0, y1 = float(self._ys.min()), float(self._ys.max())
        area = (x1 - x0) * (y1 - y0)
        n_stains = int(rng.poisson(floor.stains_per_m2 * area))
        # (x, y, sigma along, sigma across, angle, depth): soft stains darker or lighter
        self._stains = [(float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)),
                         float(rng.uniform(0.08, 0.35)), float(rng.uniform(0.05, 0.2)),
                         float(rng.uniform(0.0, math.pi)), float(rng.uniform(0.3, 0.8)))
                        for _ in range(n_stains)]
        # Cracks: jagged random walks (with a branch now and then), drawn once into a layer.
        n_cracks = int(rng.poisson(floor.cracks_per_m2 * area))
        self._cracks: NDArray[np.uint8] | None = None
        if n_cracks:
            h, w = shape
            layer = np.zeros((h, w), np.uint8)
            shift = 4
            for _ in range(n_cracks):
                start = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
                heading = rng.uniform(0.0, 2 * math.pi)
                for branch in range(int(rng.integers(1, 3))):
                    walk = [start]
                    direction = heading + (0.0 if branch == 0 else rng.uniform(-1.2, 1.2))
                    for _ in range(int(rng.integers(8, 40))):
                        direction += rng.normal(0.0, 0.45)
                        step = rng.uniform(0.01, 0.04)
                        walk.append(walk[-1] + step * np.array([math.cos(direction),
                                                                math.sin(direction)]))
                    points = np.array(walk)
                    px = np.column_stack([(points[:, 0] - x0) / m, (y1 - points[:, 1]) / m])
                    width_px = max(1, round(rng.uniform(0.001, 0.003) / m))
                    cv2.polylines(layer, [np.round(px * (1 << shift)).astype(np.int32)],
                                  False, 255, width_px, cv2.LINE_AA, shift)
            self._cracks = layer

    # ---- strips ------------------------------------------------------------------------------
    def rows(self, r0: int, r1: int) -> FloorStrip:
        """The floor in texture rows [r0, r1)."""
        floor = self.floor
        kind = floor.kind
        h, w = r1 - r0, len(self._xs)
        shade = np.ones((h, w), np.float32)
        noise = iter(self._noise)
        if kind in ("tiles", "ceramic", "terrazzo"):
            seams = self._tile_rows(r0, r1, shade)
            amp, smooth = next(noise)
            shade *= 1.0 + amp * smooth.rows(r0, r1)
            self._fine_grain(r0, r1, shade)
            if kind == "terrazzo":
                parts = self._chip_parts(r0, r1, shade, seams)
            else:
                parts = _two_parts(shade, seams, self._floor_bgr, self._seam_bgr)
            return FloorStrip(parts, shade, self._gloss(seams))
        if kind == "foam":
            return self._foam_rows(r0, r1, shade)
        if kind == "wood":
            seams = self._wood_rows(r0, r1, shade, noise)
        elif kind == "parquet":
            seams = self._parquet_rows(r0, r1, shade, noise)
        else:  # plain, noisy, carpet, concrete: smooth noises
            for amp, smooth in noise:
                shade *= 1.0 + amp * smooth.rows(r0, r1)
            seams = np.zeros((h, w), np.float32)
        self._fine_grain(r0, r1, shade)
        if kind == "concrete":
            return self._concrete_rows(r0, r1, shade)
        return FloorStrip(_two_parts(shade, seams, self._floor_bgr, self._seam_bgr), shade,
                          self._gloss(seams))

    def _fine_grain(self, r0: int, r1: int, shade: F32) -> None:
        grain = self._fine.rows(r0, r1)
        cv2.scaleAdd(grain, 0.5 * self.floor.grain, np.ones_like(shade), dst=grain)
        cv2.multiply(shade, grain, dst=shade)

    def _gloss(self, seams: F32) -> F32 | None:
        """The floor's gloss, none in its seams (grout, joints, cracks are matte)."""
        if self.floor.gloss <= 0:
            return None
        return np.float32(self.floor.gloss) * (np.float32(1.0) - seams)

    def _tile_rows(self, r0: int, r1: int, shade: F32) -> F32:
        floor, m = self.floor, self._m
        xs, ys = self._xs, self._ys[r0:r1]
        ox, oy = floor.grid_offset_m
        seams = np.zeros((r1 - r0, len(xs)), np.float32)
        if abs(self._sa) < 1e-9:
            u1 = (xs - ox).astype(np.float32)
            v1 = (ys - oy).astype(np.float32)
            cu = coverage_1d(u1, floor.tile_m, floor.seam_m, m)
            cv = coverage_1d(v1, floor.tile_m, floor.seam_m, m)
            np.maximum(cv[:, None], cu[None, :], out=seams)
            iu = np.floor(u1 / floor.tile_m).astype(np.int64) - self._umin
            iv = np.floor(v1 / floor.tile_m).astype(np.int64) - self._vmin
            shade[:] = np.take(self._table[iv], iu, axis=1)
        else:
            gx, gy = np.meshgrid(xs - ox, ys - oy)
            u = (self._ca * gx + self._sa * gy).astype(np.float32)
            v = (-self._sa * gx + self._ca * gy).astype(np.float32)
            np.maximum(coverage_1d(u, floor.tile_m, floor.seam_m, m),
                       coverage_1d(v, floor.tile_m, floor.seam_m, m), out=seams)
            iu = np.floor(u / floor.tile_m).astype(np.int64) - self._umin
            iv = np.floor(v / floor.tile_m).astype(np.int64) - self._vmin
            shade[:] = self._table[np.clip(iv, 0, self._table.shape[0] - 1),
                                   np.clip(iu, 0, self._table.shape[1] - 1)]
        return seams

    def _chip_parts(self, r0: int, r1: int, shade: F32,
                    seams: F32) -> list[tuple[F32, BGR]]:
        """Terrazzo: chips of each palette colour over the cement matrix, grout on top."""
        m = self._m
        gx = self._xs[None, :]
        gy = self._ys[r0:r1, None]
        chip_colour = np.full(shade.shape, -1, np.int64)
        chip_cover = np.zeros(shade.shape, np.float32)
        # small chips first, big ones over them
        for cell_m, table in reversed(self._chips):
            cx, cy = gx / cell_m, gy / cell_m
            ix, iy = np.floor(cx), np.floor(cy)
            i = ix.astype(np.int64) % CELL_PERIOD
            j = iy.astype(np.int64) % CELL_PERIOD
            dx = (cx - ix) - table[0][j, i]
            dy = (cy - iy) - table[1][j, i]
            cos, sin = table[4][j, i], table[5][j, i]
            u = dx * cos + dy * sin
            v = dy * cos - dx * sin
            q = np.sqrt(u * u * table[2][j, i] + v * v * table[3][j, i])
            # soft edge one texture pixel wide: (1 - q) times the chip's radius in pixels
            radius_px = cell_m / m / np.sqrt(table[2][j, i])
            cover = np.clip((1.0 - q) * radius_px + 0.5, 0.0, 1.0).astype(np.float32)
            colour = table[6][j, i].astype(np.int64)
            cover[colour < 0] = 0.0
            take = cover > 0.0
            chip_colour[take] = colour[take]
            chip_cover[take] = cover[take]
        matrix = (1.0 - chip_cover) * (1.0 - seams) * shade
        parts: list[tuple[F32, BGR]] = [(matrix.astype(np.float32), self._floor_bgr)]
        solid = (1.0 - seams) * shade
        for index, colour in enumerate(self._palette):
            weight = np.where(chip_colour == index, chip_cover, 0.0) * solid
            parts.append((weight.astype(np.float32), colour))
        parts.append(((seams * shade).astype(np.float32), self._seam_bgr))
        return parts

    def _foam_rows(self, r0: int, r1: int, shade: F32) -> FloorStrip:
        """Interlocking mats: each mat's column and row come from its edges' jigsaw curves, so a
        knob carries its mat's colour; the seam is where the mat changes."""
        floor, m = self.floor, self._m
        size, depth = floor.tile_m, floor.tooth_m
        # one row more than asked: a seam is where a pixel's mat differs from the next one's
        gy = self._ys[r0:r1 + 1, None] if r1 < len(self._ys) else np.concatenate(
            [self._ys[r0:r1], self._ys[r1 - 1:r1] - m])[:, None]
        gx = np.concatenate([self._xs, self._xs[-1:] + m])[None, :]

        def wave(t: F32, edge: NDArray[np.int64]) -> F32:
            # knobs out and in along an edge, flat tops, steep sides; the pattern alternates
            # from edge to edge
            phase = (edge % 2) * math.pi
            return np.clip(3.0 * np.sin(2 * math.pi * self._teeth * t / size + phase), -1, 1)

        ei = np.floor(gx / size + 0.5).astype(np.int64)  # nearest vertical edge
        column = np.where(gx >= ei * size + depth * wave(gy, ei), ei, ei - 1)
        ej = np.floor(gy / size + 0.5).astype(np.int64)  # nearest horizontal edge
        row = np.where(gy >= ej * size + depth * wave(gx, ej + 1), ej, ej - 1)
        column = np.broadcast_to(column, (gy.shape[0], gx.shape[1]))
        row = np.broadcast_to(row, (gy.shape[0], gx.shape[1]))
        mat = (row - self._mat_j0) * 100_003 + (column - self._mat_i0)
        seams = ((mat[:-1, :-1] != mat[:-1, 1:]) | (mat[:-1, :-1] != mat[1:, :-1])).astype(
            np.float32)
        if floor.seam_m <= 0:
            seams[:] = 0.0
        else:
            seams *= min(1.0, floor.seam_m / m)
        rows_i = np.clip(row[:-1, :-1] - self._mat_j0, 0, self._mat_colour.shape[0] - 1)
        cols_i = np.clip(column[:-1, :-1] - self._mat_i0, 0, self._mat_colour.shape[1] - 1)
        shade *= self._mat_shade[rows_i, cols_i]
        self._fine_grain(r0, r1, shade)
        colour = self._mat_colour[rows_i, cols_i]
        solid = (1.0 - seams) * shade
        parts: list[tuple[F32, BGR]] = [
            (np.where(colour == i, solid, 0.0).astype(np.float32), c)
            for i, c in enumerate(self._palette)]
        parts.append(((seams * shade).astype(np.float32), self._seam_bgr))
        return FloorStrip(parts, shade, self._gloss(seams))

    def _wood_rows(self, r0: int, r1: int, shade: F32, noise: object) -> F32:
        floor, m = self.floor, self._m
        xs, ys = self._xs, self._ys[r0:r1]
        ox, oy = floor.grid_offset_m
        v = (ys - oy).astype(np.float32)
        seams = np.empty((r1 - r0, len(xs)), np.float32)
        seams[:] = coverage_1d(v, self._plank, floor.seam_m, m)[:, None]
        rows = np.floor(v / self._plank).astype(np.int64) - self._rmin
        shade *= self._plank_shade[rows][:, None]
        for r in np.unique(rows):
            sel = rows == r
            joint = coverage_1d((xs - ox + self._stagger[r]).astype(np.float32), 1.2,
                                floor.seam_m, m)
            seams[sel] = np.maximum(seams[sel], joint[None, :])
        gy = (ys[:, None] + 0.01 * self._warp.rows(r0, r1)).astype(np.float32)
        shade *= 1.0 + 1.5 * floor.grain * np.sin(gy * (2 * math.pi / 0.006)).astype(
            np.float32)
        amp, smooth = next(noise)  # type: ignore[call-overload]
        shade *= 1.0 + amp * smooth.rows(r0, r1)
        return seams

    def _parquet_rows(self, r0: int, r1: int, shade: F32, noise: object) -> F32:
        """Basket weave: square blocks of `slats` slats, slats along x where the block's
        column + row is even, along y where it is odd; grain along each slat."""
        floor, m = self.floor, self._m
        size, slats = floor.tile_m, floor.slats
        gx = np.broadcast_to(self._xs[None, :], shade.shape)
        gy = np.broadcast_to(self._ys[r0:r1, None], shade.shape)
        bi = np.floor(gx / size).astype(np.int64)
        bj = np.floor(gy / size).astype(np.int64)
        along_x = (bi + bj) % 2 == 0
        # across the slats: y within the block where they run along x, else x
        across = np.where(along_x, gy - bj * size, gx - bi * size).astype(np.float32)
        slat_w = size / slats
        seams = np.maximum(
            np.maximum(coverage_1d(gx.astype(np.float32), size, floor.seam_m, m),
                       coverage_1d(gy.astype(np.float32), size, floor.seam_m, m)),
            coverage_1d(across, slat_w, floor.seam_m, m))
        k = np.clip(np.floor(across / slat_w).astype(np.int64), 0, slats - 1)
        jj = np.clip(bj - self._block_j0, 0, self._slat_shade.shape[0] - 1)
        ii = np.clip(bi - self._block_i0, 0, self._slat_shade.shape[1] - 1)
        shade *= self._slat_shade[jj, ii, k]
        grain = across + 0.004 * self._warp.rows(r0, r1)
        shade *= 1.0 + 1.2 * floor.grain * np.sin(
            grain * (2 * math.pi / 0.005) + self._slat_phase[jj, ii, k]).astype(np.float32)
        amp, smooth = next(noise)  # type: ignore[call-overload]
        shade *= 1.0 + amp * smooth.rows(r0, r1)
        return seams

    def _concrete_rows(self, r0: int, r1: int, shade: F32) -> FloorStrip:
        floor, m = self.floor, self._m
        xs, ys = self._xs, self._ys[r0:r1]
        stain = np.zeros(shade.shape, np.float32)
        for x, y, sa, sb, angle, depth in self._stains:
            reach = 3.0 * sa
            if ys[-1] > y + reach or ys[0] < y - reach:
                continue
            cols = np.nonzero(np.abs(xs - x) < reach)[0]
            if len(cols) == 0:
                continue
            c0, c1 = cols[0], cols[-1] + 1
            dx = (xs[c0:c1] - x)[None, :]
            dy = (ys - y)[:, None]
            u = dx * math.cos(angle) + dy * math.sin(angle)
            v = dy * math.cos(angle) - dx * math.sin(angle)
            blob = depth * np.exp(-0.5 * ((u / sa) ** 2 + (v / sb) ** 2))
            np.maximum(stain[:, c0:c1], blob.astype(np.float32), out=stain[:, c0:c1])
        seams = np.zeros(shade.shape, np.float32)
        if floor.seam_m > 0:
            ox, oy = floor.grid_offset_m
            cu = coverage_1d((xs - ox).astype(np.float32), floor.tile_m, floor.seam_m, m)
            cv = coverage_1d((ys - oy).astype(np.float32), floor.tile_m, floor.seam_m, m)
            np.maximum(cv[:, None], cu[None, :], out=seams)
        if self._cracks is not None:
            np.maximum(seams, self._cracks[r0:r1].astype(np.float32) * (1.0 / 255.0), out=seams)
        solid = (1.0 - seams) * shade
        parts: list[tuple[F32, BGR]] = [
            ((solid * (1.0 - stain)).astype(np.float32), self._floor_bgr),
            ((solid * stain).astype(np.float32), self._palette[0]),
            ((seams * shade).astype(np.float32), self._seam_bgr)]
        return FloorStrip(parts, shade, self._gloss(seams))


def _two_parts(shade: F32, seams: F32, floor_bgr: BGR, seam_bgr: BGR) -> list[tuple[F32, BGR]]:
    seam_weight = np.asarray(cv2.multiply(shade, seams), dtype=np.float32)
    return [(np.asarray(cv2.subtract(shade, seam_weight), dtype=np.float32), floor_bgr),
            (seam_weight, seam_bgr)]
