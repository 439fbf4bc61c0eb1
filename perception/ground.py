"""The ground model: where the floor is in the image, in metres, for one camera at one image size.

A camera's intrinsics (K, from the chessboard calibration) and its pose over the floor give the
homography between the floor plane and the UNDISTORTED image, the horizon, and the size of a
pixel on the floor anywhere in the image. Perception uses it to judge tape and seams in metres,
so the same rules hold on any camera; the simulator's camera uses the same math to render.

Frames (ROS REP 103):
- robot frame: x forward, y left, z up, metres; origin on the floor under the robot's centre
  (base_footprint).
- camera frame (OpenCV): x right, y down, z along the optical axis.
- image: pixels of the undistorted image, origin top-left, u right, v down.

Pose angles follow the right-hand rule about the robot's axes, applied to a level camera looking
along +x: `yaw_deg` about z (left +), then `pitch_deg` about the camera's left axis (nose DOWN +,
as REP 103's pitch about +y), then `roll_deg` about the optical axis (left side up +).

Pure geometry: no clock, no I/O, no distortion (undistort first; the simulator's renderer adds
distortion on top of this model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from lanewarden.perception.calibration import CameraCalibration

FloatArray = NDArray[np.float64]

#: The camera perception assumes when there is no ground calibration: the simulator's default
#: camera (a cheap ~70 deg USB camera 0.40 m above the floor, pitched 35 deg down, 0.15 m ahead of
#: the robot's centre). scenarios.camera.CameraModel's defaults are these.
DEFAULT_HFOV_DEG = 70.0
DEFAULT_POSE_HEIGHT_M = 0.40
DEFAULT_POSE_PITCH_DEG = 35.0
DEFAULT_POSE_FORWARD_M = 0.15

#: A ray closer than this to parallel with the floor (z component of its unit direction in the
#: robot frame) counts as looking at or above the horizon: it meets no floor in front of us.
_MIN_DOWN_COMPONENT = 1e-9


@dataclass(frozen=True)
class CameraPose:
    """The camera's rigid pose on the robot, relative to base_footprint.

    `height_m`: optical centre above the floor (> 0). `forward_m`, `lateral_m`: its x, y in the
    robot frame. Angles in degrees as described in the module docstring.
    """

    height_m: float
    pitch_deg: float
    roll_deg: float = 0.0
    yaw_deg: float = 0.0
    forward_m: float = 0.0
    lateral_m: float = 0.0

    def rotation_robot_to_camera(self) -> FloatArray:
        """R such that p_cam = R @ (p_robot - position)."""
        yaw, pitch, roll = (math.radians(a) for a in (self.yaw_deg, self.pitch_deg,
                                                        self.roll_deg))
        # robot axes -> a level camera looking along +x: cam x = -y, cam y = -z, cam z = x
        level = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
        cy, sy = math.cos(yaw), math.sin(yaw)
        undo_yaw = np.array([[cy, sy, 0.0], [-sy, cy, 0.0], [0.0, 0.0, 1.0]])
        # nose down by `pitch` = a rotation about the camera's x axis (which points right)
        cp, sp = math.cos(pitch), math.sin(pitch)
        pitch_m = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
        # left side up by `roll` = the image content turns clockwise about the optical axis
        cr, sr = math.cos(roll), math.sin(roll)
        roll_m = np.array([[cr, sr, 0.0], [-sr, cr, 0.0], [0.0, 0.0, 1.0]])
        return roll_m @ pitch_m @ level @ undo_yaw

    def position(self) -> FloatArray:
        """The optical centre in the robot frame, metres."""
        return np.array([self.forward_m, self.lateral_m, self.height_m])

    @classmethod
    def from_rotation(cls, rotation: FloatArray, position: FloatArray) -> CameraPose:
        """The pose whose `rotation_robot_to_camera()` is `rotation` (a proper rotation matrix)
        and whose optical centre is `position` (robot frame, metres): the inverse of the two
        methods above, as a chessboard on the floor measures them.

        The optical axis in the robot frame is (cos p cos y, cos p sin y, -sin p), which gives
        pitch and yaw; what remains of the rotation after undoing them is the roll."""
        rot = np.asarray(rotation, dtype=np.float64).reshape(3, 3)
        axis = rot.T @ np.array([0.0, 0.0, 1.0])
        pitch = math.asin(max(-1.0, min(1.0, -float(axis[2]))))
        yaw = math.atan2(float(axis[1]), float(axis[0]))
        bare = cls(height_m=1.0, pitch_deg=math.degrees(pitch), yaw_deg=math.degrees(yaw))
        # rot = roll @ (pitch @ level @ undo_yaw), so roll = rot @ bare^T
        roll_m = rot @ bare.rotation_robot_to_camera().T
        roll = math.atan2(float(roll_m[0, 1]), float(roll_m[0, 0]))
        x, y, z = (float(v) for v in np.asarray(position, dtype=np.float64).reshape(3))
        return cls(height_m=z, pitch_deg=math.degrees(pitch), roll_deg=math.degrees(roll),
                   yaw_deg=math.degrees(yaw), forward_m=x, lateral_m=y)

    def describe(self) -> str:
        """One line for users: 'h 0.26 m, pitch 40.0°, ...' (zero roll, yaw and offsets left
        out)."""
        parts = [f"h {self.height_m:.3f} m", f"pitch {self.pitch_deg:.1f}°"]
        if abs(self.roll_deg) >= 0.05:
            parts.append(f"roll {self.roll_deg:+.1f}°")
        if abs(self.yaw_deg) >= 0.05:
            parts.append(f"yaw {self.yaw_deg:+.1f}°")
        if abs(self.forward_m) >= 0.0005:
            parts.append(f"{self.forward_m:.3f} m ahead of the robot's centre")
        if abs(self.lateral_m) >= 0.0005:
            parts.append(f"{self.lateral_m:+.3f} m to its left")
        return ", ".join(parts)


class GroundModel:
    """Floor <-> undistorted image for one camera (K, pose) at one image size.

    - `floor_to_image` / `image_to_floor`: points (N, 2) <-> (N, 2); NaN where there is no
      answer (a floor point behind the camera; a pixel at or above the horizon).
    - `horizon_v(u)`: the image row of the horizon at column u (the line the floor converges to).
    - `metres_per_px_across(u, v)`: how much floor, in metres, one pixel step along the image
      row covers at (u, v) (NaN at or above the horizon). The scale every metric threshold in
      perception is turned into pixels with.
    - `pixel_at(x_m, y_m)`: where a floor point lands, as a float pixel.
    """

    def __init__(self, camera_matrix: FloatArray, pose: CameraPose,
                 image_size: tuple[int, int]) -> None:
        k = np.asarray(camera_matrix, dtype=np.float64).reshape(3, 3)
        if not (np.all(np.isfinite(k)) and k[0, 0] > 0 and k[1, 1] > 0):
            raise ValueError(f"camera matrix must be finite with positive focal lengths, got {k}")
        if not (math.isfinite(pose.height_m) and pose.height_m > 0):
            raise ValueError(f"camera height must be above the floor, got {pose.height_m} m")
        self.camera_matrix = k
        self.pose = pose
        self.image_size = (int(image_size[0]), int(image_size[1]))
        self.rotation = pose.rotation_robot_to_camera()
        self.position = pose.position()
        t = -self.rotation @ self.position
        # floor (x, y, 1) -> undistorted pixel (u, v, 1) up to scale
        self.floor_to_image_h = k @ np.column_stack([self.rotation[:, 0], self.rotation[:, 1], t])
        self.image_to_floor_h = np.linalg.inv(self.floor_to_image_h)
        self._k_inv = np.linalg.inv(k)
        # horizon: pixels whose ray has no z component in the robot frame
        up_in_camera = self.rotation @ np.array([0.0, 0.0, 1.0])
        self.horizon_line = self._k_inv.T @ up_in_camera  # (a, b, c): a u + b v + c = 0

    @classmethod
    def from_fov(cls, hfov_deg: float, image_size: tuple[int, int],
                 pose: CameraPose) -> GroundModel:
        """An ideal pinhole (square pixels, centred principal point) with this horizontal FOV."""
        return cls(camera_matrix_for_fov(hfov_deg, image_size), pose, image_size)

    def scaled_to(self, image_size: tuple[int, int]) -> GroundModel:
        """The same camera and pose at another image size (K scaled per axis)."""
        sx = image_size[0] / self.image_size[0]
        sy = image_size[1] / self.image_size[1]
        k = np.diag([sx, sy, 1.0]) @ self.camera_matrix
        return GroundModel(k, self.pose, image_size)

    # ---- projections --------------------------------------------------------------------------
    def floor_to_image(self, points_xy: FloatArray) -> FloatArray:
        """Floor points (N, 2), robot frame, metres -> undistorted pixels (N, 2); behind the
        camera -> NaN."""
        pts = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
        hom = np.column_stack([pts, np.ones(len(pts))]) @ self.floor_to_image_h.T
        out = np.full((len(pts), 2), np.nan)
        ahead = hom[:, 2] > 1e-12
        out[ahead] = hom[ahead, :2] / hom[ahead, 2:3]
        return out

    def image_to_floor(self, points_px: FloatArray) -> FloatArray:
        """Undistorted pixels (N, 2) -> floor points (N, 2), robot frame, metres; pixels at or
        above the horizon -> NaN."""
        pix = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
        rays_cam = np.column_stack([pix, np.ones(len(pix))]) @ self._k_inv.T
        rays_robot = rays_cam @ self.rotation  # R^T applied to each row
        norms = np.linalg.norm(rays_robot, axis=1)
        down = rays_robot[:, 2] < -_MIN_DOWN_COMPONENT * norms
        out = np.full((len(pix), 2), np.nan)
        scale = -self.position[2] / rays_robot[down, 2]
        out[down] = self.position[:2] + rays_robot[down, :2] * scale[:, None]
        return out

    def pixel_at(self, x_m: float, y_m: float) -> tuple[float, float]:
        u, v = self.floor_to_image(np.array([[x_m, y_m]]))[0]
        return float(u), float(v)

    # ---- scale and horizon --------------------------------------------------------------------
    def horizon_v(self, u: float | None = None) -> float:
        """Row of the horizon at column `u` (default: the image centre); +inf when the camera
        looks straight down (no horizon), -inf/+inf as the line is vertical (roll near 90 deg)."""
        a, b, c = self.horizon_line
        u = self.image_size[0] / 2.0 if u is None else u
        if abs(b) < 1e-12:
            return math.inf
        return float(-(a * u + c) / b)

    def metres_per_px_across(self, u: float, v: float) -> float:
        """Floor distance covered by one pixel step along the row at (u, v), metres."""
        a, b = self.image_to_floor(np.array([[u - 0.5, v], [u + 0.5, v]]))
        return float(np.linalg.norm(a - b))

    def metres_per_px_along(self, u: float, v: float) -> float:
        """Floor distance covered by one pixel step down the column at (u, v), metres."""
        a, b = self.image_to_floor(np.array([[u, v - 0.5], [u, v + 0.5]]))
        return float(np.linalg.norm(a - b))

    def row_at_distance(self, x_m: float) -> float:
        """The image row where the floor point straight ahead at forward distance `x_m` lands
        (NaN when it is behind the camera)."""
        return self.pixel_at(x_m, self.pose.lateral_m)[1]

    def distance_at_row(self, v: float) -> float:
        """Forward distance (robot x) of the floor seen at row `v` in the image centre column;
        NaN at or above the horizon."""
        return float(self.image_to_floor(np.array([[self.image_size[0] / 2.0, v]]))[0, 0])


def default_pose() -> CameraPose:
    return CameraPose(height_m=DEFAULT_POSE_HEIGHT_M, pitch_deg=DEFAULT_POSE_PITCH_DEG,
                      forward_m=DEFAULT_POSE_FORWARD_M)


def default_ground_model(image_size: tuple[int, int]) -> GroundModel:
    """The ground model of the simulator's default camera at `image_size` (used when a camera
    has no ground calibration; callers say so once)."""
    return GroundModel.from_fov(DEFAULT_HFOV_DEG, image_size, default_pose())


def ground_model_for(calibration: CameraCalibration | None, image_size: tuple[int, int],
                     source: str | None = None,
                     camera_matrix: FloatArray | None = None) -> tuple[GroundModel, str]:
    """The ground model perception uses for frames of `image_size`, and one line saying which.
    `camera_matrix`: the undistorted image's K when it is not the calibration's own
    (`Undistorter.camera_matrix`).

    - A calibration with a ground pose (`lanewarden calibrate ground`): its K and pose.
    - A calibration without one: its K with the simulator's default mount (0.40 m, 35°).
    - No calibration: the simulator's default camera (70° HFOV pinhole, default mount).
    K is scaled when the frames' size differs from the calibration's (the runner refuses that
    case on the robot; `detect` may see resized images). `source` names the file in the line.
    """
    where = f" from {source}" if source else ""
    if calibration is None:
        model = default_ground_model(image_size)
        return model, ("no ground calibration: assuming the simulator's default camera "
                       f"({DEFAULT_HFOV_DEG:g}° HFOV, {model.pose.describe()})")
    ground = calibration.ground
    pose = default_pose() if ground is None else ground.pose
    k = calibration.camera_matrix if camera_matrix is None else camera_matrix
    model = GroundModel(k, pose, calibration.image_size)
    if tuple(image_size) != tuple(calibration.image_size):
        model = model.scaled_to(image_size)
    if ground is None:
        return model, (f"no ground calibration in the calibration{where}: assuming the "
                       f"simulator's default mount ({pose.describe()}) with its K; run "
                       "`lanewarden calibrate ground`")
    how = f", {ground.method}" if ground.method else ""
    return model, f"ground calibration{where}: {pose.describe()}{how}"


def camera_matrix_for_fov(hfov_deg: float, image_size: tuple[int, int]) -> FloatArray:
    """K of an ideal pinhole with square pixels and the principal point at the image centre."""
    if not (0.0 < hfov_deg < 180.0):
        raise ValueError(f"horizontal field of view must be within 0..180 deg, got {hfov_deg}")
    width, height = image_size
    f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])
