"""What `lanewarden calibrate` tells the user: a text report and one JSON object.

The report shows the RMS reprojection error, per-view errors with outliers flagged, rejected views
with their reasons, which parts of the image the corners cover (a 6x6 map and the named regions
that are missing), and the camera matrix and distortion coefficients with standard deviations.

Pure formatting: returns strings and JSON-ready dicts, never prints, never writes files.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any

from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.chessboard import ViewDetection
from lanewarden.perception.chessboard_calibration import CalibrationRun, Coverage

_DIST_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4",
               "tau_x", "tau_y")


def coverage_map(coverage: Coverage) -> list[str]:
    """The 6x6 coverage grid as text rows: '#' many corners, '+' a few, '.' none."""
    counts = [c for row in coverage.corner_counts for c in row]
    busy = max(counts) if counts else 0
    rows = []
    for row in coverage.corner_counts:
        cells = ["." if c == 0 else ("#" if c * 4 >= busy else "+") for c in row]
        rows.append(" ".join(cells))
    return rows


def format_report(
    run: CalibrationRun, failures: Sequence[str], config: CalibrationConfig
) -> str:
    """The human-readable report of a calibration run and its quality gates."""
    cal = run.calibration
    used = len(run.per_view)
    total = used + len(run.rejected) + len(run.dropped_outliers)
    lines = [
        f"Calibrated from {used} of {total} views ({cal.pattern}), "
        f"image {cal.image_size[0]}x{cal.image_size[1]}",
        f"RMS reprojection error: {run.rms:.4f} px "
        f"(gate: <= calibration.max_rms_px {config.max_rms_px:g} px)",
    ]
    if run.rms_before_drop is not None:
        lines.append(
            f"  re-calibrated without {len(run.dropped_outliers)} outlier view(s) "
            f"({', '.join(run.dropped_outliers)}): RMS was {run.rms_before_drop:.4f} px"
        )
    lines.append("")
    lines.append("Per-view RMS error (px):")
    width = max((len(v.name) for v in run.per_view), default=4)
    for view in run.per_view:
        flag = "  <- outlier" if view.outlier else ""
        lines.append(f"  {view.name:<{width}}  {view.rms_px:7.4f}{flag}")
    if run.outliers:
        lines.append(
            f"  {len(run.outliers)} outlier view(s) (> {config.outlier_error_factor:g} x median and"
            f" > {config.outlier_min_error_px:g} px); --drop-outliers re-calibrates without them"
        )
    if run.rejected:
        lines.append("")
        lines.append(f"Rejected views ({len(run.rejected)}):")
        lines.extend(f"  {v.name}: {v.rejection}" for v in run.rejected)
    lines.append("")
    cov = run.coverage
    lines.append(
        f"Coverage: corners in {cov.fraction:.0%} of the image (6x6 cells; gate: >= "
        f"calibration.min_coverage_fraction {config.min_coverage_fraction:g}); "
        f"{cov.describe_missing()}"
    )
    lines.extend(f"  {row}" for row in coverage_map(cov))
    lines.append("")
    std = run.std_deviations
    lines.append("Camera matrix (px, +- one standard deviation):")
    for name, value in (("fx", cal.fx), ("fy", cal.fy), ("cx", cal.cx), ("cy", cal.cy)):
        lines.append(f"  {name} = {value:10.3f} +- {std.get(name, float('nan')):.3f}")
    lines.append("Distortion coefficients (+- one standard deviation):")
    for name, value in zip(_DIST_NAMES, cal.dist_coeffs, strict=False):
        lines.append(f"  {name} = {value:+.6f} +- {std.get(name, float('nan')):.6f}")
    for note in run.notes:
        lines.append(f"Note: {note}")
    lines.append("")
    if failures:
        lines.append("Quality gates: FAILED")
        lines.extend(f"  - {failure}" for failure in failures)
    else:
        lines.append("Quality gates: passed")
    return "\n".join(lines)


def _rejections(views: Sequence[ViewDetection]) -> list[dict[str, str]]:
    return [{"file": v.name, "reason": v.rejection or "rejected"} for v in views]


def run_as_json(run: CalibrationRun, failures: Sequence[str]) -> dict[str, Any]:
    """The JSON object of a calibration run (`--json`)."""
    cal = run.calibration
    return {
        "rms": cal.rms,
        "camera_matrix": cal.camera_matrix.tolist(),
        "dist_coeffs": cal.dist_coeffs.tolist(),
        "image_size": list(cal.image_size),
        "views_used": len(run.per_view),
        "views_rejected": _rejections(run.rejected)
        + [{"file": name, "reason": "outlier, dropped by --drop-outliers"}
           for name in run.dropped_outliers],
        "per_view_error": [
            {"file": v.name, "rms_px": v.rms_px, "outlier": v.outlier} for v in run.per_view
        ],
        "std_deviations": dict(run.std_deviations),
        "coverage": {
            "fraction": run.coverage.fraction,
            "missing": list(run.coverage.missing),
            "sparse": list(run.coverage.sparse),
        },
        "rms_before_drop": run.rms_before_drop,
        "pattern": cal.pattern,
        "date": cal.date,
        "quality_gates": {"passed": not failures, "failures": list(failures)},
    }


def unsolved_as_json(
    views: Sequence[ViewDetection], image_size: tuple[int, int] | None, failures: Sequence[str]
) -> dict[str, Any]:
    """The JSON object when too few views were usable to calibrate at all."""
    return {
        "rms": None,
        "camera_matrix": None,
        "dist_coeffs": None,
        "image_size": None if image_size is None else list(image_size),
        "views_used": sum(1 for v in views if v.accepted),
        "views_rejected": _rejections([v for v in views if not v.accepted]),
        "per_view_error": [],
        "quality_gates": {"passed": False, "failures": list(failures)},
    }


def summarize_rejections(views: Sequence[ViewDetection]) -> str:
    """e.g. '11 x board not found (looked for 8x6 inner corners, whole board); 2 x blurred ...'."""
    counts = Counter(_reason_kind(v.rejection or "") for v in views if not v.accepted)
    return "; ".join(f"{n} x {reason}" for reason, n in counts.most_common())


def _reason_kind(reason: str) -> str:
    # Numbers differ per view ("blurred (edge width 6.1 px ...)"); group by the words before them.
    for kind in ("blurred", "too little contrast", "image size"):
        if reason.startswith(kind):
            return kind
    return reason
