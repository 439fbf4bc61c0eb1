"""Ceiling lights mirrored by glossy floors and tape: highlights that move with the camera.

A glossy surface shows a ceiling light where the ray from the camera to the light's mirror image
(the light reflected in the floor plane) meets the floor: for a camera `h` above the floor at C
and a light `H` above the floor point L, at P = C + (L - C) * h / (h + H). The highlight moves
with the robot (by H / (h + H) of its motion), unlike anything painted on the floor, so it is
drawn per frame, not painted into the floor texture.

Each highlight is an elliptical Gaussian on the floor: the light's mirror image widened by the
surface's roughness (`FloorSpec.roughness_rad`: facets tilted that much turn the mirrored ray by
twice as much), which spreads it along the view direction 1 / sin^2(elevation of the view ray)
times as far as across (a glossy floor draws streaks towards the camera); its peak is the light's
`strength` times the surface's gloss (the floor texture's gloss layer, per pixel: grout and
matte tape stay dark), spread over that area. It is projected into the image through the
camera's real (distorted) projection, linearised at its centre, and added in frame levels (after
exposure, so it saturates).

Never reads a clock; per frame only the few lights whose highlight is in view are drawn, each
over its bounding box.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.spec import MAX_GLOSS, CeilingLightsSpec

U8 = NDArray[np.uint8]
F32 = NDArray[np.float32]
FloatArray = NDArray[np.float64]

#: The gloss layer stores gloss 0..GLOSS_FULL_SCALE as 0..255.
GLOSS_FULL_SCALE = MAX_GLOSS
#: A highlight is drawn out to this many standard deviations.
_EXTENT_SIGMA = 3.0
#: Highlights further from the camera than this (metres, on the floor) are left out.
MAX_DISTANCE_M = 6.0


class Highlights:
    """The ceiling lights' highlights for one camera over one floor (`bounds`: x0, y0, x1, y1,
    metres), with the floor's `roughness_rad`."""

    def __init__(self, ceiling: CeilingLightsSpec, camera: CameraModel,
                 bounds: tuple[float, float, float, float], roughness_rad: float) -> None:
        self.ceiling = ceiling
        self.camera = camera
        self.roughness_rad = roughness_rad
        self._h = camera.height_m
        self._position = camera.position_robot()[:2]
        x0, y0, x1, y1 = bounds
        sx, sy = ceiling.spacing_m
        ox, oy = ceiling.offset_m
        reach = MAX_DISTANCE_M * (self._h + ceiling.height_m) / self._h
        xs = ox + sx * np.arange(math.floor((x0 - reach - ox) / sx),
                                 math.ceil((x1 + reach - ox) / sx) + 1)
        ys = oy + sy * np.arange(math.floor((y0 - reach - oy) / sy),
                                 math.ceil((y1 + reach - oy) / sy) + 1)
        gx, gy = np.meshgrid(xs, ys)
        self._lights = np.column_stack([gx.ravel(), gy.ravel()])
        self._w, self._h_px = camera.width_px, camera.height_px
        # Where on the floor (robot frame) the camera sees anything: a highlight outside this
        # box is not projected at all.
        gx_r, gy_r = camera.pixel_ground_points(distorted=True)
        seen = np.isfinite(gx_r) & np.isfinite(gy_r)
        near = np.hypot(gx_r[seen], gy_r[seen]) <= MAX_DISTANCE_M
        self._box = (float(gx_r[seen][near].min()), float(gx_r[seen][near].max()),
                     float(gy_r[seen][near].min()), float(gy_r[seen][near].max()))

    def centres(self, pose: Pose2D) -> tuple[FloatArray, FloatArray]:
        """The highlights that may be in view at `pose`: floor points (N, 2) in the robot frame
        and in the world."""
        c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
        cam = np.array([pose.x_m + c * self._position[0] - s * self._position[1],
                        pose.y_m + s * self._position[0] + c * self._position[1]])
        share = self._h / (self._h + self.ceiling.height_m)
        world = cam + (self._lights - cam) * share
        rel = world - (pose.x_m, pose.y_m)
        robot = np.column_stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]])
        x0, x1, y0, y1 = self._box
        keep = (robot[:, 0] >= x0) & (robot[:, 0] <= x1) & (robot[:, 1] >= y0) & (
            robot[:, 1] <= y1)
        return robot[keep], world[keep]

    def draw(self, image: U8, pose: Pose2D, floor_map: F32, gloss: U8, fill_gloss: int,
             scale: float | tuple[float, float, float]) -> int:
        """Add the highlights in view at `pose` to `image` (frame levels, in place, saturating).
        `floor_map`: the frame's texture coordinates per pixel (the renderer's remap map) and
        `gloss` the gloss layer they index; `scale`: frame levels per unit of white floor (per
        channel for BGR). Returns how many were drawn."""
        points, _ = self.centres(pose)
        camera = self.camera
        if len(points):
            # Only where the ideal pinhole sees them: outside its view a strong lens model's
            # projection folds back into the image.
            ideal = camera.project_ground(points, distort=False)
            margin_x, margin_y = 0.1 * self._w, 0.1 * self._h_px
            inside = np.isfinite(ideal).all(axis=1) & (ideal[:, 0] > -margin_x) & (
                ideal[:, 0] < self._w + margin_x) & (ideal[:, 1] > -margin_y) & (
                ideal[:, 1] < self._h_px + margin_y)
            points = points[inside]
        if len(points) == 0:
            return 0
        eps = 0.01
        probes = np.vstack([points, points + (eps, 0.0), points + (0.0, eps)])
        pixels = camera.project_ground(probes, distort=True).reshape(3, len(points), 2)
        light_r = self.ceiling.size_m / 2.0 * self._h / (self._h + self.ceiling.height_m)
        drawn = 0
        for i, point in enumerate(points):
            centre = pixels[0, i]
            if not np.all(np.isfinite(pixels[:, i])):
                continue
            jac = np.column_stack([(pixels[1, i] - centre) / eps, (pixels[2, i] - centre) / eps])
            view = point - self._position
            distance = float(math.hypot(*view))
            along = view / max(distance, 1e-6)
            slant = math.hypot(distance, self._h)
            rise = max(self._h / slant, 0.05)  # sine of the view ray's elevation
            # Facets tilted by the roughness turn the mirrored ray by twice that: up and down
            # (moving the floor point along the view by slant / rise per radian), and sideways
            # by only `rise` times as much: streaks towards the camera.
            spread = 2.0 * self.roughness_rad * slant
            across_sigma = light_r + spread * rise
            along_sigma = light_r + spread / rise
            rot = np.array([[along[0], -along[1]], [along[1], along[0]]])
            floor_cov = rot @ np.diag([along_sigma**2, across_sigma**2]) @ rot.T
            cov = jac @ floor_cov @ jac.T
            peak = self.ceiling.strength * min(1.0, light_r**2 / (along_sigma * across_sigma))
            drawn += self._blob(image, centre, cov, peak, floor_map, gloss, fill_gloss, scale)
        return drawn

    def _blob(self, image: U8, centre: FloatArray, cov: FloatArray, peak: float,
              floor_map: F32, gloss: U8, fill_gloss: int,
              scale: float | tuple[float, float, float]) -> int:
        half = _EXTENT_SIGMA * np.sqrt(np.maximum(np.diag(cov), 1e-6))
        x0, x1 = int(math.floor(centre[0] - half[0])), int(math.ceil(centre[0] + half[0])) + 1
        y0, y1 = int(math.floor(centre[1] - half[1])), int(math.ceil(centre[1] + half[1])) + 1
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, self._w), min(y1, self._h_px)
        if x0 >= x1 or y0 >= y1:
            return 0
        try:
            inv = np.linalg.inv(cov)
        except np.linalg.LinAlgError:
            return 0
        dx = (np.arange(x0, x1, dtype=np.float32) - np.float32(centre[0]))[None, :]
        dy = (np.arange(y0, y1, dtype=np.float32) - np.float32(centre[1]))[:, None]
        quad = inv[0, 0] * dx * dx + 2.0 * inv[0, 1] * dx * dy + inv[1, 1] * dy * dy
        shine = np.exp(-0.5 * quad).astype(np.float32)
        sub = np.ascontiguousarray(floor_map[y0:y1, x0:x1])
        local = cv2.remap(gloss, sub, None, cv2.INTER_LINEAR,  # type: ignore[call-overload]
                          borderMode=cv2.BORDER_CONSTANT, borderValue=fill_gloss)
        shine *= local.astype(np.float32) * np.float32(GLOSS_FULL_SCALE / 255.0 * peak * 255.0)
        region = image[y0:y1, x0:x1]
        if region.ndim == 2:
            assert isinstance(scale, float)
            region[...] = cv2.add(region, shine * np.float32(scale), dtype=cv2.CV_8U)
        else:
            scales = scale if isinstance(scale, tuple) else (scale, scale, scale)
            for c in range(region.shape[2]):
                plane = np.ascontiguousarray(region[:, :, c])
                region[:, :, c] = cv2.add(plane, shine * np.float32(scales[c]), dtype=cv2.CV_8U)
        return 1
