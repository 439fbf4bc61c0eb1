"""`lanewarden calibrate ground`: the camera's pose over the floor, into the calibration file.

Two ways (see docs/calibration.md, "Ground calibration"):

    lanewarden calibrate ground --calibration FILE --height-m H --pitch-deg P [--roll-deg R]
        [--forward-m F] --out FILE                                  # from the mount
    lanewarden calibrate ground --calibration FILE --image IMG --pattern COLSxROWS --square M
        --board-center-m X,Y --out FILE                             # from a floor chessboard

Both print the pose, the horizon, the floor size of a pixel at the look-ahead row and the slope
sum this camera sees in bends of radius 0.5 m and 1 m (`--json`: one JSON object on the last
stdout line), write FILE (the calibration with the ground pose added; `--ros` also writes FILE's
stem + .ros.yaml) and a check picture (the floor grid drawn over the undistorted photo; default
FILE's stem + .ground-check.png). An implausible chessboard result (camera under the floor,
horizon below the board, floor error above `calibration.max_ground_error_m`, camera rolled more
than 10°) exits 2 and writes
nothing; so does a mount from which the camera sees no floor.

Only I/O lives here (files, the date, printing); the work is `perception.ground_calibration` and
`perception.ground_report`.
"""

from __future__ import annotations

import math
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import click
import numpy as np

from lanewarden.commands.calibrate import PATTERN, _emit_json, _positive_length, read_image
from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import PathFlag
from lanewarden.commands.output_folders import create_output_file_folder
from lanewarden.config import LanewardenConfig, load_config
from lanewarden.errors import OutputError, QualityGateError, UsageError
from lanewarden.image_files import write_image
from lanewarden.perception.calibration import (
    CameraCalibration,
    GroundCalibration,
    Undistorter,
    load_calibration,
    save_calibration,
    save_ros_camera_info,
)
from lanewarden.perception.chessboard import (
    ChessboardPattern,
    detect_view,
    larger_pattern,
    suggest_pattern,
)
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.errors import PerceptionConfigError, PerceptionError
from lanewarden.perception.ground import CameraPose, GroundModel
from lanewarden.perception.ground_calibration import (
    FloorChessboardSolution,
    plausibility_problems,
    pose_from_mount,
    solve_floor_chessboard,
)
from lanewarden.perception.ground_report import (
    GroundSummary,
    draw_ground_check,
    summarize_ground,
)

USAGE = ("usage: lanewarden calibrate ground --calibration FILE --height-m H --pitch-deg P "
         "--out FILE (from the mount), or --calibration FILE --image IMG --pattern COLSxROWS "
         "--square M --board-center-m X,Y --out FILE (from a floor chessboard)")


#: A floor chessboard farther than this from the robot is not one its camera sees.
MAX_BOARD_DISTANCE_M = 10.0


class PointType(click.ParamType):
    """X,Y in metres (robot frame)."""

    name = "X,Y"

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> tuple[float, float]:
        if isinstance(value, tuple):
            return value
        parts = str(value).split(",")
        try:
            x, y = (float(p) for p in parts)
        except ValueError:
            self.fail(f"{value!r}: expected X,Y in metres (robot frame: x forward, y left), "
                      "e.g. 0.6,0", param, ctx)
        if not (math.isfinite(x) and math.isfinite(y)):
            self.fail(f"{value!r}: expected finite metres", param, ctx)
        if max(abs(x), abs(y)) > MAX_BOARD_DISTANCE_M:
            self.fail(f"{value!r}: expected a board on the floor in view, within "
                      f"{MAX_BOARD_DISTANCE_M:g} m of the robot", param, ctx)
        return (x, y)


def _finite_number(ctx: click.Context, param: click.Parameter, value: float | None) -> Any:
    if value is not None and not math.isfinite(value):
        raise click.BadParameter(f"{value!r}: expected a finite number")
    return value


def _refused(problems: list[str], out: Path) -> QualityGateError:
    return QualityGateError(
        f"calibrate ground: implausible result: {'; '.join(problems)}; nothing written to {out}")


def perception_refusal(model: GroundModel, config: LanewardenConfig) -> str | None:
    """What `detect`/`run` would say about this camera with this config (the detector's own
    start-up check), or None when it works. The pose may well be right (the camera simply
    looks elsewhere than perception's floor region): a warning, not a refusal."""
    try:
        LaneDetector(config.perception, ground=model)
    except PerceptionConfigError as exc:
        return str(exc)
    return None


def _summary_lines(pose: CameraPose, method: str, summary: GroundSummary,
                   solution: FloorChessboardSolution | None, gate_m: float,
                   image_height_px: int) -> list[str]:
    lines = [f"Ground calibration {method}:", f"  camera: {pose.describe()}"]
    if solution is not None:
        errors = solution.floor_errors_m
        worst = float(np.nanmax(errors)) if np.any(np.isfinite(errors)) else math.inf
        lines.append(
            f"  reprojection error on the floor: {solution.reprojection_error_m * 1000:.2f} mm "
            f"RMS (worst corner {worst * 1000:.2f} mm; gate calibration.max_ground_error_m "
            f"{gate_m * 1000:g} mm); in the image {solution.image_error_px:.2f} px RMS")
    horizon = summary.horizon_y_px
    where = ("above the image" if horizon < 0 else "inside the image"
             if horizon < image_height_px else "below the image")
    lines.append(f"  horizon: row {horizon:.0f} at the image centre ({where})")
    if math.isfinite(summary.look_ahead_m):
        lines.append(
            f"  look-ahead: row {summary.look_ahead_y_px:.0f} sees the floor "
            f"{summary.look_ahead_m:.2f} m ahead of the robot's centre; one pixel in the middle of "
            f"that row is "
            f"{summary.mm_per_px_across_at_look_ahead:.1f} mm across and "
            f"{summary.mm_per_px_along_at_look_ahead:.1f} mm along")
    elif math.isfinite(summary.look_ahead_y_px):
        lines.append(
            f"  look-ahead: row {summary.look_ahead_y_px:.0f} is at or above the horizon: it "
            "sees no floor (move perception's look-ahead down)")
    else:
        lines.append("  look-ahead: no row of the image sees the floor at a distance perception "
                     "can use")

    def fmt(value: float | None) -> str:
        return "not seen" if value is None else f"{value:+.1f}"

    bends = "; ".join(f"R {b.radius_m:g} m: right {fmt(b.right)}, left {fmt(b.left)}"
                      for b in summary.bends)
    seen = any(v is not None for b in summary.bends for v in (b.right, b.left))
    lines.append(
        f"  strongest slope sum driving through a 90° bend (lane {summary.lane_width_m:g} m, "
        f"tape {summary.tape_width_m * 1000:g} mm): {bends}"
        + (" (the lecture turns beyond +-supervisor.turn_enter_slope_sum)" if seen
           else ": this camera sees neither tape through these bends"))
    return lines


def _payload(pose: CameraPose, method: str, summary: GroundSummary,
             solution: FloorChessboardSolution | None, problems: list[str]) -> dict[str, Any]:
    error = None if solution is None else solution.reprojection_error_m
    return {
        "height_m": round(pose.height_m, 4),
        "pitch_deg": round(pose.pitch_deg, 3),
        "roll_deg": round(pose.roll_deg, 3),
        "yaw_deg": round(pose.yaw_deg, 3),
        "forward_m": round(pose.forward_m, 4),
        "lateral_m": round(pose.lateral_m, 4),
        "method": method,
        "reprojection_error_m": None if error is None else round(error, 5),
        "image_error_px": None if solution is None else round(solution.image_error_px, 3),
        **summary.as_json(),
        "problems": problems,
    }


def _read_photo(calibration: CameraCalibration, path: Path,
                       flag: str) -> np.ndarray:
    image, why = read_image(path)
    if image is None:  # what the photo is, and how to take one (a headless Pi has no camera app)
        raise UsageError(f"{flag} '{path}': {why}; expected a photo from the robot's camera of "
                         "the chessboard lying flat on the floor (lanewarden calibrate capture "
                         "--camera 0 --pattern COLSxROWS --count 1 --out DIR takes one)")
    height, width = image.shape[:2]
    if (width, height) != tuple(calibration.image_size):
        raise UsageError(
            f"{flag} '{path}': image is {width}x{height}, the calibration is for "
            f"{calibration.image_size[0]}x{calibration.image_size[1]}")
    return image


def _solve_from_board(calibration: CameraCalibration, image: np.ndarray, image_path: Path,
                      pattern: ChessboardPattern, square_m: float,
                      centre: tuple[float, float],
                      config: LanewardenConfig) -> FloorChessboardSolution:
    view = detect_view(image, pattern, config.calibration, name=image_path.name)
    if not view.accepted or view.corners is None:
        hint = ""
        if not view.board_found:
            found = suggest_pattern(image, pattern)
            hint = (f"; the photo shows a {found} inner-corner board: try --pattern {found}"
                    if found is not None else
                    "; the whole board must be in the photo (count INNER corners)")
        raise QualityGateError(f"--image '{image_path}': {view.rejection}{hint}; nothing written")
    # OpenCV finds a 9x5 grid inside a 9x6 board: the pose from that part of the board is off by
    # a row (half a square at the board's centre), so a larger board in the photo is refused
    larger = larger_pattern(image, pattern)
    if larger is not None:
        raise UsageError(f"--pattern {pattern}: '{image_path}' shows a board with {larger} inner "
                         f"corners; use --pattern {larger} (count ALL inner corners: squares "
                         "minus one per side); nothing written")
    try:
        corners = np.asarray(view.corners, dtype=np.float64)
        return solve_floor_chessboard(corners, pattern, square_m, centre, calibration)
    except PerceptionError as exc:
        raise QualityGateError(f"{exc}; nothing written") from None


def _default_check_path(out: Path) -> Path:
    return out.with_name(out.stem + ".ground-check.png")


@click.command("ground")
@click.option("--calibration", "calibration_path", required=True,
              type=PathFlag("a calibration file", dir_okay=False, exists=True), metavar="FILE",
              help="The camera's calibration (from `lanewarden calibrate`).")
@click.option("--out", "out_path", required=True,
              type=PathFlag("a file name", dir_okay=False),
              metavar="FILE", help="Where to write the calibration with the ground pose (may be "
              "the --calibration file itself).")
@click.option("--height-m", type=float, callback=_finite_number, metavar="H",
              help="Mount: the lens's height above the floor, metres.")
@click.option("--pitch-deg", type=float, callback=_finite_number, metavar="P",
              help="Mount: how far the camera looks down from level, degrees.")
@click.option("--roll-deg", type=float, callback=_finite_number, metavar="R",
              help="Mount: roll about the optical axis, left side up +, degrees (default 0).")
@click.option("--yaw-deg", type=float, callback=_finite_number, metavar="Y",
              help="Mount: yaw, looking left +, degrees (default 0).")
@click.option("--forward-m", type=float, callback=_finite_number, metavar="F",
              help="Mount: the lens's distance ahead of the robot's centre, metres (default 0).")
@click.option("--lateral-m", type=float, callback=_finite_number, metavar="L",
              help="Mount: the lens's distance to the left of the robot's centre, metres "
              "(default 0).")
@click.option("--image", "image_path", type=PathFlag("an image file", dir_okay=False),
              metavar="IMG",
              help="Chessboard: a photo of the board lying flat on the floor (with a mount: "
              "the check picture's background).")
@click.option("--pattern", type=PATTERN, help="Chessboard: inner corners, e.g. 9x6.")
@click.option("--square", "square_m", type=float, callback=_positive_length, metavar="M",
              help="Chessboard: side of one square, metres.")
@click.option("--board-center-m", "board_centre", type=PointType(),
              help="Chessboard: the centre of its inner corners in the robot frame (x forward, "
              "y left), metres, e.g. 0.6,0. Its columns run across the robot.")
@click.option("--check-image", "check_path", type=PathFlag("a file name", dir_okay=False),
              metavar="PNG",
              help="Check picture (default: FILE's stem + .ground-check.png).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (the result) as the last stdout line.")
@click.option("--ros", is_flag=True, help="Also write FILE's stem + .ros.yaml (ROS camera_info).")
@config_option
def ground_command(
    calibration_path: str, out_path: str, height_m: float | None, pitch_deg: float | None,
    roll_deg: float | None, yaw_deg: float | None, forward_m: float | None,
    lateral_m: float | None, image_path: str | None, pattern: ChessboardPattern | None,
    square_m: float | None, board_centre: tuple[float, float] | None, check_path: str | None,
    as_json: bool, ros: bool, config_path: str | None,
) -> None:
    """The camera's pose over the floor, from its mount or from a floor chessboard photo.

    Exit code 2 when the result is implausible (nothing is written then).

    \b
    Examples:
      lanewarden calibrate ground --calibration camera.yaml --height-m 0.26 --pitch-deg 40 \\
          --forward-m 0.12 --out camera.yaml
      lanewarden calibrate ground --calibration camera.yaml --image floor.jpg --pattern 9x6 \\
          --square 0.03 --board-center-m 0.55,0 --out camera.yaml
    """
    mount = {"--height-m": height_m, "--pitch-deg": pitch_deg, "--roll-deg": roll_deg,
             "--yaw-deg": yaw_deg, "--forward-m": forward_m, "--lateral-m": lateral_m}
    board = {"--pattern": pattern, "--square": square_m, "--board-center-m": board_centre}
    mount_given = [flag for flag, value in mount.items() if value is not None]
    board_given = [flag for flag, value in board.items() if value is not None]
    if mount_given and board_given:
        raise UsageError(f"{', '.join(mount_given)} (mount) and {', '.join(board_given)} "
                         "(chessboard) are two different ways: give one")
    if not mount_given and not board_given:
        raise UsageError(f"calibrate ground: say how: {USAGE}")
    out = Path(out_path)  # its folder, and the check image's, are created when they are written
    if out.is_dir():
        raise UsageError(f"--out '{out}': is a folder, expected a file name")
    check = Path(check_path) if check_path else _default_check_path(out)
    if check.suffix.lower() not in (".png", ".jpg", ".jpeg"):
        raise UsageError(f"--check-image '{check}': expected a .png or .jpg file name")
    config = load_config(config_path)
    calibration = load_calibration(calibration_path)
    k = calibration.camera_matrix
    photo = (None if image_path is None
             else _read_photo(calibration, Path(image_path), "--image"))

    solution: FloorChessboardSolution | None = None
    if board_given:
        missing = [flag for flag, value in board.items() if value is None]
        if image_path is None:
            missing.insert(0, "--image")
        if missing:
            raise UsageError(f"missing {', '.join(missing)} ({USAGE})")
        assert photo is not None and image_path is not None and pattern is not None
        assert square_m is not None and board_centre is not None
        solution = _solve_from_board(calibration, photo, Path(image_path), pattern, square_m,
                                     board_centre, config)
        pose = solution.pose
        method = (f"from a floor chessboard ({pattern}, {square_m:g} m squares, centre at "
                  f"x {board_centre[0]:g} m, y {board_centre[1]:g} m)")
        problems = plausibility_problems(solution, config.calibration.max_ground_error_m)
        if solution.model is None:  # under the floor: nothing to measure on it
            if as_json:
                _emit_json({"height_m": round(pose.height_m, 4), "method": method,
                            "problems": problems, "calibration_file": None})
            raise _refused(problems, out)
        model = solution.model
    else:
        missing = [flag for flag in ("--height-m", "--pitch-deg") if mount[flag] is None]
        if missing:
            raise UsageError(f"missing {', '.join(missing)} ({USAGE})")
        assert height_m is not None and pitch_deg is not None
        try:
            pose = pose_from_mount(height_m, pitch_deg, roll_deg or 0.0, forward_m or 0.0,
                                   lateral_m or 0.0, yaw_deg or 0.0)
        except PerceptionError as exc:
            raise UsageError(str(exc)) from None
        method = "from the mount (measured)"
        model = GroundModel(k, pose, calibration.image_size)
        problems = []
        bottom = calibration.image_size[1] - 1
        width = calibration.image_size[0]
        if min(model.horizon_v(0.0), model.horizon_v(float(width))) >= bottom:
            problems.append(f"with pitch {pitch_deg:g}° (roll {roll_deg or 0.0:g}°) the horizon "
                            "is below the image: this camera sees no floor")

    summary = summarize_ground(model, config.perception)
    payload = _payload(pose, method, summary, solution, problems)
    ros_path = out.with_name(out.stem + ".ros.yaml") if ros else None
    if not problems:
        date = datetime.now(UTC).isoformat(timespec="seconds")
        ground = GroundCalibration(
            pose=pose, method=method, date=date,
            reprojection_error_m=None if solution is None else solution.reprojection_error_m)
        updated = replace(calibration, ground=ground)
        undistorted = None if photo is None else Undistorter(calibration).apply(photo)
        picture = draw_ground_check(
            undistorted, model, [f"camera: {pose.describe()}", method],
            look_ahead_v=summary.look_ahead_y_px,
            corners_px=None if solution is None else solution.corners_px,
            corners_floor=None if solution is None else solution.floor_points,
            lane_width_m=config.perception.lane.width_m)
        # The picture first: if it cannot be written, the calibration is left as it was.
        create_output_file_folder(check, "--check-image")
        create_output_file_folder(out)
        if ros_path is not None:
            create_output_file_folder(ros_path, "--ros")
        try:
            write_image(check, picture)
        except OSError as exc:  # a runtime failure (exit 1), as `calibrate` says it
            raise OutputError(f"--check-image '{check}': cannot write the picture "
                              f"({getattr(exc, 'strerror', None) or exc}); nothing written to "
                              f"{out}") from None
        try:
            save_calibration(updated, out)
            if ros_path is not None:
                save_ros_camera_info(updated, ros_path, camera_name=out.stem)
        except PerceptionError as exc:  # the calibration is good; writing it failed
            raise OutputError(str(exc)) from None
    payload["calibration_file"] = None if problems else str(out)
    payload["ros_file"] = None if problems or ros_path is None else str(ros_path)
    payload["check_image"] = None if problems else str(check)
    if as_json:
        _emit_json(payload)
    else:
        for line in _summary_lines(pose, method, summary, solution,
                                   config.calibration.max_ground_error_m,
                                   calibration.image_size[1]):
            click.echo(line)
        refusal = perception_refusal(model, config)
        if refusal is not None:
            click.echo(f"  warning: with this config `detect` and `run` will refuse this camera: "
                       f"{refusal}")
        if not problems:
            written = [str(out), *([str(ros_path)] if ros_path else []), str(check)]
            click.echo(f"Wrote {', '.join(written)}")
    if problems:
        raise _refused(problems, out)
