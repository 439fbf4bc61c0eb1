"""`lanewarden calibrate capture --camera INDEX|PATH|URL --pattern COLSxROWS --out DIR`: grab
frames, keep those whose whole board is found and adds coverage, save them as JPGs. Headless.

A rerun into the same folder continues it: the views already there count as kept (a frame too
similar to one of them is skipped, so a rerun never adds duplicates) and new files are numbered
on. Exit codes: 0 when at least one view was kept; 2 when frames came but none was kept (no whole
board, too similar, blurred or dark: the frames fail the views' quality gates, like a failed
`calibrate`); 1 when the camera delivered no frame at all (a runtime failure of the source).

Only I/O lives here (camera, files, printing); every decision is `perception.calibration_capture`.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import click
import cv2
import numpy as np
from tqdm import tqdm

from lanewarden.camera_source import numbered_sequence_gap, open_camera, quiet_opencv
from lanewarden.commands.chessboard_pattern import PATTERN
from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import CAMERA_EXPECTED, PathFlag, WholeRange
from lanewarden.commands.output_folders import create_output_folder
from lanewarden.config import load_config
from lanewarden.errors import DeviceError, OutputError, QualityGateError, UsageError
from lanewarden.image_files import read_image, write_image
from lanewarden.perception.calibration_capture import BoardPlacement, judge_frame
from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.chessboard import ChessboardPattern, larger_pattern, suggest_pattern
from lanewarden.perception.detector import too_small

_VIEW_NAME = re.compile(r"view_(\d+)\.jpg")


def _existing_views(out_dir: Path) -> list[Path]:
    return sorted(p for p in out_dir.glob("view_*.jpg") if _VIEW_NAME.fullmatch(p.name))


def _next_index(views: list[Path]) -> int:
    taken = [int(m.group(1)) for p in views if (m := _VIEW_NAME.fullmatch(p.name))]
    return max(taken) + 1 if taken else 0


def placements_of(views: list[Path], pattern: ChessboardPattern,
                  config: CalibrationConfig) -> list[BoardPlacement]:
    """Where the board sits in each saved view that shows it (others are ignored)."""
    placements = []
    for path in views:
        image, _ = read_image(path)
        if image is None:
            continue
        decision = judge_frame(image, pattern, [], config, name=path.name)
        if decision.placement is not None:
            placements.append(decision.placement)
    return placements


def run_capture(
    camera: str,
    pattern: ChessboardPattern,
    out_dir: Path,
    count: int,
    max_frames: int | None,
    config: CalibrationConfig,
) -> dict[str, int]:
    """Grab frames until `count` new views are kept or the source ends; returns counts per
    outcome ("frames", "kept", "already there", "no board", "too similar", "rejected")."""
    create_output_folder(out_dir)
    existing = _existing_views(out_dir)
    capture = open_camera(camera)
    index = _next_index(existing)
    kept = placements_of(existing, pattern, config)
    last_frame: np.ndarray | None = None
    outcome = {"frames": 0, "kept": 0, "already there": len(kept), "no board": 0,
               "too similar": 0, "rejected": 0}
    progress = tqdm(total=count, desc="views kept", unit="view", file=sys.stderr,
                    disable=None, leave=False)
    try:
        while outcome["kept"] < count and (max_frames is None or outcome["frames"] < max_frames):
            with quiet_opencv():
                ok, frame = capture.read()
            if not ok or frame is None:
                break
            outcome["frames"] += 1
            if outcome["frames"] == 1 and (why := too_small(frame.shape[1], frame.shape[0],
                                                              use="a chessboard")):
                raise UsageError(f"--camera {camera}: its first frame: {why}")
            last_frame = frame
            decision = judge_frame(frame, pattern, kept, config, name=f"frame {outcome['frames']}")
            if not decision.keep or decision.placement is None:
                key = "rejected" if decision.reason.startswith("rejected") else decision.reason
                outcome[key] += 1
                progress.set_postfix(frames=outcome["frames"], refresh=False)
                continue
            if outcome["kept"] == 0:
                found = larger_pattern(frame, pattern)
                if found is not None:
                    raise UsageError(
                        f"--pattern {pattern}: the camera shows a board with {found} inner "
                        f"corners; use --pattern {found} (count ALL inner corners)"
                    )
            path = out_dir / f"view_{index:03d}.jpg"
            try:
                write_image(path, frame, [cv2.IMWRITE_JPEG_QUALITY, 95])
            except OSError as exc:
                raise OutputError(f"{path}: cannot write captured view "
                                  f"({exc.strerror or exc})") from None
            index += 1
            kept.append(decision.placement)
            outcome["kept"] += 1
            progress.update(1)
            progress.set_postfix(frames=outcome["frames"], refresh=False)
    finally:
        progress.close()
        capture.release()
    if outcome["kept"] == 0 and last_frame is not None and outcome["no board"] == outcome["frames"]:
        found = suggest_pattern(last_frame, pattern)
        if found is not None:
            raise UsageError(
                f"--pattern {pattern}: no frame showed the whole board, but the camera shows a "
                f"board with {found} inner corners; use --pattern {found}"
            )
    return outcome


def _breakdown(outcome: dict[str, int]) -> str:
    already = outcome["already there"]
    return (
        f"{outcome['no board']} without the whole board, {outcome['too similar']} too similar "
        f"to kept views" + (f" (including the {already} already there)" if already else "")
        + f", {outcome['rejected']} blurred or too dark"
    )


@click.command("capture")
@click.option("--camera", required=True, metavar="INDEX|PATH|URL",
              type=PathFlag(CAMERA_EXPECTED, readable=False),
              help="Camera index (0), video file, image sequence ('dir/f_%03d.png') or URL.")
@click.option("--pattern", required=True, type=PATTERN, help="Inner corners, e.g. 9x6.")
@click.option("--out", "out_dir", required=True, type=PathFlag("a folder", file_okay=True),
              metavar="DIR",
              help="Folder for the kept views (view_000.jpg, ...); created if missing. Views "
              "already there count as kept: a rerun adds only new placements.")
@click.option("--count", default=25, show_default=True, type=WholeRange(1, 1000),
              help="Stop after keeping this many new views.")
@click.option("--max-frames", type=WholeRange(1, 10_000_000), default=None,
              help="Stop after reading this many frames (default: until the source ends).")
@config_option
def capture_command(
    camera: str,
    pattern: ChessboardPattern,
    out_dir: str,
    count: int,
    max_frames: int | None,
    config_path: str | None,
) -> None:
    """Grab frames and keep those whose whole board adds coverage (position, size, tilt).

    Exit code 2 when no view was kept, 1 when the camera delivered no frame.

    \b
    Example:
      lanewarden calibrate capture --camera 0 --pattern 9x6 --out shots/
    """
    config = load_config(config_path).calibration
    outcome = run_capture(camera, pattern, Path(out_dir), count, max_frames, config)
    if outcome["frames"] == 0:
        raise DeviceError(f"--camera '{camera}': delivered no frame, nothing captured")
    gap = numbered_sequence_gap(camera, outcome["frames"])
    advice = gap or "show the board in new places, sizes and tilts"
    if outcome["kept"] == 0:
        raise QualityGateError(
            f"kept none of {outcome['frames']} frames in {out_dir} ({_breakdown(outcome)}): "
            f"{advice}"
        )
    click.echo(
        f"kept {outcome['kept']} of {count} views from {outcome['frames']} frames in {out_dir} "
        f"({_breakdown(outcome)})"
    )
    if outcome["kept"] < count:
        click.echo(
            f"stopped after {outcome['frames']} frames with fewer than {count} views kept: "
            + (gap or "show the board in new places, sizes and tilts and capture again (files "
               "are numbered on)"), err=True
        )
