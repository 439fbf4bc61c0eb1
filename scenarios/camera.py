"""The pinhole camera on the robot: where a ground point lands in the image, and back.

Frames:
- robot frame: x forward, y left, z up, metres, origin at the robot's centre on the floor.
- camera frame (OpenCV): x right, y down, z along the optical axis.
- image: pixels, origin top-left, x right, y down. "Undistorted" pixels follow the ideal pinhole;
  the camera's real pixels add lens distortion (OpenCV's model, `dist_coeffs`).

The camera is rigid on the robot, so the map from an image pixel to the floor point it sees (in the
robot frame) is fixed and computed once. Pure geometry: no clock, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.calibration import CameraCalibration, GroundCalibration
from lanewarden.perception.ground import (
    DEFAULT_HFOV_DEG,
    DEFAULT_POSE_FORWARD_M,
    DEFAULT_POSE_HEIGHT_M,
    DEFAULT_POSE_PITCH_DEG,
    CameraPose,
    GroundModel,
)

FloatArray = NDArray[np.float64]

#: The default lens distortion [k1, k2, p1, p2, k3]: a cheap USB camera's visible barrel.
DEFAULT_DIST_COEFFS = (-0.20, 0.05, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class CameraModel:
    """A camera looking forward and down at the floor from the front of the robot.

    Defaults: a cheap 640x480 USB camera with a ~70 deg lens and visible barrel distortion,
    0.40 m above the floor, pitched 35 deg down, 0.15 m ahead of the robot's centre. With these, a
    0.60 m wide lane fills the bottom edge of the image and converges towards the top.
    """

    width_px: int = 640
    height_px: int = 480
    hfov_deg: float = DEFAULT_HFOV_DEG
    height_m: float = DEFAULT_POSE_HEIGHT_M
    pitch_down_deg: float = DEFAULT_POSE_PITCH_DEG
    roll_deg: float = 0.0
    forward_offset_m: float = DEFAULT_POSE_FORWARD_M
    dist_coeffs: tuple[float, float, float, float, float] = DEFAULT_DIST_COEFFS

    @property
    def pose(self) -> CameraPose:
        return CameraPose(height_m=self.height_m, pitch_deg=self.pitch_down_deg,
                          roll_deg=self.roll_deg, forward_m=self.forward_offset_m)

    @cached_property
    def ground(self) -> GroundModel:
        """Perception's ground model of this camera (undistorted pixels): the same floor <->
        image math the detector uses, so the renderer and perception cannot disagree."""
        return GroundModel.from_fov(self.hfov_deg, (self.width_px, self.height_px), self.pose)

    @property
    def focal_px(self) -> float:
        return float(self.ground.camera_matrix[0, 0])

    def camera_matrix(self) -> FloatArray:
        """3x3 intrinsics K (square pixels, principal point at the image centre)."""
        return self.ground.camera_matrix.copy()

    def distortion(self) -> FloatArray:
        return np.asarray(self.dist_coeffs, dtype=np.float64)

    def calibration(self) -> CameraCalibration:
        """This camera's true calibration, ground pose included: what perception gets in the
        simulator, as a robot calibrated with `calibrate` and `calibrate ground` would."""
        return CameraCalibration(
            camera_matrix=self.camera_matrix(), dist_coeffs=self.distortion(),
            image_size=(self.width_px, self.height_px),
            ground=GroundCalibration(pose=self.pose,
                                     method="the simulated camera, at its true pose"))

    def rotation_robot_to_camera(self) -> FloatArray:
        """R such that p_cam = R @ (p_robot - camera_position)."""
        return self.ground.rotation.copy()

    def position_robot(self) -> FloatArray:
        return self.ground.position.copy()

    def extrinsics(self) -> tuple[FloatArray, FloatArray]:
        """(rvec, tvec) for cv2.projectPoints with object points in the robot frame."""
        rot = self.rotation_robot_to_camera()
        tvec = -rot @ self.position_robot()
        rvec, _ = cv2.Rodrigues(rot)
        return np.asarray(rvec, dtype=np.float64).reshape(3), tvec.reshape(3)

    def ground_to_image_homography(self) -> FloatArray:
        """H mapping floor points (x, y, 1) in the robot frame to UNDISTORTED pixels (u, v, 1)."""
        return self.ground.floor_to_image_h.copy()

    @cached_property
    def _projection(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(rvec, tvec, K, dist coeffs) for cv2.projectPoints, read-only: the simulator projects
        ground truth through the camera every frame, and the Rodrigues and copies cost as much
        as the projection of a few dozen points."""
        rvec, tvec = self.extrinsics()
        arrays = (rvec, tvec, self.camera_matrix(), self.distortion())
        for array in arrays:
            array.setflags(write=False)
        return arrays

    def project_ground(self, points_xy: FloatArray, distort: bool = True) -> FloatArray:
        """Floor points (N, 2), robot frame -> pixels (N, 2); points behind the camera -> NaN."""
        pts = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
        obj = np.column_stack([pts, np.zeros(len(pts))])
        cam = (self.ground.rotation @ (obj - self.ground.position).T).T
        behind = cam[:, 2] <= 1e-6
        if distort:
            rvec, tvec, k, dist = self._projection
            img, _ = cv2.projectPoints(obj.reshape(-1, 1, 3), rvec, tvec, k, dist)
            out = np.asarray(img, dtype=np.float64).reshape(-1, 2)
        else:
            h = self.ground_to_image_homography()
            hom = (h @ np.column_stack([pts, np.ones(len(pts))]).T).T
            out = hom[:, :2] / hom[:, 2:3]
        out[behind] = np.nan
        return out

    def pixel_ground_points(self, distorted: bool = True) -> tuple[FloatArray, FloatArray]:
        """For every pixel, the floor point (x, y) in the robot frame it sees.

        Returns two (height, width) arrays, read-only; pixels looking at or above the horizon are
        NaN. With `distorted=True` the pixel grid is the real (distorted) image. Computed once
        per camera: every run of a campaign's worker asks for the same camera's (its renderer's
        floor grid and its ceiling lights' highlights).
        """
        return _pixel_ground_points(self, distorted)


@lru_cache(maxsize=4)
def _pixel_ground_points(camera: CameraModel, distorted: bool) -> tuple[FloatArray, FloatArray]:
    u, v = np.meshgrid(
        np.arange(camera.width_px, dtype=np.float64), np.arange(camera.height_px, dtype=np.float64)
    )
    pix: FloatArray = np.stack([u.ravel(), v.ravel()], axis=1)
    if distorted:
        k = camera.camera_matrix()
        # OpenCV's default of 5 fixed-point iterations does not converge near the corners
        # of a wide lens (120 deg with k1 -0.2: tapes bent outward there); iterate to
        # convergence instead.
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-9)
        pix = np.asarray(cv2.undistortPoints(pix.reshape(-1, 1, 2), k, camera.distortion(),
                                             None, None, k, criteria),
                         dtype=np.float64).reshape(-1, 2)
    ground = camera.ground.image_to_floor(pix)
    ground.setflags(write=False)
    shape = (camera.height_px, camera.width_px)
    return ground[:, 0].reshape(shape), ground[:, 1].reshape(shape)
