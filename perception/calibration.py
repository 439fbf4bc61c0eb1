"""A camera's calibration: intrinsics and lens distortion, their file format, and undistortion.

- `CameraCalibration`: the camera matrix K (3x3, pixels), OpenCV distortion coefficients (1-D:
  k1, k2, p1, p2[, k3[, ...]]), the image size it is valid for (width, height) and, when known,
  how it was obtained (RMS reprojection error in pixels, pattern, date, number of views), and
  optionally the camera's pose over the floor (`GroundCalibration`, from `lanewarden calibrate
  ground`), which with K gives perception's ground model (`perception.ground.ground_model_for`).
- `load_calibration` / `save_calibration`: OpenCV FileStorage YAML (the format OpenCV's own
  calibration sample writes). `load_calibration` also reads a ROS camera_info YAML, which
  `save_ros_camera_info` writes.
- `Undistorter`: remap tables computed once, then one `cv2.remap` per frame.
- `check_calibration`: the problems that make a calibration unusable for a given camera, so the
  robot runner can refuse to move before the first frame.

Never prints, never reads a clock (the date is given by the caller), never touches motors.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray

from lanewarden.documents import (
    MAX_DOCUMENT_BYTES,
    MAX_LEVEL_MARKS,
    MAX_NESTING_DEPTH,
    NOT_A_REGULAR_FILE,
    config_given_as,
    is_special_file,
    level_marks,
    nesting_depth,
    shorten,
)
from lanewarden.output_files import replace_file
from lanewarden.perception.errors import PerceptionError
from lanewarden.perception.ground import CameraPose
from lanewarden.wording import shown_name

if TYPE_CHECKING:
    from lanewarden.perception.calibration_config import CalibrationConfig

FloatArray = NDArray[np.float64]

#: Lengths of OpenCV's distortion vector (plumb_bob is 5).
DIST_COEFF_COUNTS = (4, 5, 8, 12, 14)

#: The ground pose's keys in the calibration file (OpenCV FileStorage or ROS camera_info YAML),
#: with the CameraPose field each holds. height and pitch are required together; the others
#: default to 0.
GROUND_POSE_KEYS = (
    ("ground_height_m", "height_m"),
    ("ground_pitch_deg", "pitch_deg"),
    ("ground_roll_deg", "roll_deg"),
    ("ground_yaw_deg", "yaw_deg"),
    ("ground_forward_m", "forward_m"),
    ("ground_lateral_m", "lateral_m"),
)
#: The farthest a camera is mounted from the floor or the robot's centre, metres: a robot's
#: camera, not a building's (1e308 had overflowed the floor model into NumPy warnings).
MAX_MOUNT_DISTANCE_M = 10.0
#: The lowest camera a ground pose may describe, metres: the smallest robots' are 0.1 m up (a
#: JetBot's 0.125 m). A file saying 1e-9 had been taken, and the floor region then reported out
#: of view, the blame on perception.roi and the file not named.
MIN_MOUNT_HEIGHT_M = 0.02
#: How the ground pose was obtained, its error on the floor and when (optional keys).
GROUND_METHOD_KEY = "ground_method"
GROUND_ERROR_KEY = "ground_reprojection_error_m"
GROUND_DATE_KEY = "ground_date"


def _frozen_array(values: object, name: str) -> FloatArray:
    try:
        array = np.array(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise PerceptionError(f"calibration: {name} is not numeric ({exc})") from exc
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class GroundCalibration:
    """The camera's pose over the floor and how it was obtained.

    - `pose`: see `perception.ground.CameraPose` (robot frame, REP 103).
    - `method`: e.g. "from the mount" or "from a floor chessboard (9x6, 0.03 m squares)".
    - `reprojection_error_m`: RMS distance on the floor between the board's corners and where
      the solved pose puts them (chessboard only), metres.
    - `date`: ISO 8601 text, when known.
    """

    pose: CameraPose
    method: str | None = None
    reprojection_error_m: float | None = None
    date: str | None = None

    def __post_init__(self) -> None:
        pose = self.pose
        if not (math.isfinite(pose.height_m)
                and MIN_MOUNT_HEIGHT_M <= pose.height_m <= MAX_MOUNT_DISTANCE_M):
            raise PerceptionError(
                f"calibration: ground_height_m {pose.height_m:g} must be at least "
                f"{MIN_MOUNT_HEIGHT_M:g} m above the floor and within {MAX_MOUNT_DISTANCE_M:g} m "
                f"of it ({MIN_MOUNT_HEIGHT_M:g} <= value <= {MAX_MOUNT_DISTANCE_M:g})"
            )
        for key, field in GROUND_POSE_KEYS[1:]:
            value = getattr(pose, field)
            if not math.isfinite(value):
                raise PerceptionError(f"calibration: {key} {value} is not finite")
        if not -90.0 <= pose.pitch_deg <= 90.0:
            raise PerceptionError(
                f"calibration: ground_pitch_deg {pose.pitch_deg:g} must be within -90..90"
            )
        if not -90.0 <= pose.roll_deg <= 90.0:  # as `calibrate ground --roll-deg` takes it
            # rolled further, the camera is upside down: its top rows look nearer than its
            # bottom rows, and the start-up check had blamed the resolution and the tape
            raise PerceptionError(
                f"calibration: ground_roll_deg {pose.roll_deg:g} must be within -90..90 (a "
                "camera rolled further is upside down: turn its frames, or the camera)")
        if not -180.0 <= pose.yaw_deg <= 180.0:
            raise PerceptionError(
                f"calibration: ground_yaw_deg {pose.yaw_deg:g} must be within -180..180")
        for key, value in (("ground_forward_m", pose.forward_m),
                           ("ground_lateral_m", pose.lateral_m)):
            if abs(value) > MAX_MOUNT_DISTANCE_M:
                raise PerceptionError(f"calibration: {key} {value:g} must be within "
                                      f"{MAX_MOUNT_DISTANCE_M:g} m of the robot's centre")
        error = self.reprojection_error_m
        if error is not None and not (math.isfinite(error) and error >= 0):
            raise PerceptionError(
                f"calibration: {GROUND_ERROR_KEY} {error} must be a finite length >= 0 m"
            )


@dataclass(frozen=True, eq=False)
class CameraCalibration:
    """Intrinsics and distortion of one camera at one image size.

    - `camera_matrix`: (3, 3) float64, [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in pixels.
    - `dist_coeffs`: (N,) float64 with N in 4, 5, 8, 12, 14 (OpenCV's order: k1 k2 p1 p2 k3 ...).
    - `image_size`: (width, height) in pixels of the images the calibration was made with.
    - `rms`: overall RMS reprojection error in pixels of the calibration run, when known.
    - `pattern`: e.g. "9x6 chessboard, 0.025 m squares", when known.
    - `date`: ISO 8601 text, when known.
    - `views_used`: how many chessboard views went into the result, when known.
    - `ground`: the camera's pose over the floor, when calibrated (`calibrate ground`).

    Arrays are stored read-only. Shapes are checked here; values (finite, positive focal length,
    RMS) are judged by `check_calibration`, so that a bad file can be reported rather than crash.
    """

    camera_matrix: FloatArray
    dist_coeffs: FloatArray
    image_size: tuple[int, int]
    rms: float | None = None
    pattern: str | None = None
    date: str | None = None
    views_used: int | None = None
    ground: GroundCalibration | None = None

    def __post_init__(self) -> None:
        k = _frozen_array(self.camera_matrix, "camera_matrix")
        if k.shape != (3, 3):
            raise PerceptionError(
                f"calibration: camera_matrix has shape {k.shape}, expected (3, 3)"
            )
        d = _frozen_array(self.dist_coeffs, "dist_coeffs").reshape(-1)
        d.setflags(write=False)
        if d.size not in DIST_COEFF_COUNTS:
            raise PerceptionError(
                f"calibration: dist_coeffs has {d.size} values, expected one of "
                f"{', '.join(str(n) for n in DIST_COEFF_COUNTS)}"
            )
        try:
            width, height = (int(v) for v in self.image_size)
        except (TypeError, ValueError) as exc:
            raise PerceptionError(
                f"calibration: image_size {self.image_size!r} is not (width, height)"
            ) from exc
        if width <= 0 or height <= 0:
            raise PerceptionError(
                f"calibration: image_size {width}x{height} must be positive (width, height)"
            )
        if why := image_size_problem(width, height):
            raise PerceptionError(f"calibration: {why}")
        object.__setattr__(self, "camera_matrix", k)
        object.__setattr__(self, "dist_coeffs", d)
        object.__setattr__(self, "image_size", (width, height))
        if self.rms is not None:
            object.__setattr__(self, "rms", float(self.rms))
        if self.views_used is not None:
            object.__setattr__(self, "views_used", int(self.views_used))

    @property
    def fx(self) -> float:
        return float(self.camera_matrix[0, 0])

    @property
    def fy(self) -> float:
        return float(self.camera_matrix[1, 1])

    @property
    def cx(self) -> float:
        return float(self.camera_matrix[0, 2])

    @property
    def cy(self) -> float:
        return float(self.camera_matrix[1, 2])


# ---------------------------------------------------------------------------------------- files


def save_calibration(calibration: CameraCalibration, path: str | Path) -> None:
    """Write `calibration` as OpenCV FileStorage YAML (camera_matrix, distortion_coefficients,
    image_width, image_height and, when known, rms, pattern, date, views_used and the ground
    pose's keys, GROUND_POSE_KEYS and ground_method, ground_reprojection_error_m, ground_date).

    OpenCV writes it into memory (in the format the name's suffix picks: YAML, or XML or JSON
    for those suffixes); `replace_file` then puts it in place: a full disk or a crash mid-write
    never leaves a calibration cut short where one was (OpenCV's own writer does not say when
    its last write fails), and a link at the name, or at a partial file's name beside it, is
    never written through."""
    path = Path(path)
    if path.parent and not path.parent.exists():
        raise PerceptionError(f"{path}: folder {path.parent} does not exist")
    text = _storage_text(calibration, path.name)
    try:
        replace_file(path, text.encode("utf-8"))
    except OSError as exc:
        raise PerceptionError(f"{path}: cannot write calibration file "
                              f"({exc.strerror or exc})") from None


def _storage_text(calibration: CameraCalibration, name: str) -> str:
    """The calibration as OpenCV's FileStorage writes it to a file called `name`."""
    storage = cv2.FileStorage(name, cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    storage.write("camera_matrix", np.asarray(calibration.camera_matrix, dtype=np.float64))
    storage.write(
        "distortion_coefficients",
        np.asarray(calibration.dist_coeffs, dtype=np.float64).reshape(1, -1),
    )
    storage.write("image_width", int(calibration.image_size[0]))
    storage.write("image_height", int(calibration.image_size[1]))
    if calibration.rms is not None:
        storage.write("rms", float(calibration.rms))
    if calibration.views_used is not None:
        storage.write("views_used", int(calibration.views_used))
    if calibration.pattern is not None:
        storage.write("pattern", str(calibration.pattern))
    if calibration.date is not None:
        storage.write("date", str(calibration.date))
    for key, value in ground_fields(calibration.ground).items():
        storage.write(key, value)
    return str(storage.releaseAndGetString())


def ground_fields(ground: GroundCalibration | None) -> dict[str, float | str]:
    """The file keys of a ground calibration (none without one), in GROUND_POSE_KEYS order."""
    if ground is None:
        return {}
    fields: dict[str, float | str] = {
        key: float(getattr(ground.pose, field)) for key, field in GROUND_POSE_KEYS
    }
    if ground.method is not None:
        fields[GROUND_METHOD_KEY] = str(ground.method)
    if ground.reprojection_error_m is not None:
        fields[GROUND_ERROR_KEY] = float(ground.reprojection_error_m)
    if ground.date is not None:
        fields[GROUND_DATE_KEY] = str(ground.date)
    return fields


def ros_camera_info(calibration: CameraCalibration, camera_name: str = "camera") -> dict[str, Any]:
    """The calibration as a ROS camera_info YAML mapping (camera_calibration_parsers' layout).

    Monocular: rectification_matrix is the identity and projection_matrix is [K | 0], i.e. the
    rectified image uses the calibration's own K, as `Undistorter` does. A ground pose is added
    as extra top-level keys (`ground_height_m`, ...), which ROS's parser ignores.
    """
    k = np.asarray(calibration.camera_matrix, dtype=np.float64)
    d = np.asarray(calibration.dist_coeffs, dtype=np.float64).reshape(-1)
    projection = np.hstack([k, np.zeros((3, 1))])
    model = "plumb_bob" if d.size == 5 else "rational_polynomial" if d.size == 8 else "opencv"

    def matrix(values: np.ndarray, rows: int, cols: int) -> dict[str, Any]:
        return {"rows": rows, "cols": cols, "data": [float(v) for v in values.reshape(-1)]}

    return {
        "image_width": int(calibration.image_size[0]),
        "image_height": int(calibration.image_size[1]),
        "camera_name": camera_name,
        "camera_matrix": matrix(k, 3, 3),
        "distortion_model": model,
        "distortion_coefficients": matrix(d, 1, d.size),
        "rectification_matrix": matrix(np.eye(3), 3, 3),
        "projection_matrix": matrix(projection, 3, 4),
        **ground_fields(calibration.ground),
    }


def save_ros_camera_info(
    calibration: CameraCalibration, path: str | Path, camera_name: str = "camera"
) -> None:
    """Write a ROS camera_info YAML (readable by ROS and by `load_calibration`)."""
    path = Path(path)
    text = yaml.safe_dump(
        ros_camera_info(calibration, camera_name), sort_keys=False, default_flow_style=None
    )
    try:
        replace_file(path, text.encode("utf-8"))
    except OSError as exc:
        raise PerceptionError(
            f"{path}: cannot write ROS camera_info file ({exc.strerror or exc})"
        ) from exc


def _read_matrix(node: cv2.FileNode, path: Path, name: str) -> FloatArray:
    """An opencv-matrix node, or a ROS-style {rows, cols, data} mapping."""
    if node.isNone():
        raise PerceptionError(f"{path}: missing node '{name}'; {EXPECTED_CALIBRATION}")
    if not node.isMap():
        raise PerceptionError(f"{path}: node '{name}' is not a matrix (expected rows, cols, data)")
    data_node = node.getNode("data")
    if data_node.isNone() or not data_node.isSeq():
        raise PerceptionError(f"{path}: node '{name}' has no 'data' list")
    values = []
    for i in range(data_node.size()):
        item = data_node.at(i)
        if not (item.isReal() or item.isInt()):
            raise PerceptionError(f"{path}: node '{name}' data[{i}] is not a number")
        values.append(item.real())
    rows = _read_int(node.getNode("rows"), path, f"{name}.rows")
    cols = _read_int(node.getNode("cols"), path, f"{name}.cols")
    for side, value in (("rows", rows), ("cols", cols)):
        if value < 1:  # (-3 x -3 matched 9 values, and reshape raised a ValueError traceback)
            raise PerceptionError(f"{path}: node '{name}' {side} = {value}: expected a whole "
                                  "number of at least 1")
    if rows * cols != len(values):
        raise PerceptionError(
            f"{path}: node '{name}' is {rows}x{cols} but has {len(values)} values"
        )
    return np.array(values, dtype=np.float64).reshape(rows, cols)


def _repeated_node(root: cv2.FileNode) -> str:
    """The first name that appears twice in `root` or in a mapping under it (a matrix's rows,
    cols, data), dotted ('camera_matrix.rows'); '' when none does."""
    names = list(root.keys())
    for name in names:
        if names.count(name) > 1:
            return str(name)
    for name in names:
        node = root.getNode(name)
        if node.isMap() and (inner := _repeated_node(node)):
            return f"{name}.{inner}"
    return ""


def _read_int(node: cv2.FileNode, path: Path, name: str) -> int:
    if node.isNone():
        raise PerceptionError(f"{path}: missing node '{name}'; {EXPECTED_CALIBRATION}")
    if not node.isInt():
        raise PerceptionError(f"{path}: node '{name}' is not an integer")
    return int(node.real())


def _read_optional_real(node: cv2.FileNode, path: Path, name: str) -> float | None:
    if node.isNone():
        return None
    if not (node.isReal() or node.isInt()):
        raise PerceptionError(f"{path}: node '{name}' is not a number")
    return float(node.real())


def _read_optional_string(node: cv2.FileNode) -> str | None:
    """A text node as one short printable line (`ground_method`, `ground_date` are shown in the
    ground model's line: a method of ESC, BEL and a newline had set the terminal's title and
    split that line, an attacker's review)."""
    if node.isNone() or not node.isString():
        return None
    return shorten(shown_name(str(node.string())))


def _unknown_ground_key(root: cv2.FileNode, path: Path) -> None:
    """PerceptionError for a `ground_...` node that is none of ours: a misspelt pose key
    (`ground_roll_degs: 5`, `ground_forward: 0.1`) had been passed over, and the pose taken as 0
    there. Other unknown nodes are fine: OpenCV's and ROS's files carry their own."""
    known = [key for key, _ in GROUND_POSE_KEYS] + [GROUND_METHOD_KEY, GROUND_ERROR_KEY,
                                                    GROUND_DATE_KEY]
    for name in root.keys():
        if str(name).startswith("ground_") and name not in known:
            close = difflib.get_close_matches(str(name), known, n=1)
            hint = f"did you mean '{close[0]}'?" if close else f"expected one of {', '.join(known)}"
            raise PerceptionError(f"{path}: unknown node '{name}': {hint}")


def _read_ground(storage: cv2.FileStorage, path: Path) -> GroundCalibration | None:
    """The ground pose keys, if the file has any (older files have none: None)."""
    _unknown_ground_key(storage.root(), path)
    values = {key: _read_optional_real(storage.getNode(key), path, key)
              for key, _ in GROUND_POSE_KEYS}
    if all(v is None for v in values.values()):
        return None
    for key in ("ground_height_m", "ground_pitch_deg"):
        if values[key] is None:
            raise PerceptionError(
                f"{path}: node '{key}' is missing (a ground pose needs ground_height_m and "
                "ground_pitch_deg; run `lanewarden calibrate ground`)"
            )
    given = {field: values[key] for key, field in GROUND_POSE_KEYS}
    pose = CameraPose(**{field: 0.0 if value is None else value
                         for field, value in given.items()})
    try:
        return GroundCalibration(
            pose=pose,
            method=_read_optional_string(storage.getNode(GROUND_METHOD_KEY)),
            reprojection_error_m=_read_optional_real(
                storage.getNode(GROUND_ERROR_KEY), path, GROUND_ERROR_KEY),
            date=_read_optional_string(storage.getNode(GROUND_DATE_KEY)),
        )
    except PerceptionError as exc:
        raise PerceptionError(f"{path}: {str(exc).removeprefix('calibration: ')}") from None


#: A calibration's image may have at most this many pixels (the largest
#: `perception.max_image_pixels` allowed) and this long a side: its undistortion tables are
#: sized by it before any image is compared with it (20000x20000 asked for 5.6 GB).
MAX_CALIBRATION_PIXELS = 50_000_000
MAX_CALIBRATION_SIDE_PX = 20_000


def image_size_problem(width: int, height: int) -> str:
    """Why a calibration cannot be for a `width` x `height` image ('' when it can)."""
    if max(width, height) > MAX_CALIBRATION_SIDE_PX or width * height > MAX_CALIBRATION_PIXELS:
        return (f"image size {width}x{height} is larger than any camera image taken (at most "
                f"{MAX_CALIBRATION_PIXELS} pixels, {MAX_CALIBRATION_SIDE_PX} px a side)")
    return ""


#: What a calibration file is, for errors about one that is not.
EXPECTED_CALIBRATION = ("expected a camera calibration as `lanewarden calibrate` writes it "
                        "(camera_matrix, distortion_coefficients, image_width, image_height)")


def load_calibration(path: str | Path) -> CameraCalibration:
    """Read a calibration written by `save_calibration` (or OpenCV's calibration sample, or a ROS
    camera_info YAML). Raises PerceptionError naming the file and the bad or missing node."""
    path = Path(path)
    if not path.exists():
        raise PerceptionError(f"{path}: calibration file not found")
    if path.is_dir():
        raise PerceptionError(f"{path}: is a directory, expected a calibration YAML file")
    if is_special_file(path):  # OpenCV would wait for a writer
        raise PerceptionError(f"{path}: {NOT_A_REGULAR_FILE}, expected a calibration YAML file")
    # Read once and parsed from memory, as read: OpenCV would decompress a *.gz file of any
    # size, and a file may change between a check and a second read. OpenCV's parser recurses
    # once per level before any check: a deep file crashed the process (a segfault).
    try:
        with path.open("rb") as stream:  # at most one byte past the limit, whatever its size
            data = stream.read(MAX_DOCUMENT_BYTES + 1)
    except OSError as exc:
        raise PerceptionError(f"{path}: cannot read calibration file ({exc.strerror or exc})"
                              ) from None
    if len(data) > MAX_DOCUMENT_BYTES:  # the --config limit: refused before parsing
        raise PerceptionError(f"{path}: calibration file is larger than "
                              f"{MAX_DOCUMENT_BYTES // 1000} kB, refusing to read it")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise PerceptionError(f"{path}: not UTF-8 text; {EXPECTED_CALIBRATION}") from None
    if (marks := level_marks(text)) > MAX_LEVEL_MARKS:
        raise PerceptionError(f"{path}: {marks} characters that open a nesting level ([, {{, "
                              f"<, -), more than any calibration holds (at most "
                              f"{MAX_LEVEL_MARKS}), refusing to read it; {EXPECTED_CALIBRATION}")
    if nesting_depth(text) > MAX_NESTING_DEPTH:
        raise PerceptionError(f"{path}: nested deeper than {MAX_NESTING_DEPTH} levels, refusing "
                              f"to read it; {EXPECTED_CALIBRATION}")
    try:
        storage = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except (cv2.error, SystemError) as exc:
        raise PerceptionError(
            f"{path}: not a readable OpenCV FileStorage YAML calibration file"
        ) from exc
    if not storage.isOpened():
        raise PerceptionError(f"{path}: cannot open calibration file")
    try:
        root = storage.root()
        if not root.isMap():
            raise PerceptionError(f"{path}: expected a mapping of calibration nodes")
        if repeated := _repeated_node(root):
            # OpenCV reads the first silently: a ground_pitch_deg corrected at the end of the
            # file was ignored while the reader saw the correction
            raise PerceptionError(f"{path}: node '{repeated}' appears twice (OpenCV would read "
                                  "the first and ignore the other); expected each node once")
        if config := config_given_as(root.keys(), ("camera_matrix",), "calibration",
                                     EXPECTED_CALIBRATION):
            raise PerceptionError(f"{path}: {config}")
        camera_matrix = _read_matrix(storage.getNode("camera_matrix"), path, "camera_matrix")
        if camera_matrix.shape != (3, 3):
            raise PerceptionError(
                f"{path}: node 'camera_matrix' is {camera_matrix.shape[0]}x"
                f"{camera_matrix.shape[1]}, expected 3x3"
            )
        dist = _read_matrix(
            storage.getNode("distortion_coefficients"), path, "distortion_coefficients"
        ).reshape(-1)
        if dist.size not in DIST_COEFF_COUNTS:
            raise PerceptionError(
                f"{path}: node 'distortion_coefficients' has {dist.size} values, expected one of "
                f"{', '.join(str(n) for n in DIST_COEFF_COUNTS)}"
            )
        width = _read_int(storage.getNode("image_width"), path, "image_width")
        height = _read_int(storage.getNode("image_height"), path, "image_height")
        if width <= 0 or height <= 0:
            raise PerceptionError(
                f"{path}: image size {width}x{height} is not positive (image_width, image_height)"
            )
        if why := image_size_problem(width, height):  # before anything sized by it is built
            raise PerceptionError(f"{path}: {why} (image_width, image_height)")
        rms = _read_optional_real(storage.getNode("rms"), path, "rms")
        views_node = storage.getNode("views_used")
        views = None if views_node.isNone() else _read_int(views_node, path, "views_used")
        return CameraCalibration(
            camera_matrix=camera_matrix,
            dist_coeffs=dist,
            image_size=(width, height),
            rms=rms,
            pattern=_read_optional_string(storage.getNode("pattern")),
            date=_read_optional_string(storage.getNode("date")),
            views_used=views,
            ground=_read_ground(storage, path),
        )
    except cv2.error as exc:
        raise PerceptionError(f"{path}: malformed calibration file ({exc.err})") from exc
    finally:
        storage.release()


# ---------------------------------------------------------------------------------- undistortion


class Undistorter:
    """Removes lens distortion from frames of one size, with tables computed once.

    The output is an ideal pinhole image of the same size whose intrinsics are `camera_matrix`
    (by default the calibration's own K, so pixel geometry near the centre is unchanged; pixels
    mapped from outside the source image are black). A calibration without distortion (a camera
    or driver that delivers rectified frames) kept at its own K is the identity: `apply` returns
    the frame itself (after its checks) instead of remapping every pixel onto itself.
    """

    def __init__(
        self, calibration: CameraCalibration, new_camera_matrix: FloatArray | None = None
    ) -> None:
        self.calibration = calibration
        self.image_size: tuple[int, int] = calibration.image_size
        k_new = calibration.camera_matrix if new_camera_matrix is None else new_camera_matrix
        self.camera_matrix: FloatArray = _frozen_array(k_new, "new_camera_matrix")
        #: True when the maps would send every pixel onto itself (no distortion, same K).
        self.identity = bool(
            not np.any(np.asarray(calibration.dist_coeffs))
            and np.array_equal(self.camera_matrix, np.asarray(calibration.camera_matrix)))
        try:
            map_x, map_y = cv2.initUndistortRectifyMap(
                np.asarray(calibration.camera_matrix),
                np.asarray(calibration.dist_coeffs),
                None,
                np.asarray(self.camera_matrix),
                self.image_size,
                cv2.CV_32FC1,
            )
            # Fixed-point tables: about twice as fast to remap with, and half the memory.
            self._map_fixed, self._map_frac = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
        except cv2.error as exc:
            raise PerceptionError(
                f"calibration: cannot build undistortion maps ({exc.err})"
            ) from exc

    def apply(self, image: np.ndarray) -> np.ndarray:
        """Undistort one image (gray HxW or colour HxWxC, any dtype cv2.remap takes)."""
        if not isinstance(image, np.ndarray) or image.ndim not in (2, 3) or image.size == 0:
            raise PerceptionError("undistort: expected an HxW or HxWxC image array")
        height, width = image.shape[:2]
        if (width, height) != self.image_size:
            raise PerceptionError(
                f"undistort: image is {width}x{height}, the calibration is for "
                f"{self.image_size[0]}x{self.image_size[1]}"
            )
        if self.identity:
            return image
        return cv2.remap(image, self._map_fixed, self._map_frac, cv2.INTER_LINEAR)

    def undistort_points(self, points_px: FloatArray) -> FloatArray:
        """Distorted pixels (N, 2) -> pixels (N, 2) of the undistorted image."""
        pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 1, 2)
        out = cv2.undistortPoints(
            pts,
            np.asarray(self.calibration.camera_matrix),
            np.asarray(self.calibration.dist_coeffs),
            P=np.asarray(self.camera_matrix),
        )
        return np.asarray(out, dtype=np.float64).reshape(-1, 2)


# -------------------------------------------------------------------------------------- checking


#: Larger distortion coefficients describe no lens (OpenCV's rational model's fit the strongest
#: fisheyes with values in the tens); they only turn undistortion into noise.
MAX_DISTORTION_COEFFICIENT = 1.0e4
#: A focal length is at most this many times the image's side, and at least its 1/this: a view
#: from 0.6 to 178 degrees wide (a pinhole cannot see 180).
MAX_FOCAL_RATIO = 100.0


def check_calibration(
    calibration: CameraCalibration, image_size: tuple[int, int], gates: CalibrationConfig
) -> list[str]:
    """Problems that make `calibration` unusable for a camera delivering `image_size` frames.

    An empty list means usable. Each problem is one line with the measured and allowed values.
    RMS and views are judged only when the file stores them.
    """
    problems: list[str] = []
    k = calibration.camera_matrix
    d = calibration.dist_coeffs
    if not np.all(np.isfinite(k)):
        problems.append("camera_matrix has non-finite values")
    if not np.all(np.isfinite(d)):
        problems.append("dist_coeffs has non-finite values")
    elif np.any(np.abs(d) > MAX_DISTORTION_COEFFICIENT):
        problems.append(f"dist_coeffs has a value of {float(np.max(np.abs(d))):g}, beyond any "
                        f"lens (at most {MAX_DISTORTION_COEFFICIENT:g} in size)")
    if np.all(np.isfinite(k)):
        width, height = calibration.image_size
        if k[0, 0] <= 0 or k[1, 1] <= 0:
            problems.append(
                f"focal length fx={k[0, 0]:g}, fy={k[1, 1]:g} px must be positive"
            )
        elif not all(side / MAX_FOCAL_RATIO <= f <= side * MAX_FOCAL_RATIO
                     for f, side in ((k[0, 0], width), (k[1, 1], height))):
            # 1e-300 or 1e300 px had passed, then overflowed in the ground model (numpy's
            # RuntimeWarnings on stderr beside the one error line)
            problems.append(
                f"focal length fx={k[0, 0]:g}, fy={k[1, 1]:g} px is no camera's for "
                f"{width}x{height} images (expected {1 / MAX_FOCAL_RATIO:g} to "
                f"{MAX_FOCAL_RATIO:g} times the image's width and height: a view 0.6 to 178 "
                "degrees wide)"
            )
        if abs(k[2, 2] - 1.0) > 1e-9 or k[2, 0] != 0 or k[2, 1] != 0:
            problems.append("camera_matrix last row must be [0, 0, 1]")
        if not (0 <= k[0, 2] <= width and 0 <= k[1, 2] <= height):
            problems.append(
                f"principal point ({k[0, 2]:g}, {k[1, 2]:g}) px lies outside the "
                f"{width}x{height} image"
            )
    rms = calibration.rms
    if rms is not None:
        if not math.isfinite(rms):
            problems.append("rms is not finite")
        elif rms < 0:
            problems.append(f"rms {rms:g} px is negative (a reprojection error is 0 or more)")
        elif rms > gates.max_rms_px:
            problems.append(
                f"rms {rms:.3f} px exceeds calibration.max_rms_px {gates.max_rms_px:g} px"
            )
    views = calibration.views_used
    if views is not None and views < gates.min_views:
        problems.append(
            f"views_used {views} is below calibration.min_views {gates.min_views}"
        )
    cam_w, cam_h = (int(v) for v in image_size)
    cal_w, cal_h = calibration.image_size
    if (cam_w, cam_h) != (cal_w, cal_h):
        problems.append(
            f"image size mismatch: camera delivers {cam_w}x{cam_h}, calibration is for "
            f"{cal_w}x{cal_h}"
        )
    return problems


def require_usable_calibration(
    calibration: CameraCalibration,
    image_size: tuple[int, int],
    gates: CalibrationConfig,
    source: str,
    refusal: str = "not a usable calibration",
) -> None:
    """The one calibration check behind `run`, `detect` and `undistort`: PerceptionError (one
    line naming `source`, e.g. '--calibration camera.yaml', then `refusal`: `run` says it is
    'refusing to engage', the others that the calibration is not usable) listing every
    `check_calibration` problem, or nothing when the calibration is usable for `image_size`
    frames."""
    problems = check_calibration(calibration, image_size, gates)
    if problems:
        raise PerceptionError(f"{source}: {refusal}: {'; '.join(problems)}")
