"""A before/after picture of undistortion, so a user can see what the calibration does.

`side_by_side(before, after)` puts the original and the undistorted image next to each other and
draws the same straight reference lines over both: lines that are straight in the world bend away
from them on the left (lens distortion) and follow them on the right.

Debug drawing only: never used in the per-frame path, never reads files or prints.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

_LINE_COLOUR = (0, 200, 255)  # BGR amber: visible on both dark and light scenes
_LABEL_COLOUR = (255, 255, 255)
_GAP_PX = 8


def _as_bgr(image: np.ndarray) -> NDArray[np.uint8]:
    if image.ndim == 2:
        return np.asarray(cv2.cvtColor(image, cv2.COLOR_GRAY2BGR), dtype=np.uint8)
    if image.shape[2] == 4:
        return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGRA2BGR), dtype=np.uint8)
    return np.asarray(image, dtype=np.uint8).copy()


def draw_reference_lines(image: np.ndarray, divisions: int = 6) -> NDArray[np.uint8]:
    """A BGR copy of `image` with straight horizontal and vertical lines `divisions` apart."""
    out = _as_bgr(image)
    height, width = out.shape[:2]
    for i in range(1, divisions):
        x = round(i * width / divisions)
        y = round(i * height / divisions)
        cv2.line(out, (x, 0), (x, height - 1), _LINE_COLOUR, 1, cv2.LINE_AA)
        cv2.line(out, (0, y), (width - 1, y), _LINE_COLOUR, 1, cv2.LINE_AA)
    return out


def _label(image: NDArray[np.uint8], text: str) -> None:
    scale = max(0.4, image.shape[1] / 1000.0)
    thickness = 1 if scale < 0.8 else 2
    (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thickness)
    cv2.rectangle(image, (4, 4), (12 + w, 12 + h + base), (0, 0, 0), -1)
    cv2.putText(image, text, (8, 8 + h), cv2.FONT_HERSHEY_SIMPLEX, scale, _LABEL_COLOUR,
                thickness, cv2.LINE_AA)


def side_by_side(before: np.ndarray, after: np.ndarray) -> NDArray[np.uint8]:
    """[before | after] as one BGR image, both with the same straight reference lines and a
    label. `before` and `after` must have the same height and width."""
    if before.shape[:2] != after.shape[:2]:
        raise ValueError(f"side_by_side: sizes differ ({before.shape[:2]} vs {after.shape[:2]})")
    left = draw_reference_lines(before)
    right = draw_reference_lines(after)
    _label(left, "before (as captured)")
    _label(right, "after (undistorted)")
    gap = np.full((left.shape[0], _GAP_PX, 3), 255, dtype=np.uint8)
    return np.hstack([left, gap, right])
