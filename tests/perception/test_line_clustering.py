"""Clustering Hough segments into lines (`perception.line_kernel.cluster_collinear`): collinear
pieces join one line, pieces of parallel lines a few pixels apart do not, for a few segments and
for hundreds (a frame of glossy terrazzo gives 200-odd)."""

from __future__ import annotations

import numpy as np
import pytest

from lanewarden.perception.line_kernel import cluster_collinear, segment_pieces


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
    pieces, kept = segment_pieces(collinear_groups(groups, per_group), 10.0, 170.0)
    assert len(kept) == groups * per_group  # (none is flat)
    line_of, lines = cluster_collinear(pieces, 5.0, 3.0)
    # equal lengths: leaders in list order, so line g is group g
    assert lines == groups
    assert line_of.tolist() == [i // per_group for i in range(groups * per_group)]


def test_parallel_lines_a_few_pixels_apart_stay_apart() -> None:
    near = collinear_groups(1, 40).reshape(-1, 4)
    beside = near + np.array([6, 0, 6, 0], dtype=np.int32)  # 6 px to the right: a neighbour
    both = np.concatenate([near, beside]).reshape(-1, 1, 4)
    line_of, lines = cluster_collinear(segment_pieces(both, 10.0, 170.0)[0], 5.0, 3.0)
    assert lines == 2
    assert line_of.tolist() == [0] * 40 + [1] * 40
