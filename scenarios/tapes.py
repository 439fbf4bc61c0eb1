"""Tape as it lies on a real floor: how much of each texture pixel it covers, worn, torn, creased.

`tape_damage(tape, rng)` draws a tape's damage along its pieces (`TapeSpec`: `wear` as a
fraction of its length in worn patches, `tears_per_m` chunks torn off an edge, `wrinkles_per_m`
creases across it) as polygons in world metres, each with the share of the tape it keeps
(0 torn off; 0.3..0.6 worn: the floor shows through; 0.5 a crease, lighter on dark tape,
darker on light tape). `TapeCoverage` turns tape outlines and their damage into the coverage of
any strip of texture rows, exact to 1/supersample^2: the outlines are filled at `supersample`
times the resolution in blocks (only blocks the tapes touch), the damage drawn over them, and the
result area-averaged back down.

Seeded by the caller's generator (the floor's seed: `--seed` changes the damage, not the lane);
never paints colour or light (`scenarios.texture`), never reads a clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.scenarios.world import Tape

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]

#: A worn patch keeps this share of the tape (drawn uniformly).
WORN_KEEPS = (0.3, 0.6)
#: A crease keeps this share (a thin line of another brightness).
CREASE_KEEPS = 0.5


@dataclass(frozen=True, eq=False)
class Damage:
    """A patch of a tape: `polygon` (N, 2) world metres keeps `keeps` of the tape's cover."""

    polygon: FloatArray
    keeps: float


def _frames(piece: FloatArray, s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Points (M, 2) and unit normals (left of travel) at arc lengths `s` along `piece`."""
    seg = np.diff(piece, axis=0)
    length = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
    x = np.interp(s, length, piece[:, 0])
    y = np.interp(s, length, piece[:, 1])
    index = np.clip(np.searchsorted(length, s) - 1, 0, len(seg) - 1)
    d = seg[index] / np.maximum(np.hypot(seg[index, 0], seg[index, 1]), 1e-12)[:, None]
    return np.column_stack([x, y]), np.column_stack([-d[:, 1], d[:, 0]])


def _patch(piece: FloatArray, s0: float, s1: float, lateral0: FloatArray,
           lateral1: FloatArray) -> FloatArray:
    """The polygon between arc lengths s0..s1 from `lateral0` to `lateral1` (per vertex, metres
    left of the tape's centre line)."""
    s = np.linspace(s0, s1, len(lateral0))
    points, normals = _frames(piece, s)
    return np.vstack([points + lateral0[:, None] * normals,
                      (points + lateral1[:, None] * normals)[::-1]])


def tape_damage(tape: Tape, rng: np.random.Generator) -> list[Damage]:
    """The worn patches, tears and creases of `tape` (see the module docstring)."""
    look = tape.look
    half = tape.width_m / 2.0
    out: list[Damage] = []
    for piece in tape.pieces:
        seg = np.diff(piece, axis=0)
        length = float(np.hypot(seg[:, 0], seg[:, 1]).sum())
        if length <= 0.01:
            continue
        if look.wear > 0:
            # patches 2..12 cm long until `wear` of the length is covered
            covered = 0.0
            while covered < look.wear * length:
                size = float(rng.uniform(0.02, 0.12))
                s0 = float(rng.uniform(0.0, max(length - size, 1e-3)))
                k = 7
                # ragged sides, from somewhere across the tape to somewhere else
                a = rng.uniform(-1.1, 0.2) * half + rng.normal(0, 0.1 * half, k)
                b = rng.uniform(0.2, 1.1) * half + rng.normal(0, 0.1 * half, k)
                out.append(Damage(_patch(piece, s0, s0 + size, a, b),
                                  float(rng.uniform(*WORN_KEEPS))))
                covered += size
        for _ in range(int(rng.poisson(look.tears_per_m * length))):
            size = float(rng.uniform(0.01, 0.04))
            s0 = float(rng.uniform(0.0, max(length - size, 1e-3)))
            side = 1.0 if rng.random() < 0.5 else -1.0
            k = 6
            # from beyond the edge to 20..60 % across, jagged
            depth = rng.uniform(0.2, 0.6) * tape.width_m
            inner = side * (half - depth * np.sin(np.linspace(0.0, math.pi, k)) ** 0.6)
            inner += rng.normal(0.0, 0.05 * tape.width_m, k)
            outer = np.full(k, side * (half + 0.01))
            out.append(Damage(_patch(piece, s0, s0 + size, inner, outer), 0.0))
        for _ in range(int(rng.poisson(look.wrinkles_per_m * length))):
            s_mid = float(rng.uniform(0.0, length))
            tilt = float(rng.uniform(-0.6, 0.6)) * half  # along-shift from one edge to the other
            width = float(rng.uniform(0.001, 0.002))
            lateral = np.array([-half - 0.002, half + 0.002])
            ends = np.clip(np.array([s_mid - tilt, s_mid + tilt]), 0.0, length)
            points, normals = _frames(piece, ends)
            edge = points + lateral[:, None] * normals
            d = edge[1] - edge[0]
            n = np.array([-d[1], d[0]]) / max(float(np.hypot(*d)), 1e-12) * width / 2.0
            out.append(Damage(np.array([edge[0] + n, edge[1] + n, edge[1] - n, edge[0] - n]),
                              CREASE_KEEPS))
    return out


class TapeCoverage:
    """Fraction of each texture pixel covered by tape (exact to 1/supersample^2), for any strip
    of rows: outlines (N, 2) and damage polygons in texture pixel coordinates."""

    def __init__(self, outlines: list[FloatArray], damage: list[tuple[FloatArray, float]],
                 shape: tuple[int, int], block_px: int = 128, supersample: int = 4) -> None:
        self._outlines = outlines
        self._damage = [(poly, keeps, poly.min(axis=0), poly.max(axis=0))
                        for poly, keeps in damage]
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
        big = block_px * supersample
        self._big = np.zeros((big, big), np.uint8)
        self._kept = np.zeros((big, big), np.uint8)
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

    def _local(self, polygon: FloatArray, x0: int, y0: int, shift: int) -> NDArray[np.int32]:
        scale = self._supersample * (1 << shift)
        # Pixel centres sit at integers; the supersampled grid's cells start at -0.5.
        local = (polygon - (x0, y0) + 0.5) * scale - (1 << shift) * 0.5
        return np.round(local).astype(np.int32).reshape(-1, 1, 2)

    def _fill(self, x0: int, y0: int) -> U8:
        shift = 3
        self._big[:] = 0
        for outline in self._outlines:
            cv2.fillPoly(self._big, [self._local(outline, x0, y0, shift)], 255,
                         lineType=cv2.LINE_8, shift=shift)
        block = self._block
        near = [(poly, keeps) for poly, keeps, lo, hi in self._damage
                if hi[0] >= x0 - 1 and lo[0] <= x0 + block + 1 and hi[1] >= y0 - 1
                and lo[1] <= y0 + block + 1]
        if near:
            self._kept[:] = 255
            for poly, keeps in near:
                cv2.fillPoly(self._kept, [self._local(poly, x0, y0, shift)],
                             int(round(255 * keeps)), lineType=cv2.LINE_8, shift=shift)
            cv2.multiply(self._big, self._kept, dst=self._big, scale=1.0 / 255.0)
        return np.asarray(cv2.resize(self._big, (block, block),
                                     interpolation=cv2.INTER_AREA), dtype=np.uint8)
