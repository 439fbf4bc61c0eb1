"""Clustering Hough segments into lines (`perception.lines._cluster_collinear`): collinear pieces
join one line, pieces of parallel lines a few pixels apart do not. Up to 64 segments the
compatibility bit sets are read as one 64-bit word per segment, beyond that byte by byte: both
ways must give the same lines (a frame of glossy terrazzo gives 200-odd segments)."""

from __future__ import annotations

import numpy as np
import pytest

from lanewarden.perception.lines import _cluster_collinear, _oriented_segments, _Pieces


def collinear_groups(groups: int, per_group: int) -> np.ndarray:
    """`groups` upright lines 40 px apart, each cut into `per_group` pieces 8 px long with 2 px
    gaps, listed line by line (HoughLinesP's (N, 1, 4) int32)."""
    segments = []
    for g in range(groups):
        x = 20 + 40 * g
        for k in range(per_group):
            y_near = 1000 - 10 * k
            segments.append((x, y_near, x, y_near - 8))
    return np.array(segments, dtype=np.int32).reshape(-1, 1, 4)


@pytest.mark.parametrize(("groups", "per_group"),
                         [(6, 10), (1, 64), (1, 65), (7, 10), (13, 5), (30, 8)])
def test_collinear_pieces_make_one_line_each(groups: int, per_group: int) -> None:
    seg, angle = _oriented_segments(collinear_groups(groups, per_group))
    line_of, lines = _cluster_collinear(_Pieces.of(seg, angle), angle_tol_deg=5.0,
                                        offset_tol_px=3.0)
    # equal lengths: leaders in list order, so line g is group g
    assert lines == groups
    assert line_of.tolist() == [i // per_group for i in range(groups * per_group)]


def test_parallel_lines_a_few_pixels_apart_stay_apart() -> None:
    near = collinear_groups(1, 40).reshape(-1, 4)
    beside = near + np.array([6, 0, 6, 0], dtype=np.int32)  # 6 px to the right: a neighbour
    both = np.concatenate([near, beside]).reshape(-1, 1, 4)
    seg, angle = _oriented_segments(both)
    line_of, lines = _cluster_collinear(_Pieces.of(seg, angle), angle_tol_deg=5.0,
                                        offset_tol_px=3.0)
    assert lines == 2
    assert line_of.tolist() == [0] * 40 + [1] * 40
