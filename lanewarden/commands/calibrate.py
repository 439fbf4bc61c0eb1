"""`lanewarden calibrate --images GLOB --pattern COLSxROWS --square METERS --out FILE`: the shell
around the calibration core, and the `calibrate` group its subcommands join.

Detect the board in every image (progress on stderr), calibrate, report, apply the quality gates,
write an OpenCV FileStorage YAML (and with `--ros` a ROS camera_info YAML) into FILE's folder
(created if missing). `--json` prints one JSON object as the last stdout line. A failed gate exits
2 (QualityGateError) and writes nothing. Subcommands: `capture` (lanewarden.commands.
calibrate_capture).

Only I/O lives here (files, clock for the date, printing); every decision is made by
`perception.chessboard*` and `perception.calibration_report`.
"""

from __future__ import annotations

import json
import math
import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import click
import cv2
from tqdm import tqdm

from lanewarden.commands.calibrate_capture import capture_command
from lanewarden.commands.chessboard_pattern import PATTERN
from lanewarden.commands.command_group import CommandGroup, unknown_command_message
from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import PathFlag
from lanewarden.commands.output_folders import create_output_file_folder
from lanewarden.config import load_config
from lanewarden.errors import OutputError, QualityGateError, UsageError
from lanewarden.image_files import expand_images, read_image
from lanewarden.perception.calibration import save_calibration, save_ros_camera_info
from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.calibration_report import (
    format_report,
    run_as_json,
    summarize_rejections,
    unsolved_as_json,
)
from lanewarden.perception.chessboard import (
    ChessboardPattern,
    ViewDetection,
    common_image_size,
    detect_view,
    larger_pattern,
    reject_other_sizes,
    suggest_pattern,
    unreadable_view,
)
from lanewarden.perception.chessboard_calibration import (
    MIN_VIEWS_TO_SOLVE,
    calibrate_views,
    gate_failures,
)
from lanewarden.perception.detector import too_small
from lanewarden.perception.errors import PerceptionError

#: Largest chessboard square `--square` accepts, metres.
MAX_SQUARE_M = 1.0


def _positive_length(ctx: click.Context, param: click.Parameter, value: float | None) -> Any:
    if value is not None and not (math.isfinite(value) and 0 < value <= MAX_SQUARE_M):
        raise click.BadParameter(
            f"{value!r} m: expected a positive square size in metres, at most {MAX_SQUARE_M:g}"
        )
    return value


class CalibrateGroup(CommandGroup):
    """A group whose stray positional words get a hint: a mistyped subcommand, or an unquoted
    glob expanded by the shell."""

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        name = args[0] if args else ""
        if name and self.get_command(ctx, name) is None and not name.startswith("-"):
            known = self.list_commands(ctx)
            if "did you mean" in (message := unknown_command_message(name, known)):
                raise click.UsageError(message, ctx)
            raise click.UsageError(
                f"unexpected argument '{name}': quote the --images glob so the shell does not "
                "expand it (e.g. --images 'shots/*.jpg'), or use a subcommand "
                f"({', '.join(known)})",
                ctx,
            )
        return super().resolve_command(ctx, args)


def _detect_all(
    paths: list[Path], pattern: ChessboardPattern, config: CalibrationConfig
) -> list[ViewDetection]:
    views: list[ViewDetection] = []
    progress = tqdm(paths, desc="detecting corners", unit="view", file=sys.stderr,
                    disable=None, leave=False)
    for path in progress:
        image, why = read_image(path, cv2.IMREAD_GRAYSCALE)
        if image is None:
            views.append(unreadable_view(path.name, why))
        else:
            views.append(detect_view(image, pattern, config, name=path.name))
    return views


def _pattern_hint(paths: list[Path], views: list[ViewDetection],
                  pattern: ChessboardPattern) -> str:
    """When no view has the board, look for a nearby inner-corner count in one image."""
    for path, view in zip(paths, views, strict=True):
        if view.image_size is None or too_small(*view.image_size):
            continue
        image, _ = read_image(path, cv2.IMREAD_GRAYSCALE)
        if image is None:
            continue
        found = suggest_pattern(image, pattern)
        if found is not None:
            return (f"; {path.name} shows a {found} inner-corner board: try --pattern {found} "
                    "(count INNER corners: squares minus one per side)")
        return f"; is --pattern {pattern} right? (count INNER corners: squares minus one per side)"
    return ""


def _check_not_larger(
    paths: list[Path], views: list[ViewDetection], pattern: ChessboardPattern, samples: int = 2
) -> None:
    """UsageError when the first few usable views show a board with more inner corners than
    --pattern (OpenCV finds a 8x6 grid inside a 9x6 board)."""
    checked = 0
    for path, view in zip(paths, views, strict=True):
        if not view.accepted or checked >= samples:
            continue
        checked += 1
        image, _ = read_image(path, cv2.IMREAD_GRAYSCALE)
        found = None if image is None else larger_pattern(image, pattern)
        if found is not None:
            raise UsageError(
                f"--pattern {pattern}: {path.name} shows a board with {found} inner corners; "
                f"use --pattern {found} (count ALL inner corners: squares minus one per side)"
            )


def _emit_json(payload: dict[str, Any]) -> None:
    click.echo(json.dumps(_finite(payload), separators=(",", ":"), allow_nan=False))


def _finite(payload: Any) -> Any:
    """NaN/inf (e.g. an unestimated standard deviation) become null: JSON has no NaN."""
    if isinstance(payload, float):
        return payload if math.isfinite(payload) else None
    if isinstance(payload, dict):
        return {k: _finite(v) for k, v in payload.items()}
    if isinstance(payload, list):
        return [_finite(v) for v in payload]
    return payload


def run_calibration(
    images: str,
    pattern: ChessboardPattern,
    square_m: float,
    out: Path,
    *,
    as_json: bool,
    ros: bool,
    drop_outliers: bool,
    config: CalibrationConfig,
) -> None:
    """The `lanewarden calibrate` shell: read, detect, calibrate, report, gate, write."""
    if out.is_dir():
        raise UsageError(f"--out '{out}': is a folder, expected a calibration file name")
    paths = expand_images(images)
    if not paths:
        raise UsageError(
            f"--images '{images}': no files match (expected a glob of chessboard images, "
            "e.g. 'shots/*.jpg', or a folder of images)"
        )
    views = _detect_all(paths, pattern, config)
    image_size = common_image_size(views)
    if image_size is None:
        raise UsageError(
            f"--images '{images}': none of the {len(paths)} matching files is a readable image"
        )
    views = reject_other_sizes(views, image_size)
    _check_not_larger(paths, views, pattern)
    usable = sum(1 for v in views if v.accepted)
    if usable < MIN_VIEWS_TO_SOLVE:
        hint = _pattern_hint(paths, views, pattern) if usable == 0 else ""
        rejections = summarize_rejections(views)
        message = (
            f"only {usable} of {len(views)} views are usable, need calibration.min_views "
            f"{config.min_views} (at least {MIN_VIEWS_TO_SOLVE} to solve at all)"
            f"{': ' + rejections if rejections else ''}{hint}; nothing written"
        )
        if as_json:
            _emit_json(unsolved_as_json(views, image_size, [message]))
        raise QualityGateError(message)
    date = datetime.now(UTC).isoformat(timespec="seconds")
    run = calibrate_views(
        views, pattern, square_m, image_size, config, date=date, drop_outliers=drop_outliers
    )
    failures = gate_failures(run, config)
    payload = run_as_json(run, failures)
    ros_path = out.with_name(out.stem + ".ros.yaml") if ros else None
    if not failures:
        create_output_file_folder(out)
        if ros_path is not None:
            create_output_file_folder(ros_path, "--ros")
        try:
            save_calibration(run.calibration, out)
            if ros_path is not None:
                save_ros_camera_info(run.calibration, ros_path, camera_name=out.stem)
        except PerceptionError as exc:  # the calibration is good; writing it failed
            raise OutputError(str(exc)) from None
    payload["calibration_file"] = None if failures else str(out)
    payload["ros_file"] = None if failures or ros_path is None else str(ros_path)
    if as_json:
        _emit_json(payload)
    else:
        click.echo(format_report(run, failures, config))
        if not failures:
            click.echo(f"Wrote {out}" + (f" and {ros_path}" if ros_path else ""))
    if failures:
        raise QualityGateError(
            f"calibration fails {len(failures)} quality gate(s): {'; '.join(failures)}; "
            f"nothing written to {out}"
        )


@click.group("calibrate", cls=CalibrateGroup, invoke_without_command=True)
@click.option("--images", metavar="GLOB",
              type=PathFlag("a glob or a folder of images", readable=False),
              help="Chessboard images: a quoted glob ('shots/*.jpg') or a folder.")
@click.option("--pattern", type=PATTERN, help="Inner corners of the board, e.g. 9x6.")
@click.option("--square", "square_m", type=float, callback=_positive_length, metavar="METERS",
              help="Side of one chessboard square in metres (scales the poses, not K).")
@click.option("--out", "out_path", type=PathFlag("a file name", dir_okay=True), metavar="FILE",
              help="Where to write the OpenCV FileStorage YAML.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (the result) as the last stdout line.")
@click.option("--ros", is_flag=True, help="Also write FILE's stem + .ros.yaml (ROS camera_info).")
@click.option("--drop-outliers", is_flag=True,
              help="Re-calibrate without the views flagged as outliers.")
@config_option
@click.pass_context
def calibrate_group(
    ctx: click.Context,
    images: str | None,
    pattern: ChessboardPattern | None,
    square_m: float | None,
    out_path: str | None,
    as_json: bool,
    ros: bool,
    drop_outliers: bool,
    config_path: str | None,
) -> None:
    """Calibrate the camera from chessboard photos; `calibrate capture` takes the photos.

    Exit code 2 when a quality gate fails (nothing is written then).

    \b
    Example:
      lanewarden calibrate --images 'shots/*.jpg' --pattern 9x6 --square 0.025 --out camera.yaml
    """
    if ctx.invoked_subcommand is not None:
        given = [flag for flag, value in (("--images", images), ("--square", square_m),
                                          ("--out", out_path), ("--pattern", pattern))
                 if value is not None]
        if given:
            raise click.UsageError(
                f"{', '.join(given)} belong after 'capture' when capturing "
                f"(lanewarden calibrate {ctx.invoked_subcommand} --pattern ... --out DIR)", ctx
            )
        return
    missing = [flag for flag, value in (("--images", images), ("--pattern", pattern),
                                        ("--square", square_m), ("--out", out_path))
               if value is None]
    if missing:
        raise click.UsageError(
            f"missing {', '.join(missing)} (usage: lanewarden calibrate --images GLOB "
            "--pattern COLSxROWS --square METERS --out FILE)", ctx
        )
    assert images is not None and pattern is not None
    assert square_m is not None and out_path is not None
    config = load_config(config_path).calibration
    run_calibration(images, pattern, square_m, Path(out_path), as_json=as_json, ros=ros,
                    drop_outliers=drop_outliers, config=config)


calibrate_group.add_command(capture_command)


def commands() -> list[click.Command]:
    from lanewarden.commands.calibrate_ground import ground_command  # imports this module

    calibrate_group.add_command(ground_command)
    return [calibrate_group]
