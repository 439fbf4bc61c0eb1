"""Ceiling lights mirrored by glossy floors and tape: highlights that move with the camera.

A glossy floor is a blurred mirror. A camera pixel that sees the floor at P (camera `h` above
the floor at C) sees, mirrored, the ceiling point where the ray reflected at P meets the
ceiling `H` above the floor: C + (P - C) * (h + H) / h, straight beyond P. That point is fixed
on the robot (like the floor point, `CameraModel.pixel_ground_points`), so per frame it only
moves with the robot's pose: one `cv2.transform` into the ceiling's coordinates and one
`cv2.remap` of the ceiling (a tile of one light, repeated). A light's highlight
thus lies where the ray from the camera to its mirror image meets the floor, and moves with
the robot (by H / (h + H) of its motion), unlike anything painted on the floor.

Roughness (`FloorSpec.roughness_rad`, alpha): facets tilted by alpha turn the mirrored ray by
2 alpha. Across the plane of incidence that spreads the ceiling point by 2 alpha H (the ceiling
tile is blurred by that), along it the reflected ray's elevation, which the camera sees as an
image angle, by 2 alpha: the highlights are smeared down the image over 2 alpha x focal length
pixels (1 sigma; a glossy floor draws streaks towards the camera). The result is the light's
`strength` times the surface's gloss per pixel (the floor texture's gloss layer: grout and matte
tape stay dark), added in frame levels after exposure (so it saturates).

Never reads a clock; everything per pixel is precomputed per camera, and the ceiling around the
camera is one texture (whole periods of the light grid, shifted by whole periods with the robot,
so no coordinate wraps); per frame it is two remaps, a blur, a multiply and an add, all uint8.
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

#: The gloss layer stores gloss 0..GLOSS_FULL_SCALE as 0..255.
GLOSS_FULL_SCALE = MAX_GLOSS
#: The ceiling texture's resolution: half the roughness blur, within these bounds (metres).
CEILING_RES_M = (0.02, 0.08)
#: Pixels looking at the floor further than this from the camera (metres) mirror nothing (a
#: ray reflected that flat sees the walls, not the lights), nor do those whose mirrored ray meets
#: the ceiling further away than the lights' `reach_m`.
MAX_DISTANCE_M = 6.0


class Highlights:
    """The ceiling lights' reflections for one camera, on a floor of `roughness_rad`."""

    def __init__(self, ceiling: CeilingLightsSpec, camera: CameraModel,
                 roughness_rad: float) -> None:
        self.ceiling = ceiling
        self.camera = camera
        h, big_h = camera.height_m, ceiling.height_m
        w_px, h_px = camera.width_px, camera.height_px
        # The light is smooth (blurred by the roughness): it is looked up at half the
        # resolution and scaled up; only the gloss (sharp at grout and tape edges) is full size.
        full_x, full_y = camera.pixel_ground_points(distorted=True)
        half = (w_px // 2, h_px // 2)
        gx = np.asarray(cv2.resize(full_x, half, interpolation=cv2.INTER_LINEAR), np.float64)
        gy = np.asarray(cv2.resize(full_y, half, interpolation=cv2.INTER_LINEAR), np.float64)
        cam = camera.position_robot()[:2]
        grow = (h + big_h) / h
        reach = min(MAX_DISTANCE_M * grow, ceiling.reach_m)
        distance = np.hypot(gx - cam[0], gy - cam[1])
        seen = np.isfinite(distance) & (distance * grow < reach)
        mirror = np.full((h_px // 2, w_px // 2, 2), 1.0e7, np.float32)  # off the ceiling
        mirror[seen, 0] = cam[0] + (gx[seen] - cam[0]) * grow
        mirror[seen, 1] = cam[1] + (gy[seen] - cam[1]) * grow
        self._mirror = mirror
        self._cam = cam
        # One period of the ceiling: a light (a disc `size_m` across) in the middle, blurred by
        # the roughness's 2 alpha H; 255 = the light's `strength`.
        sx, sy = ceiling.spacing_m
        blur_m = 2.0 * roughness_rad * big_h
        res = min(max(blur_m / 2.0, CEILING_RES_M[0]), CEILING_RES_M[1], min(sx, sy) / 8.0)
        tw, th = max(8, round(sx / res)), max(8, round(sy / res))
        self._res = (sx / tw, sy / th)
        disc = np.zeros((th, tw), np.float32)
        axes = (ceiling.size_m / 2.0 / self._res[0] * 16, ceiling.size_m / 2.0 / self._res[1] * 16)
        cv2.ellipse(disc, (tw * 8, th * 8), (max(1, round(axes[0])), max(1, round(axes[1]))),
                    0.0, 0.0, 360.0, 1.0, -1, cv2.LINE_AA, 4)
        tile = disc
        sigma = blur_m / min(self._res)
        if sigma > 0.3:
            pad = min(int(math.ceil(3 * sigma)), 4 * max(tw, th))
            wrapped = np.pad(disc, pad, mode="wrap")  # the ceiling repeats: blur it so
            tile = np.asarray(cv2.GaussianBlur(wrapped, (0, 0), sigma),
                              np.float32)[pad:pad + th, pad:pad + tw]
        peak = float(tile.max())
        # The ceiling around the camera, as many periods as the mirrored rays reach.
        self._periods = (int(math.ceil(2 * reach / sx)) + 2, int(math.ceil(2 * reach / sy)) + 2)
        self._ceiling = np.ascontiguousarray(np.tile(
            np.rint(255.0 * np.asarray(tile) / max(peak, 1e-9)).astype(np.uint8),
            (self._periods[1], self._periods[0])))
        #: frame levels per ceiling texture level and gloss level, per unit of white floor
        self._strength = ceiling.strength * peak / 255.0 * GLOSS_FULL_SCALE
        self._streak_px = 2.0 * roughness_rad * camera.focal_px
        self._map = np.empty_like(mirror)
        self._light_half = np.empty((h_px // 2, w_px // 2), np.uint8)
        self._light = np.empty((h_px, w_px), np.uint8)
        self._gloss = np.empty((h_px, w_px), np.uint8)

    def draw(self, image: U8, pose: Pose2D, floor_map: F32, gloss: U8,
             scale: float | tuple[float, float, float]) -> None:
        """Add the reflections at `pose` to `image` (frame levels, in place, saturating).
        `floor_map`: the frame's texture coordinates per pixel (the renderer's remap map) and
        `gloss` the gloss layer they index; `scale`: frame levels per unit of white floor (per
        channel for BGR)."""
        cv2.remap(gloss, floor_map, None, cv2.INTER_LINEAR,  # type: ignore[call-overload]
                  dst=self._gloss, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        if not self._gloss.any():
            return
        c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
        rx, ry = self._res
        sx, sy = self.ceiling.spacing_m
        ox, oy = self.ceiling.offset_m
        # The texture's top-left corner: whole periods from a light, the camera in the middle.
        cam_x = pose.x_m + c * self._cam[0] - s * self._cam[1]
        cam_y = pose.y_m + s * self._cam[0] + c * self._cam[1]
        x0 = ox - sx / 2 + (round((cam_x - ox) / sx) - self._periods[0] // 2) * sx
        y1 = oy + sy / 2 + (round((cam_y - oy) / sy) + self._periods[1] // 2) * sy
        # robot frame -> world -> ceiling texture pixels (rows go down in y, like the floor's)
        to_tile = np.array([[c / rx, -s / rx, (pose.x_m - x0) / rx - 0.5],
                            [-s / ry, -c / ry, (y1 - pose.y_m) / ry - 0.5]])
        cv2.transform(self._mirror, to_tile, dst=self._map)
        cv2.remap(self._ceiling, self._map, None, cv2.INTER_LINEAR,  # type: ignore[call-overload]
                  dst=self._light_half, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        if not self._light_half.any():
            return
        cv2.resize(self._light_half, (self._light.shape[1], self._light.shape[0]),
                   dst=self._light, interpolation=cv2.INTER_LINEAR)
        if self._streak_px > 0.5:
            cv2.GaussianBlur(self._light, (1, 0), sigmaX=0.1, sigmaY=self._streak_px,
                             dst=self._light)
        scales = (scale,) if isinstance(scale, float) else scale
        for channel, level in enumerate(scales):
            shine = cv2.multiply(self._light, self._gloss, scale=self._strength * level)
            if image.ndim == 2:
                cv2.add(image, shine, dst=image)
            else:
                plane = np.ascontiguousarray(image[:, :, channel])
                cv2.add(plane, shine, dst=plane)
                image[:, :, channel] = plane
