"""`lanewarden detect IMAGE... [--config FILE] [--calibration FILE] [--out DIR] [--json]`.

Runs the lane detector on still images and prints one result per image, in order, flushed as
soon as it is known (a bad image later in the list never loses the results already printed).
Images are analysed independently (no `previous`, so `consistency` is neutral). With `--json`
each line is one JSON object:

    {"image", "left", "right", "slope_sum", "lane_offset_m", "lane_heading_rad", "confidence",
     "components", "decision"}

`left` / `right`: null or {"x1", "y1", "x2", "y2", "slope", "offset_m", "heading_rad", "near_m"}
(pixels of the analysed, i.e. undistorted, image; slope in the lecture's y-up convention; the
edge's line on the floor in the robot frame, and how far ahead it begins). `lane_offset_m` /
`lane_heading_rad`: the lane centre line's signed distance from the robot's centre (left +) and
direction (left +), null without both edges.
`decision`: "straight", "left", "right" or "none" (confidence below
`supervisor.confidence_usable_min`, or an edge missing; left/right beyond
`supervisor.turn_enter_slope_sum`: the supervisor's thresholds).
With `--out DIR`, `<name>_detect.png` overlays are written there too.

Perception sees the floor through a ground model; one line says which one (the calibration's
ground pose from `lanewarden calibrate ground`; without one the simulator's default mount) and
what a pixel covers at the look-ahead, for the images' own size (once per size, before the
first result of that size; with a calibration, its size): in the text output, on stderr with
`--json`.
A config this camera cannot work with (`PerceptionConfigError`: the floor region or the
look-ahead out of view, tape and seams not separable at the look-ahead) is a config error: one
line, exit code 2.

Unusable images (missing, empty, not an image, a folder, more pixels than
`perception.max_image_pixels`, wrong size for the calibration) are skipped and reported together
at the end as one error line naming each file; the exit code is then 2 (1 when an overlay could not
be written). The calibration is checked as `run` checks it (`require_usable_calibration`). Only
file I/O and printing live here; the work is `perception.detector`.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from lanewarden.assembly import decision_rule
from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import PathFlag
from lanewarden.commands.output_folders import create_output_folder
from lanewarden.config import load_config
from lanewarden.errors import ConfigError, InputFileError, OutputError, UsageError
from lanewarden.image_files import read_image, same_output_name, write_image
from lanewarden.perception.calibration import (
    Undistorter,
    load_calibration,
    require_usable_calibration,
)
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.errors import PerceptionConfigError, PerceptionError
from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.perception.overlay import confidence_text, draw_overlay
from lanewarden.wording import shown_name

#: `--out`'s annotated images of smaller frames are enlarged to at least this many rows, so
#: that perception's text fits their width.
ANNOTATED_MIN_ROWS = 480


def result_json(image: str, observation: LaneObservation, decision: str) -> dict[str, object]:
    """The `--json` line for one image (key order as documented)."""
    full = observation.as_json()
    return {
        "image": image,
        "left": full["left"],
        "right": full["right"],
        "slope_sum": full["slope_sum"],
        "lane_offset_m": full["lane_offset_m"],
        "lane_heading_rad": full["lane_heading_rad"],
        "confidence": full["confidence"],
        "components": full["components"],
        "decision": decision,
    }


def result_text(image: str, observation: LaneObservation, decision: str) -> str:
    """The human-readable line for one image."""

    def slope(edge: LaneEdge | None) -> str:
        return "--" if edge is None else f"{edge.slope:+.2f}"

    total = "--" if observation.slope_sum is None else f"{observation.slope_sum:+.2f}"
    return (
        f"{image}: {decision}  slope sum {total} (left {slope(observation.left)}, "
        f"right {slope(observation.right)})  {confidence_text(observation)}"
    )


def _emit(line: str) -> None:
    click.echo(line)
    sys.stdout.flush()


@click.command("detect")
@click.argument("images", nargs=-1, required=True, type=PathFlag("an image file"),
                metavar="IMAGE...")
@config_option
@click.option("--calibration", "calibration_path", type=PathFlag("a calibration file", exists=True),
              default=None,
              metavar="FILE", help="Undistort with this calibration (OpenCV FileStorage YAML).")
@click.option("--out", "out_dir", type=PathFlag("a folder"), default=None, metavar="DIR",
              help="Write an annotated <name>_detect.png per image into DIR (created).")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per image per line.")
def detect_command(
    images: tuple[str, ...],
    config_path: str | None,
    calibration_path: str | None,
    out_dir: str | None,
    as_json: bool,
) -> None:
    """Find the lane in IMAGE... and print slopes, confidence and a decision: the lecture's
    rule (slope sum past +-6: turn) on a lane confident enough to trust
    (supervisor.confidence_usable_min), else none.

    Example: lanewarden detect frames/*.png --json --out annotated/
    """
    full_config = load_config(config_path)
    config = full_config.perception
    decide = decision_rule(full_config)
    undistorter = None
    if calibration_path is not None:
        calibration = load_calibration(calibration_path)
        require_usable_calibration(calibration, calibration.image_size, full_config.calibration,
                                   f"--calibration {calibration_path}")
        undistorter = Undistorter(calibration)
    out = None
    if out_dir is not None:
        if clash := same_output_name(images, "{stem}_detect.png"):
            raise UsageError(f"--out {out_dir}: {clash}")
        out = create_output_folder(Path(out_dir))
    try:
        detector = LaneDetector(config, undistorter)
    except PerceptionConfigError as exc:
        raise ConfigError(str(exc)) from None
    # which ground model, for each image size met (a 160x120 frame is not seen as 640x480):
    # before the first result of that size; with --json on stderr (stdout stays one JSON object
    # per line)
    described: set[tuple[int, int]] = set()

    def describe(size: tuple[int, int]) -> None:
        if size in described:
            return
        line = detector.describe_ground(calibration_path, size)
        described.add(size)
        if as_json:
            click.echo(f"lanewarden: {line}", err=True)
        else:
            _emit(line)

    failures: list[str] = []
    unwritten: list[str] = []
    # A config this camera cannot work with at an image size is said once for that size, with
    # how many images it kept from being analysed (not once per image).
    refused: dict[tuple[int, int], tuple[str, list[str]]] = {}
    for index, name in enumerate(images):
        path = Path(name)
        # a file's name as one printable line (a name holding a newline had split its result
        # line and forged a second 'lanewarden: error:' line: an attacker's review)
        shown = shown_name(name)
        image, why = read_image(path, max_pixels=config.max_image_pixels)
        if image is None:
            failures.append(f"{shown}: {why}")
            continue
        size = (image.shape[1], image.shape[0])
        if undistorter is not None and size != undistorter.calibration.image_size:
            failures.append(f"{shown}: image is {size[0]}x{size[1]}, but --calibration "
                            f"{calibration_path} is for "
                            f"{'x'.join(map(str, undistorter.calibration.image_size))} images")
            continue
        if size in refused:
            refused[size][1].append(shown)
            continue
        try:
            describe(size)
            observation, debug = (
                (detector.detect(image, index, 0.0), None)
                if out is None
                else detector.detect_debug(image, index, 0.0)
            )
        except PerceptionConfigError as exc:
            refused[size] = (str(exc), [shown])
            continue
        except PerceptionError as exc:
            failures.append(f"{shown}: {exc}")
            continue
        decision = decide(observation)
        if as_json:
            _emit(json.dumps(result_json(name, observation, decision)))
        else:
            _emit(result_text(shown, observation, decision))
        if out is not None and debug is not None:
            target = out / f"{path.stem}_detect.png"
            overlay = draw_overlay(debug.image, observation, debug, decision,
                                   min_rows=ANNOTATED_MIN_ROWS)
            try:
                write_image(target, overlay)
            except OSError as exc:
                unwritten.append(f"{target}: cannot write image ({exc.strerror or exc})")
    failed = len(failures) + sum(len(paths) for _, paths in refused.values())
    failures += [f"{paths[0]}" + (f" and {len(paths) - 1} more {w}x{h} image"
                                  f"{'s' if len(paths) > 2 else ''}" if len(paths) > 1 else "")
                 + f": {why}" for (w, h), (why, paths) in refused.items()]
    if unwritten:  # a runtime failure (exit 1) outranks bad input files
        # (the first, and how many more: a full disk had listed every one of 338 images)
        more = (f"; {len(unwritten) - 1} more annotated image{'s' if len(unwritten) > 2 else ''}"
                " not written" if len(unwritten) > 1 else "")
        raise OutputError("; ".join([unwritten[0] + more, *failures]))
    if failures:
        raise InputFileError(
            f"{failed} of {len(images)} images not analysed: {'; '.join(failures)}"
        )


def commands() -> list[click.Command]:
    return [detect_command]
