"""Calibrating a camera from chessboard views: intrinsics, their uncertainty, and quality gates.

`calibrate_views` runs cv2.calibrateCameraExtended on the usable views and returns a frozen
`CalibrationRun`: the `CameraCalibration`, standard deviations of every intrinsic, per-view RMS
errors with outliers flagged, and how much of the image the corners cover (and which regions have
none). With `drop_outliers` it calibrates again without the outlier views. `gate_failures` says
which quality gates a run fails, each with the measured and the allowed value.

Pure: never reads files, never prints, never reads a clock (the date is passed in).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.calibration import CameraCalibration, check_calibration
from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.chessboard import ChessboardPattern, ViewDetection
from lanewarden.perception.errors import PerceptionError

FloatArray = NDArray[np.float64]

#: calibrateCamera needs a few views to solve for K, distortion and every view's pose.
MIN_VIEWS_TO_SOLVE = 3

#: Names of calibrateCameraExtended's stdDeviationsIntrinsics entries, in its order.
INTRINSIC_NAMES = (
    "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6",
    "s1", "s2", "s3", "s4", "tau_x", "tau_y",
)

_ROW_NAMES = ("top", "middle", "bottom")
_COLUMN_NAMES = ("left", "centre", "right")


@dataclass(frozen=True)
class ViewError:
    """One view's RMS reprojection error in pixels, and whether it is an outlier."""

    name: str
    rms_px: float
    outlier: bool


#: Coverage is measured on a FINE x FINE grid; each named region of the 3x3 grid is 2x2 cells.
COVERAGE_GRID = 6


@dataclass(frozen=True)
class Coverage:
    """Where the used corners fall in the image.

    - `corner_counts[row][col]`: corners per cell of a 6x6 grid over the image (row 0 = top).
    - `fraction`: share of those 36 cells holding at least one corner (1.0 = everywhere).
    - `missing`: names of the 3x3 regions ("top-left", "middle-right", "centre", ...) with no
      corner at all; `sparse`: regions where corners fall in only one of their four cells.
    """

    corner_counts: tuple[tuple[int, ...], ...]
    fraction: float
    missing: tuple[str, ...]
    sparse: tuple[str, ...]

    def describe_missing(self) -> str:
        """e.g. 'no corners in the top third and the middle-left region; few in the centre'."""
        if not self.missing and not self.sparse:
            return "corners in every region of the image"
        text = ""
        if self.missing:
            text = "no corners in " + _join(_group_regions(set(self.missing)))
        if self.sparse:
            few = "few corners in " + _join(_group_regions(set(self.sparse)))
            text = f"{text}; {few}" if text else few
        return text


def _join(parts: list[str]) -> str:
    if len(parts) > 1:
        return ", ".join(parts[:-1]) + " and " + parts[-1]
    return parts[0]


def _group_regions(names: set[str]) -> list[str]:
    """Region names, with whole rows/columns of the 3x3 grid said as 'the top third' etc."""
    cells = {(r, c) for r in range(3) for c in range(3) if _region_name(r, c) in names}
    parts: list[str] = []
    for r, name in enumerate(_ROW_NAMES):
        if all((r, c) in cells for c in range(3)):
            parts.append(f"the {name} third")
            cells -= {(r, c) for c in range(3)}
    for c, name in enumerate(_COLUMN_NAMES):
        if all((r, c) in cells for r in range(3)):
            parts.append(f"the {name} third")
            cells -= {(r, c) for r in range(3)}
    parts.extend(f"the {_region_name(r, c)} region" for r, c in sorted(cells))
    return parts


def _region_name(row: int, col: int) -> str:
    if (row, col) == (1, 1):
        return "centre"
    if row == 1:
        return f"middle-{_COLUMN_NAMES[col]}"
    if col == 1:
        return f"{_ROW_NAMES[row]}-centre"
    return f"{_ROW_NAMES[row]}-{_COLUMN_NAMES[col]}"


def corner_coverage(
    corner_sets: Sequence[NDArray[np.float32] | FloatArray], image_size: tuple[int, int]
) -> Coverage:
    """Count corners per cell of a 6x6 grid over a (width, height) image."""
    width, height = image_size
    n = COVERAGE_GRID
    counts = np.zeros((n, n), dtype=int)
    for corners in corner_sets:
        pts = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
        cols = np.clip((pts[:, 0] * n // width).astype(int), 0, n - 1)
        rows = np.clip((pts[:, 1] * n // height).astype(int), 0, n - 1)
        np.add.at(counts, (rows, cols), 1)
    covered = counts > 0
    step = n // 3
    missing: list[str] = []
    sparse: list[str] = []
    for r in range(3):
        for c in range(3):
            cells = int(np.count_nonzero(covered[r * step:(r + 1) * step, c * step:(c + 1) * step]))
            if cells == 0:
                missing.append(_region_name(r, c))
            elif cells == 1:
                sparse.append(_region_name(r, c))
    return Coverage(
        corner_counts=tuple(tuple(int(v) for v in row) for row in counts),
        fraction=float(np.count_nonzero(covered)) / float(n * n),
        missing=tuple(missing),
        sparse=tuple(sparse),
    )


@dataclass(frozen=True, eq=False)
class CalibrationRun:
    """The result of calibrating from chessboard views.

    - `calibration`: K, distortion, image size, rms (px), pattern, date, views_used.
    - `std_deviations`: standard deviation of each estimated intrinsic ("fx" .. "k3"), same units.
    - `per_view`: RMS reprojection error of every used view, outliers flagged.
    - `coverage`: corners of the used views over the image.
    - `rejected`: views that could not be used, each with its reason.
    - `dropped_outliers`: views removed by the outlier re-calibration (empty unless asked).
    - `rms_before_drop`: overall RMS before that re-calibration, px (None unless it happened).
    - `notes`: remarks for the report (e.g. views skipped beyond max_views_per_calibration).
    """

    calibration: CameraCalibration
    std_deviations: Mapping[str, float]
    per_view: tuple[ViewError, ...]
    coverage: Coverage
    rejected: tuple[ViewDetection, ...]
    dropped_outliers: tuple[str, ...] = ()
    rms_before_drop: float | None = None
    notes: tuple[str, ...] = ()

    @property
    def rms(self) -> float:
        return float(self.calibration.rms or 0.0)

    @property
    def outliers(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.per_view if v.outlier)


@dataclass(frozen=True, eq=False)
class _Solution:
    rms: float
    camera_matrix: FloatArray
    dist_coeffs: FloatArray
    std_intrinsics: FloatArray
    per_view_rms: FloatArray


def _solve(
    views: Sequence[ViewDetection],
    object_points: NDArray[np.float32],
    image_size: tuple[int, int],
    flags: int,
) -> _Solution:
    image_points = [np.asarray(v.corners, np.float32).reshape(-1, 1, 2) for v in views]
    object_list = [object_points.reshape(-1, 1, 3)] * len(views)
    try:
        # None: no initial guess, OpenCV sizes K and the distortion vector from `flags`.
        result = cv2.calibrateCameraExtended(  # type: ignore[call-overload]
            object_list, image_points, image_size, None, None, flags=flags
        )
    except cv2.error as exc:
        raise PerceptionError(f"calibration failed in OpenCV ({exc.err})") from exc
    rms, k, d, _rvecs, _tvecs, std_in, _std_ex, per_view = result
    return _Solution(
        rms=float(rms),
        camera_matrix=np.asarray(k, np.float64),
        dist_coeffs=np.asarray(d, np.float64).reshape(-1),
        std_intrinsics=np.asarray(std_in, np.float64).reshape(-1),
        per_view_rms=np.asarray(per_view, np.float64).reshape(-1),
    )


def flag_outliers(errors_px: Sequence[float], config: CalibrationConfig) -> list[bool]:
    """A view is an outlier when its error is above outlier_error_factor x the median view
    error AND above outlier_min_error_px (tiny errors are never outliers)."""
    if not errors_px:
        return []
    median = float(np.median(errors_px))
    limit = max(config.outlier_error_factor * median, config.outlier_min_error_px)
    return [float(e) > limit for e in errors_px]


def _evenly_chosen(count: int, limit: int) -> list[int]:
    if count <= limit:
        return list(range(count))
    return sorted({int(round(i)) for i in np.linspace(0, count - 1, limit)})


def calibrate_views(
    views: Sequence[ViewDetection],
    pattern: ChessboardPattern,
    square_m: float,
    image_size: tuple[int, int],
    config: CalibrationConfig,
    *,
    date: str | None = None,
    drop_outliers: bool = False,
    flags: int = 0,
) -> CalibrationRun:
    """Calibrate from every accepted view in `views` (rejected ones are carried into the run).

    `flags` are cv2.calibrateCamera flags (0: k1, k2, p1, p2, k3 and a free aspect ratio).
    Raises PerceptionError with fewer than MIN_VIEWS_TO_SOLVE usable views.
    """
    if not square_m > 0:
        raise PerceptionError(f"square size {square_m!r} m: expected a positive length")
    usable = [v for v in views if v.accepted]
    rejected = tuple(v for v in views if not v.accepted)
    if len(usable) < MIN_VIEWS_TO_SOLVE:
        raise PerceptionError(
            f"only {len(usable)} usable chessboard views; at least {MIN_VIEWS_TO_SOLVE} are needed"
        )
    notes: list[str] = []
    chosen = _evenly_chosen(len(usable), config.max_views_per_calibration)
    if len(chosen) < len(usable):
        notes.append(
            f"{len(usable) - len(chosen)} usable views not used "
            f"(calibration.max_views_per_calibration = {config.max_views_per_calibration})"
        )
        usable = [usable[i] for i in chosen]
    object_points = pattern.object_points(square_m)
    solution = _solve(usable, object_points, image_size, flags)
    outlier_flags = flag_outliers(solution.per_view_rms.tolist(), config)
    dropped: tuple[str, ...] = ()
    rms_before: float | None = None
    keep = [v for v, bad in zip(usable, outlier_flags, strict=True) if not bad]
    if drop_outliers and len(keep) < len(usable):
        if len(keep) >= MIN_VIEWS_TO_SOLVE:
            dropped = tuple(v.name for v, bad in zip(usable, outlier_flags, strict=True) if bad)
            rms_before = solution.rms
            usable = keep
            solution = _solve(usable, object_points, image_size, flags)
            outlier_flags = flag_outliers(solution.per_view_rms.tolist(), config)
        else:
            notes.append("outliers kept: dropping them would leave too few views")
    per_view = tuple(
        ViewError(name=v.name, rms_px=float(e), outlier=bad)
        for v, e, bad in zip(usable, solution.per_view_rms, outlier_flags, strict=True)
    )
    n_dist = solution.dist_coeffs.size
    std = {
        name: float(value)
        for name, value in zip(INTRINSIC_NAMES[: 4 + n_dist], solution.std_intrinsics, strict=False)
    }
    calibration = CameraCalibration(
        camera_matrix=solution.camera_matrix,
        dist_coeffs=solution.dist_coeffs,
        image_size=image_size,
        rms=solution.rms,
        pattern=f"{pattern} chessboard, {square_m:g} m squares",
        date=date,
        views_used=len(usable),
    )
    return CalibrationRun(
        calibration=calibration,
        std_deviations=MappingProxyType(std),
        per_view=per_view,
        coverage=corner_coverage([np.asarray(v.corners) for v in usable], image_size),
        rejected=rejected,
        dropped_outliers=dropped,
        rms_before_drop=rms_before,
        notes=tuple(notes),
    )


def gate_failures(run: CalibrationRun, config: CalibrationConfig) -> list[str]:
    """Each quality gate the run fails, with the measured and allowed value (empty: passes)."""
    failures = check_calibration(run.calibration, run.calibration.image_size, config)
    if run.coverage.fraction < config.min_coverage_fraction:
        failures.append(
            f"coverage {run.coverage.fraction:.2f} is below calibration.min_coverage_fraction "
            f"{config.min_coverage_fraction:g} ({run.coverage.describe_missing()})"
        )
    return failures
