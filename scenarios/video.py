"""The run's video: the camera view with perception's overlay beside a top-down map of the run.

The map shows the painted floor (tapes, seams), the turn gates (A, B, ...), the end of the
markings (a red bar), the robot (its 0.35 m footprint, heading and the floor its camera's ROI
covers) and the path so far, coloured by the supervisor's state. Frames are encoded to H.264
yuv420p through `imageio_ffmpeg.write_frames` (browsers play it; OpenCV's wheels cannot encode
H.264), with the ffmpeg binary that package ships.

Drawing only: never steps the loop, never reads a clock; buffers are allocated once.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.errors import ScenarioOutputError
from lanewarden.scenarios.texture import GroundTexture
from lanewarden.scenarios.world import ROBOT_RADIUS_M, World

U8 = NDArray[np.uint8]
FloatArray = NDArray[np.float64]

#: Path colour per supervisor state (BGR); anything else is grey.
STATE_COLORS: dict[str, tuple[int, int, int]] = {
    "FOLLOW": (60, 200, 60),
    "TURN_LEFT": (230, 180, 40),
    "TURN_RIGHT": (200, 90, 220),
    "DEGRADED": (0, 165, 255),
    "HALT": (40, 40, 230),
}
_GREY = (150, 150, 150)


def state_color(state: str) -> tuple[int, int, int]:
    return STATE_COLORS.get(state, _GREY)


def roi_ground_outline(camera: CameraModel, roi_polygon_px: FloatArray) -> FloatArray:
    """The floor (robot frame, metres) the ROI covers: the ROI polygon clipped to the image,
    back-projected through the (undistorted) camera. (K, 2)."""
    w, h = camera.width_px, camera.height_px
    image = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float32)
    roi = np.asarray(roi_polygon_px, np.float32).reshape(-1, 2)
    area, clipped = cv2.intersectConvexConvex(image, roi)
    if area <= 0 or clipped is None:
        return np.zeros((0, 2))
    pts = clipped.reshape(-1, 2).astype(np.float64)
    h_inv = np.linalg.inv(camera.ground_to_image_homography())
    hom = np.column_stack([pts, np.ones(len(pts))]) @ h_inv.T
    ok = hom[:, 2] > 1e-9
    return hom[ok, :2] / hom[ok, 2:3]


class MapView:
    """A square top-down map of the lane, `size_px` wide, with the path drawn as it grows."""

    def __init__(self, world: World, texture: GroundTexture, size_px: int,
                 roi_outline_robot: FloatArray | None = None) -> None:
        pts = world.centreline.points
        pad = world.lane_width_m / 2.0 + 0.8
        x0, x1 = pts[:, 0].min() - pad, pts[:, 0].max() + pad
        y0, y1 = pts[:, 1].min() - pad, pts[:, 1].max() + pad
        span = max(x1 - x0, y1 - y0)
        cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
        self.size = size_px
        self.m_per_px = span / size_px
        self.x_min = cx - span / 2.0
        self.y_max = cy + span / 2.0
        self._roi = roi_outline_robot if roi_outline_robot is not None else np.zeros((0, 2))
        self.background = self._paint_background(world, texture)
        self._canvas = self.background.copy()
        self._frame = np.empty_like(self.background)
        self._last: tuple[int, int] | None = None

    def to_px(self, x: float, y: float) -> tuple[int, int]:
        return (round((x - self.x_min) / self.m_per_px), round((self.y_max - y) / self.m_per_px))

    def _paint_background(self, world: World, texture: GroundTexture) -> U8:
        source = texture.bgr if texture.bgr is not None else cv2.cvtColor(
            texture.gray, cv2.COLOR_GRAY2BGR)
        # Shrink the texture by an integer factor first (area averaging), then one affine warp
        # from map pixels to (shrunk) texture pixels.
        factor = max(1, int(self.m_per_px / texture.m_per_px))
        if factor > 1:
            size = (source.shape[1] // factor, source.shape[0] // factor)
            source = cv2.resize(source[: size[1] * factor, : size[0] * factor], size,
                                interpolation=cv2.INTER_AREA)
        res = texture.m_per_px * factor
        scale = self.m_per_px / res
        col0 = (self.x_min - texture.x_min) / res + 0.5 * scale - 0.5
        row0 = (texture.y_max - self.y_max) / res + 0.5 * scale - 0.5
        m = np.array([[scale, 0.0, col0], [0.0, scale, row0]])
        bg = cv2.warpAffine(source, m, (self.size, self.size),
                            flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                            borderMode=cv2.BORDER_REFLECT)
        bg = cv2.addWeighted(bg, 0.75, np.full_like(bg, 255), 0.25, 0.0)
        for name in world.marks:
            a, b = world.gate(name)
            pa, pb = self.to_px(*a), self.to_px(*b)
            cv2.line(bg, pa, pb, (0, 140, 0), 1, cv2.LINE_AA)
            cv2.putText(bg, name, (pb[0] + 4, pb[1] - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.6,
                        (0, 110, 0), 2, cv2.LINE_AA)
        end = world.lane_end()
        if end is not None:
            point, heading = end
            nx, ny = -math.sin(heading), math.cos(heading)
            half = world.lane_width_m / 2.0 + 0.1
            pa = self.to_px(point[0] - half * nx, point[1] - half * ny)
            pb = self.to_px(point[0] + half * nx, point[1] + half * ny)
            cv2.line(bg, pa, pb, (0, 0, 220), 2, cv2.LINE_AA)
        return np.ascontiguousarray(bg)

    def add_path_point(self, pose: Pose2D, state: str) -> None:
        p = self.to_px(pose.x_m, pose.y_m)
        if self._last is not None and self._last != p:
            cv2.line(self._canvas, self._last, p, state_color(state), 2, cv2.LINE_AA)
        self._last = p

    def draw(self, pose: Pose2D, state: str) -> U8:
        np.copyto(self._frame, self._canvas)
        c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
        if len(self._roi):
            wx = pose.x_m + c * self._roi[:, 0] - s * self._roi[:, 1]
            wy = pose.y_m + s * self._roi[:, 0] + c * self._roi[:, 1]
            poly = np.array([self.to_px(x, y) for x, y in zip(wx, wy, strict=True)], np.int32)
            cv2.polylines(self._frame, [poly], True, (255, 200, 0), 1, cv2.LINE_AA)
        centre = self.to_px(pose.x_m, pose.y_m)
        radius = max(2, round(ROBOT_RADIUS_M / self.m_per_px))
        cv2.circle(self._frame, centre, radius, state_color(state), 2, cv2.LINE_AA)
        nose = self.to_px(pose.x_m + ROBOT_RADIUS_M * c, pose.y_m + ROBOT_RADIUS_M * s)
        cv2.line(self._frame, centre, nose, state_color(state), 2, cv2.LINE_AA)
        return self._frame


def _put_lines(image: U8, lines: list[str], origin: tuple[int, int], scale: float) -> None:
    """White text on a darkened band (one text pass: OpenCV's glyph advance depends on the
    thickness, so an outline pass would not line up)."""
    x, y = origin
    step = round(22 * scale)
    top = max(0, y - step + 4)
    bottom = min(image.shape[0], y + step * (len(lines) - 1) + 8)
    band = image[top:bottom]
    cv2.addWeighted(band, 0.45, np.zeros_like(band), 0.55, 0.0, dst=band)
    for text in lines:
        cv2.putText(image, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, 0.55 * scale,
                    (255, 255, 255), 1, cv2.LINE_AA)
        y += step


class VideoRecorder:
    """Composes [camera | map] frames and streams them to an H.264 mp4."""

    def __init__(self, path: Path, camera_size: tuple[int, int], map_view: MapView,
                 fps: float, crf: int, preset: str) -> None:
        import imageio_ffmpeg

        self.path = path
        height = map_view.size
        cam_w, cam_h = camera_size
        panel_w = int(round(cam_w * height / cam_h / 2.0)) * 2
        self._panel_size = (panel_w, height)
        self._map = map_view
        self._frame = np.zeros((height, panel_w + height, 3), np.uint8)
        self._writer: Generator[Any, Any, None] | None = None
        try:
            writer = imageio_ffmpeg.write_frames(
                str(path), (panel_w + height, height), fps=fps, codec="libx264",
                pix_fmt_in="bgr24", pix_fmt_out="yuv420p", macro_block_size=2,
                output_params=["-preset", preset, "-crf", str(crf), "-movflags", "+faststart"],
                ffmpeg_log_level="error",
            )
            writer.send(None)
        except (OSError, RuntimeError) as exc:
            raise ScenarioOutputError(f"{path}: cannot start the video encoder ({exc})") from exc
        self._writer = writer
        self.frames = 0

    def add(self, camera_bgr: U8, pose: Pose2D, state: str, lines: list[str]) -> None:
        panel_w, height = self._panel_size
        panel = self._frame[:, :panel_w]
        if camera_bgr.shape[1] == panel_w and camera_bgr.shape[0] == height:
            np.copyto(panel, camera_bgr)
        else:
            cv2.resize(camera_bgr, (panel_w, height), dst=panel, interpolation=cv2.INTER_LINEAR)
        map_panel = self._frame[:, panel_w:]
        np.copyto(map_panel, self._map.draw(pose, state))
        scale = height / 480.0
        _put_lines(map_panel, lines, (8, height - round(22 * scale) * len(lines) + 8), scale)
        assert self._writer is not None
        try:
            self._writer.send(self._frame)
        except (OSError, RuntimeError) as exc:
            raise ScenarioOutputError(f"{self.path}: video encoding failed ({exc})") from exc
        self.frames += 1

    def close(self) -> None:
        if self._writer is not None:
            writer, self._writer = self._writer, None
            try:
                writer.close()
            except (OSError, RuntimeError) as exc:
                raise ScenarioOutputError(f"{self.path}: video encoding failed ({exc})") from exc
