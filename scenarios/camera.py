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

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CameraModel:
    """A camera looking forward and down at the floor from the front of the robot.

    Defaults: a cheap 640x480 USB camera with a ~70 deg lens and visible barrel distortion,
    0.40 m above the floor, pitched 35 deg down, 0.15 m ahead of the robot's centre. With these, a
    0.60 m wide lane fills the bottom edge of the image and converges towards the top.
    """

    width_px: int = 640
    height_px: int = 480
    hfov_deg: float = 70.0
    height_m: float = 0.40
    pitch_down_deg: float = 35.0
    forward_offset_m: float = 0.15
    dist_coeffs: tuple[float, float, float, float, float] = (-0.20, 0.05, 0.0, 0.0, 0.0)

    @property
    def focal_px(self) -> float:
        return (self.width_px / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)

    def camera_matrix(self) -> FloatArray:
        """3x3 intrinsics K (square pixels, principal point at the image centre)."""
        f = self.focal_px
        return np.array(
            [[f, 0.0, self.width_px / 2.0], [0.0, f, self.height_px / 2.0], [0.0, 0.0, 1.0]]
        )

    def distortion(self) -> FloatArray:
        return np.asarray(self.dist_coeffs, dtype=np.float64)

    def rotation_robot_to_camera(self) -> FloatArray:
        """R such that p_cam = R @ (p_robot - camera_position)."""
        p = math.radians(self.pitch_down_deg)
        # Level camera: cam x = -robot y, cam y = -robot z, cam z = robot x.
        level = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
        # Pitch down by p about the camera x axis (positive p tilts the optical axis to the floor).
        pitch = np.array(
            [[1.0, 0.0, 0.0], [0.0, math.cos(p), -math.sin(p)], [0.0, math.sin(p), math.cos(p)]]
        )
        return pitch @ level

    def position_robot(self) -> FloatArray:
        return np.array([self.forward_offset_m, 0.0, self.height_m])

    def extrinsics(self) -> tuple[FloatArray, FloatArray]:
        """(rvec, tvec) for cv2.projectPoints with object points in the robot frame."""
        rot = self.rotation_robot_to_camera()
        tvec = -rot @ self.position_robot()
        rvec, _ = cv2.Rodrigues(rot)
        return np.asarray(rvec, dtype=np.float64).reshape(3), tvec.reshape(3)

    def ground_to_image_homography(self) -> FloatArray:
        """H mapping floor points (x, y, 1) in the robot frame to UNDISTORTED pixels (u, v, 1)."""
        rot = self.rotation_robot_to_camera()
        t = -rot @ self.position_robot()
        return self.camera_matrix() @ np.column_stack([rot[:, 0], rot[:, 1], t])

    def project_ground(self, points_xy: FloatArray, distort: bool = True) -> FloatArray:
        """Floor points (N, 2), robot frame -> pixels (N, 2); points behind the camera -> NaN."""
        pts = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
        rot = self.rotation_robot_to_camera()
        cam = (rot @ (np.column_stack([pts, np.zeros(len(pts))]) - self.position_robot()).T).T
        behind = cam[:, 2] <= 1e-6
        if distort:
            rvec, tvec = self.extrinsics()
            obj = np.column_stack([pts, np.zeros(len(pts))]).reshape(-1, 1, 3)
            img, _ = cv2.projectPoints(obj, rvec, tvec, self.camera_matrix(), self.distortion())
            out = np.asarray(img, dtype=np.float64).reshape(-1, 2)
        else:
            h = self.ground_to_image_homography()
            hom = (h @ np.column_stack([pts, np.ones(len(pts))]).T).T
            out = hom[:, :2] / hom[:, 2:3]
        out[behind] = np.nan
        return out

    def pixel_ground_points(self, distorted: bool = True) -> tuple[FloatArray, FloatArray]:
        """For every pixel, the floor point (x, y) in the robot frame it sees.

        Returns two (height, width) arrays; pixels looking at or above the horizon are NaN.
        With `distorted=True` the pixel grid is the real (distorted) image.
        """
        u, v = np.meshgrid(
            np.arange(self.width_px, dtype=np.float64), np.arange(self.height_px, dtype=np.float64)
        )
        pix = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
        if distorted:
            norm = cv2.undistortPoints(pix, self.camera_matrix(), self.distortion()).reshape(-1, 2)
        else:
            k_inv = np.linalg.inv(self.camera_matrix())
            norm = (k_inv @ np.column_stack([pix.reshape(-1, 2), np.ones(pix.shape[0])]).T).T[:, :2]
        rays_cam = np.column_stack([norm, np.ones(len(norm))])
        rays_robot = (self.rotation_robot_to_camera().T @ rays_cam.T).T
        origin = self.position_robot()
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = -origin[2] / rays_robot[:, 2]
        scale[~(rays_robot[:, 2] < -1e-9)] = np.nan
        ground = origin[:2] + rays_robot[:, :2] * scale[:, None]
        shape = (self.height_px, self.width_px)
        return ground[:, 0].reshape(shape), ground[:, 1].reshape(shape)
