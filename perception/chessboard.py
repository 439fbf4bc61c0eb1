"""Chessboard views: the pattern, corner detection with sub-pixel refinement, per-view quality.

One image in, one frozen `ViewDetection` out: either the board's inner corners (pixels, x right,
y down, in OpenCV's detection order) or the reason the view cannot be used (board not found,
blurred, too little contrast, different image size). `board_placement` describes where a found
board sits (position, size, tilt) so `calibrate capture` can keep only frames that add coverage.

Pure functions over arrays: never reads files, never prints, never reads a clock.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.detector import too_small
from lanewarden.perception.errors import PerceptionError

FloatArray = NDArray[np.float64]

#: More inner corners per side than any printable calibration board has.
MAX_PATTERN_SIDE = 100

_PATTERN_TEXT = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")

#: findChessboardCorners' default flags; FAST_CHECK quickly gives up on frames without a board.
_DETECT_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE

#: estimateChessboardSharpness reports 9999 when it found no edge profile to measure.
_UNMEASURED_EDGE_WIDTH_PX = 9999.0


@dataclass(frozen=True)
class ChessboardPattern:
    """A chessboard counted by its INNER corners: `columns` x `rows` (a board of 10x7 squares has
    9x6 inner corners)."""

    columns: int
    rows: int

    def __post_init__(self) -> None:
        if self.columns < 3 or self.rows < 3:
            raise PerceptionError(
                f"chessboard pattern {self.columns}x{self.rows}: "
                "expected at least 3x3 inner corners (OpenCV's minimum)"
            )
        if self.columns > MAX_PATTERN_SIDE or self.rows > MAX_PATTERN_SIDE:
            raise PerceptionError(
                f"chessboard pattern {self.columns}x{self.rows}: expected at most "
                f"{MAX_PATTERN_SIDE} inner corners per side"
            )

    @property
    def size(self) -> tuple[int, int]:
        """(columns, rows), as OpenCV's patternSize."""
        return (self.columns, self.rows)

    @property
    def corner_count(self) -> int:
        return self.columns * self.rows

    def __str__(self) -> str:
        return f"{self.columns}x{self.rows}"

    def object_points(self, square_m: float) -> NDArray[np.float32]:
        """(N, 3) corner positions on the board plane (z = 0), metres, in detection order
        (columns vary fastest)."""
        grid = np.zeros((self.corner_count, 3), np.float32)
        grid[:, :2] = np.indices(self.size).T.reshape(-1, 2) * np.float32(square_m)
        return grid


def parse_pattern(text: str) -> ChessboardPattern:
    """'9x6' -> ChessboardPattern(9, 6). PerceptionError on anything else."""
    match = _PATTERN_TEXT.match(text)
    if match is None:
        raise PerceptionError(
            f"{text!r} is not COLSxROWS: expected the board's inner corners, e.g. 9x6"
        )
    return ChessboardPattern(int(match.group(1)), int(match.group(2)))


@dataclass(frozen=True, eq=False)
class ViewDetection:
    """The outcome of looking for the board in one image.

    - `name`: where the image came from (file name), used in reports.
    - `image_size`: (width, height) px, None when the image could not be read.
    - `corners`: (N, 2) float32 pixels after sub-pixel refinement, None when rejected.
    - `board_found`: the whole board was found (it may still be rejected as blurred, ...).
    - `edge_width_px`: mean black-to-white transition width (blur), when the board was found and
      OpenCV could measure it (None for tiny patterns it cannot).
    - `contrast_levels`: white minus black square brightness (0..255), when the board was found.
    - `rejection`: why the view cannot be used; None for a usable view.
    """

    name: str
    image_size: tuple[int, int] | None
    corners: NDArray[np.float32] | None = None
    board_found: bool = False
    edge_width_px: float | None = None
    contrast_levels: float | None = None
    rejection: str | None = None

    @property
    def accepted(self) -> bool:
        return self.rejection is None and self.corners is not None


def unreadable_view(name: str, detail: str = "not a readable image") -> ViewDetection:
    """A view for a file that could not be decoded."""
    return ViewDetection(name=name, image_size=None, rejection=detail)


def _as_gray(image: np.ndarray) -> NDArray[np.uint8]:
    if not isinstance(image, np.ndarray) or image.size == 0 or image.ndim not in (2, 3):
        raise PerceptionError("chessboard: expected a non-empty HxW or HxWxC image array")
    if image.ndim == 3:
        if image.shape[2] == 1:
            image = image[:, :, 0]
        elif image.shape[2] == 3:
            image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        elif image.shape[2] == 4:
            image = cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY)
        else:
            raise PerceptionError(f"chessboard: image has {image.shape[2]} channels, expected 1-4")
    if image.dtype != np.uint8:
        values = np.nan_to_num(np.asarray(image, dtype=np.float64))
        low, high = float(values.min()), float(values.max())
        scale = 255.0 / (high - low) if high > low else 0.0
        image = np.rint((values - low) * scale).astype(np.uint8)
    return np.ascontiguousarray(image, dtype=np.uint8)


def find_corners(
    gray: NDArray[np.uint8], pattern: ChessboardPattern, *, fast_check: bool = False
) -> NDArray[np.float32] | None:
    """The board's inner corners (N, 1, 2) float32 at pixel accuracy, or None if the WHOLE board
    was not found. `fast_check` gives up quickly on frames without a board (capture)."""
    if too_small(gray.shape[1], gray.shape[0]):
        return None  # OpenCV fails an assertion (a traceback) under 15 px a side
    flags = _DETECT_FLAGS | (cv2.CALIB_CB_FAST_CHECK if fast_check else 0)
    found, corners = cv2.findChessboardCorners(gray, pattern.size, flags=flags)
    if not found or corners is None:
        return None
    return np.asarray(corners, dtype=np.float32)


def refine_corners(
    gray: NDArray[np.uint8], corners: NDArray[np.float32], config: CalibrationConfig
) -> NDArray[np.float32]:
    """Sub-pixel corner positions (cv2.cornerSubPix with the configured window and stop rule)."""
    criteria = (
        cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT,
        config.subpix_max_iterations,
        config.subpix_epsilon_px,
    )
    window = (config.subpix_window_px, config.subpix_window_px)
    refined = cv2.cornerSubPix(gray, corners.copy(), window, (-1, -1), criteria)
    return np.asarray(refined, dtype=np.float32)


def detect_view(
    image: np.ndarray,
    pattern: ChessboardPattern,
    config: CalibrationConfig,
    *,
    name: str,
    fast_check: bool = False,
) -> ViewDetection:
    """Find, refine and judge the board in one image (gray or BGR)."""
    gray = _as_gray(image)
    size = (int(gray.shape[1]), int(gray.shape[0]))
    if why := too_small(*size, use="a chessboard"):
        return ViewDetection(name=name, image_size=size, rejection=f"image {why}")
    corners = find_corners(gray, pattern, fast_check=fast_check)
    if corners is None:
        return ViewDetection(
            name=name, image_size=size,
            rejection=f"board not found (looked for {pattern} inner corners, whole board)",
        )
    refined = refine_corners(gray, corners, config)
    # Returns (Scalar(mean edge width, mean black level, mean white level, 0), per-edge array).
    sharpness = cv2.estimateChessboardSharpness(gray, pattern.size, refined)
    stats = np.asarray(sharpness[0], dtype=np.float64).ravel()
    measured = bool(np.all(np.isfinite(stats[:3]))) and stats[0] < _UNMEASURED_EDGE_WIDTH_PX
    edge_width = float(stats[0]) if measured else None
    contrast = float(stats[2] - stats[1]) if measured else None
    rejection = None
    if edge_width is not None and edge_width > config.max_edge_width_px:
        rejection = (
            f"blurred (edge width {edge_width:.1f} px > calibration.max_edge_width_px "
            f"{config.max_edge_width_px:g} px)"
        )
    elif contrast is not None and contrast < config.min_contrast_levels:
        rejection = (
            f"too little contrast (white-black {contrast:.0f} levels < "
            f"calibration.min_contrast_levels {config.min_contrast_levels:g})"
        )
    return ViewDetection(
        name=name,
        image_size=size,
        corners=refined.reshape(-1, 2) if rejection is None else None,
        board_found=True,
        edge_width_px=edge_width,
        contrast_levels=contrast,
        rejection=rejection,
    )


def common_image_size(views: Sequence[ViewDetection]) -> tuple[int, int] | None:
    """The image size shared by most readable views (the first seen wins a tie)."""
    sizes = [v.image_size for v in views if v.image_size is not None]
    if not sizes:
        return None
    counts = Counter(sizes)
    best = max(counts.values())
    return next(s for s in sizes if counts[s] == best)


def reject_other_sizes(
    views: Sequence[ViewDetection], image_size: tuple[int, int]
) -> list[ViewDetection]:
    """Views whose image size differs from `image_size` become rejections saying so."""
    out: list[ViewDetection] = []
    for view in views:
        if view.image_size is not None and view.image_size != image_size:
            w, h = view.image_size
            view = replace(
                view, corners=None,
                rejection=f"image size {w}x{h} differs from {image_size[0]}x{image_size[1]} "
                          "(the size of most views)",
            )
        out.append(view)
    return out


def suggest_pattern(
    image: np.ndarray, pattern: ChessboardPattern
) -> ChessboardPattern | None:
    """A nearby inner-corner count that IS found in `image`, for a hint when `pattern` is not
    found anywhere (a board counted by squares instead of inner corners, or off by one)."""
    gray = _as_gray(image)
    cols, rows = pattern.size
    candidates = [
        (cols - 1, rows - 1), (cols + 1, rows + 1), (cols - 1, rows), (cols, rows - 1),
        (cols + 1, rows), (cols, rows + 1), (cols - 2, rows - 2), (cols + 2, rows + 2),
    ]
    for c, r in candidates:
        if c < 3 or r < 3 or (c, r) == pattern.size:
            continue
        candidate = ChessboardPattern(c, r)
        if find_corners(gray, candidate, fast_check=True) is not None:
            return larger_pattern(gray, candidate) or candidate
    return None


def larger_pattern(image: np.ndarray, pattern: ChessboardPattern) -> ChessboardPattern | None:
    """The full board when `image` shows MORE inner corners than `pattern` (None otherwise).

    findChessboardCorners happily finds an 8x6 grid inside a 9x6 board, so a too-small
    --pattern would otherwise pass unnoticed (each view then uses an arbitrary part of the board).
    """
    gray = _as_gray(image)
    cols, rows = pattern.size
    grown = False
    for _ in range(4):  # grow one dimension at a time while the larger board is still found
        if find_corners(gray, ChessboardPattern(cols + 1, rows), fast_check=True) is not None:
            cols, grown = cols + 1, True
        elif find_corners(gray, ChessboardPattern(cols, rows + 1), fast_check=True) is not None:
            rows, grown = rows + 1, True
        else:
            break
    return ChessboardPattern(cols, rows) if grown else None

