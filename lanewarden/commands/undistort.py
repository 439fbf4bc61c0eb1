"""`lanewarden undistort IMAGE... --calibration FILE --out DIR [--config FILE]`: see what a
calibration does.

For each image writes `<name>_undistorted.<ext>` and `<name>_compare.png` (before | after, with
the same straight reference lines over both). The remap tables are built once per run. The
calibration is checked as `run` checks it (`require_usable_calibration`); images with more pixels
than `perception.max_image_pixels` are refused from their header. A photo is undistorted upright
as its EXIF orientation says, at the size `calibrate` and `detect` see it (`AS_SHOWN`). Bad
images are reported in one line at the end (exit 2); an output that cannot be written stops the
command (exit 1).

Only file I/O and printing live here; the work is `perception.calibration.Undistorter` and the
drawing is `perception.undistort_preview.side_by_side`.
"""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import PathFlag
from lanewarden.commands.output_folders import create_output_folder
from lanewarden.config import load_config
from lanewarden.errors import InputFileError, OutputError, UsageError
from lanewarden.image_files import (
    AS_SHOWN,
    IMAGE_SUFFIXES,
    TURNED,
    is_turned,
    read_image,
    same_output_name,
    write_image,
)
from lanewarden.perception.calibration import (
    Undistorter,
    load_calibration,
    require_usable_calibration,
)
from lanewarden.perception.undistort_preview import side_by_side


def _write(path: Path, image: np.ndarray) -> None:
    try:
        write_image(path, image)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write image ({exc.strerror or exc})") from None


@click.command("undistort")
@click.argument("images", nargs=-1, required=True,
                type=PathFlag("an image file", dir_okay=False))
@click.option("--calibration", "calibration_path", required=True,
              type=PathFlag("a calibration file", exists=True),
              metavar="FILE", help="Calibration YAML written by `lanewarden calibrate`.")
@click.option("--out", "out_dir", required=True, type=PathFlag("a folder"), metavar="DIR",
              help="Folder for the undistorted images and before/after pictures (created).")
@config_option
def undistort_command(images: tuple[str, ...], calibration_path: str, out_dir: str,
                      config_path: str | None) -> None:
    """Undistort IMAGE... and write before/after pictures with straight reference lines.

    \b
    Example:
      lanewarden undistort shots/view_000.jpg --calibration camera.yaml --out undistorted/
    """
    config = load_config(config_path)
    calibration = load_calibration(calibration_path)
    require_usable_calibration(calibration, calibration.image_size, config.calibration,
                               f"--calibration {calibration_path}")
    if clash := same_output_name(images, "{stem}_compare.png"):
        raise UsageError(f"--out {out_dir}: {clash}")
    out = create_output_folder(Path(out_dir))
    undistorter = Undistorter(calibration)
    failures: list[str] = []
    width, height = calibration.image_size
    for name in images:
        path = Path(name)
        image, why = read_image(path, AS_SHOWN, config.perception.max_image_pixels)
        if image is None:
            failures.append(f"{path}: {why}")
            continue
        if (image.shape[1], image.shape[0]) != (width, height):
            turned = f" ({TURNED})" if is_turned(path, image) else ""
            failures.append(
                f"{path}: image is {image.shape[1]}x{image.shape[0]}{turned}, the calibration "
                f"{calibration_path} is for {width}x{height}"
            )
            continue
        after = undistorter.apply(image)
        suffix = path.suffix.lower() if path.suffix.lower() in IMAGE_SUFFIXES else ".png"
        undistorted_path = out / f"{path.stem}_undistorted{suffix}"
        compare_path = out / f"{path.stem}_compare.png"
        _write(undistorted_path, after)
        _write(compare_path, side_by_side(image, after))
        click.echo(f"wrote {undistorted_path} and {compare_path}")
    if failures:
        raise InputFileError(
            f"{len(failures)} of {len(images)} images not undistorted: {'; '.join(failures)}"
        )


def commands() -> list[click.Command]:
    return [undistort_command]
