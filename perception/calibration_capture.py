"""Choosing calibration frames from a stream: keep a frame only if its board adds coverage.

A board's `BoardPlacement` (where it sits, how big it looks, how tilted it is) is compared with
the placements already kept; `judge_frame` keeps a frame only when the whole board is found, sharp
enough, and far enough from every kept placement (`calibration.capture_min_novelty`). The idea is
the one ROS's camera_calibration uses: a good set spans the image in position, size and skew.

Pure: no camera, no files, no clock; the shell (`lanewarden calibrate capture`) does the I/O.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.chessboard import ChessboardPattern, ViewDetection, detect_view

FloatArray = NDArray[np.float64]

#: L1 weights of (x, y, size, tilt_x, tilt_y): tilts are useful over about 0..0.25, so x4.
_NOVELTY_WEIGHTS = np.array([1.0, 1.0, 1.0, 4.0, 4.0])


@dataclass(frozen=True)
class BoardPlacement:
    """Where a found board sits in the image, each value roughly in 0..1.

    - `x`, `y`: centre of the board's corners as fractions of the image width/height.
    - `size`: sqrt(board outline area / image area).
    - `tilt_x`: |left edge - right edge| / (left + right): the board turned about its vertical axis.
    - `tilt_y`: |top edge - bottom edge| / (top + bottom): turned about its horizontal axis.
    """

    x: float
    y: float
    size: float
    tilt_x: float
    tilt_y: float

    def as_array(self) -> FloatArray:
        return np.array([self.x, self.y, self.size, self.tilt_x, self.tilt_y])


def board_placement(
    corners: NDArray[np.float32] | FloatArray,
    pattern: ChessboardPattern,
    image_size: tuple[int, int],
) -> BoardPlacement:
    """Position, size and tilt of a board from its (N, 2) corners in detection order."""
    pts = np.asarray(corners, dtype=np.float64).reshape(pattern.rows, pattern.columns, 2)
    outline = np.array([pts[0, 0], pts[0, -1], pts[-1, -1], pts[-1, 0]])
    width, height = image_size
    area = abs(float(cv2.contourArea(outline.astype(np.float32))))
    top = float(np.linalg.norm(outline[1] - outline[0]))
    right = float(np.linalg.norm(outline[2] - outline[1]))
    bottom = float(np.linalg.norm(outline[3] - outline[2]))
    left = float(np.linalg.norm(outline[0] - outline[3]))
    centre = pts.reshape(-1, 2).mean(axis=0)
    # Magnitudes only: the detection order can flip by 180 deg between frames, and a board
    # tilted the other way tells the intrinsics little that is new.
    return BoardPlacement(
        x=float(centre[0] / width),
        y=float(centre[1] / height),
        size=math.sqrt(area / float(width * height)),
        tilt_x=abs(left - right) / max(left + right, 1e-9),
        tilt_y=abs(top - bottom) / max(top + bottom, 1e-9),
    )


def placement_novelty(candidate: BoardPlacement, kept: Sequence[BoardPlacement]) -> float:
    """Weighted L1 distance from `candidate` to the nearest kept placement (inf if none kept)."""
    if not kept:
        return math.inf
    c = candidate.as_array()
    return float(min(np.sum(_NOVELTY_WEIGHTS * np.abs(c - k.as_array())) for k in kept))


@dataclass(frozen=True, eq=False)
class CaptureDecision:
    """Whether to keep one frame, and why.

    `reason` is "kept", "no board" (whole board not found), "rejected: <view rejection>" or
    "too similar" (novelty below the configured minimum). `placement` is set when a board was
    found and accepted; `novelty` when it was compared with kept frames.
    """

    keep: bool
    reason: str
    view: ViewDetection
    placement: BoardPlacement | None = None
    novelty: float | None = None


def judge_frame(
    image: np.ndarray,
    pattern: ChessboardPattern,
    kept: Sequence[BoardPlacement],
    config: CalibrationConfig,
    *,
    name: str,
) -> CaptureDecision:
    """Detect the board in one frame and decide whether it adds coverage to the kept frames."""
    view = detect_view(image, pattern, config, name=name, fast_check=True)
    if view.corners is None or view.image_size is None:
        if not view.board_found:
            return CaptureDecision(keep=False, reason="no board", view=view)
        return CaptureDecision(keep=False, reason=f"rejected: {view.rejection}", view=view)
    placement = board_placement(view.corners, pattern, view.image_size)
    novelty = placement_novelty(placement, kept)
    if novelty < config.capture_min_novelty:
        return CaptureDecision(
            keep=False, reason="too similar", view=view, placement=placement, novelty=novelty
        )
    return CaptureDecision(keep=True, reason="kept", view=view, placement=placement,
                           novelty=novelty)
