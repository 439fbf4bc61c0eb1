"""The run's video: the camera view with perception's overlay beside a top-down map of the run,
under a caption band with what perception and the controller said at that moment.

The map shows the painted floor (tapes, seams), the turn gates (A, B, ...), the end of the
markings (a red bar), the robot (its 0.35 m footprint, heading and the floor its camera's ROI
covers) and the path so far, coloured by the controller's state. Every colour drawn is a row of
`video_legend()` (the report prints it). The caption names the state with its reason (HALT:
LANE_LOST, DEGRADED (LANE_UNTRUSTED)). Frames are encoded to H.264 yuv420p through
`imageio_ffmpeg.write_frames` (browsers play it; OpenCV's wheels cannot encode H.264), with the
ffmpeg binary that package ships. The poster (`poster.jpg`) is the outcome: the first frame of
the HALT the video ends in, after the controller engaged (a halt it was resumed from is not the
outcome), else the last frame.

Drawing only: never steps the loop, never reads a clock; buffers are allocated once.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Generator, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D
from lanewarden.perception.observation import LaneObservation
from lanewarden.perception.overlay import (
    BGR,
    OVERLAY_STYLES,
    OverlayStyle,
    line_step_px,
    perception_text,
    put_text_lines,
    text_scale,
)
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.encoder_pipe import (
    FFMPEG_LOG_LEVEL,
    close_encoder,
    encoder_failure,
    encoder_process,
    ffmpeg_output,
    send_whole,
)
from lanewarden.scenarios.errors import ScenarioOutputError
from lanewarden.scenarios.state_reasons import StateReasons, state_with_reason
from lanewarden.scenarios.texture import GroundTexture
from lanewarden.scenarios.world import ROBOT_RADIUS_M, World
from lanewarden.supervisor.loop import StepRecord

U8 = NDArray[np.uint8]
FloatArray = NDArray[np.float64]

#: Path colour per controller state (BGR); anything else is grey.
STATE_COLORS: dict[str, BGR] = {
    "FOLLOW": (60, 200, 60),
    "TURN_LEFT": (230, 180, 40),
    "TURN_RIGHT": (200, 90, 220),
    "DEGRADED": (0, 165, 255),
    "HALT": (40, 40, 230),
}
_GREY: BGR = (150, 150, 150)
_STATE_MEANINGS = {
    "FOLLOW": "following the lane (the lecture's controller: going straight)",
    "TURN_LEFT": "turning left",
    "TURN_RIGHT": "turning right",
    "DEGRADED": "slower, bounded steering (reason shown in the caption)",
    "HALT": "stopped (reason shown in the caption)",
}

#: Every colour the map draws apart from the state colours.
MAP_STYLES: dict[str, OverlayStyle] = {
    "gate": OverlayStyle((0, 140, 0), "turn gate A, B, ...",
                         "a line across the lane at the end of a marked turn; crossing it "
                         "counts the turn as completed"),
    "lane_end": OverlayStyle((0, 0, 220), "end of the tape",
                             "where the markings end (the earlier tape end)"),
    "roi": OverlayStyle(OVERLAY_STYLES["roi"].bgr, "ROI on the floor",
                        "the floor perception's region of interest covers, at the robot's pose"),
}
_CAPTION_BG: BGR = (32, 32, 32)
_CAPTION_HEAD: BGR = (190, 190, 190)
#: Caption lines per panel.
CAPTION_LINES = 4


def state_color(state: str) -> BGR:
    return STATE_COLORS.get(state, _GREY)


def video_legend() -> list[tuple[str, list[OverlayStyle]]]:
    """Every colour in the video, grouped by where it appears: (group title, rows)."""
    states = [OverlayStyle(bgr, state, _STATE_MEANINGS.get(state, ""))
              for state, bgr in STATE_COLORS.items()]
    return [
        ("camera view (left): what perception saw", list(OVERLAY_STYLES.values())),
        ("map (right): the course", list(MAP_STYLES.values())),
        ("map: the path so far and the robot (a disc 0.35 m across, with its heading) are "
         "coloured by the controller's state", states),
    ]


def caption_cap_height_px(map_size_px: int) -> float:
    """Capital-letter height of the caption text: 14 px for a 480 px map."""
    return map_size_px / 34.0


def caption_height_px(map_size_px: int) -> int:
    """Height of the caption band (even, for yuv420p)."""
    cap = caption_cap_height_px(map_size_px)
    height = line_step_px(cap) * CAPTION_LINES + round(cap)
    return height + height % 2


#: Map sizes a run video can have (`simulation.video.map_size_px`: 160..1440, multiple of 16).
_MAP_SIZES = range(160, 1441, 16)
#: A caption band is this share of pixels within `_BAND_TOLERANCE` grey levels of its colour.
_BAND_SHARE = 0.7
_BAND_TOLERANCE = 12
#: ... and the 2-pixel black line between the panels stays darker than this (after H.264).
_DIVIDER_MAX = 16


def run_video_layout(image: U8) -> tuple[int, int] | None:
    """(camera panel width, map size) when `image` is a frame of a run video (`VideoRecorder`:
    the caption band on top of [camera view | map], as `sim`, `demo` and `replay` write), else
    None. Its size must be one this layout gives, its top band mostly the caption's colour and
    the divider between the panels dark: a camera's own frame is none of these."""
    if image.ndim != 3 or image.shape[2] != 3:
        return None
    height, width = image.shape[:2]
    for size in _MAP_SIZES:
        band = caption_height_px(size)
        panel_w = width - size
        if size + band != height or panel_w < 2:
            continue
        top = image[:band].astype(np.int16)
        share = float(np.mean(np.all(np.abs(top - np.int16(_CAPTION_BG[0])) <= _BAND_TOLERANCE,
                                     axis=2)))
        divider = float(image[band:, max(0, panel_w - 1):panel_w + 1].mean())
        if share >= _BAND_SHARE and divider < _DIVIDER_MAX:
            return panel_w, size
    return None


#: A caption's capitals are never drawn smaller than this (px): below, a line is shortened.
MIN_CAPTION_CAP_PX = 9.0


def _text_width_px(text: str, cap_height_px: float) -> int:
    """Width of `text` as `put_text_lines` draws it (its font; the thicker stroke it may use)."""
    (width, _), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, text_scale(cap_height_px), 2)
    return int(width)


def fit_caption(lines: Sequence[str | tuple[str, BGR]], width_px: int,
                cap_height_px: float) -> tuple[list[str | tuple[str, BGR]], float]:
    """The caption lines and cap height that fit `width_px`: the text shrinks (down to
    MIN_CAPTION_CAP_PX) until its widest line fits, then a line still too long is cut and ends
    in '...'. Nothing is drawn past the panel's edge."""
    texts = [line if isinstance(line, str) else line[0] for line in lines]
    widest = max((_text_width_px(t, cap_height_px) for t in texts), default=0)
    cap = cap_height_px
    if widest > width_px:
        cap = max(MIN_CAPTION_CAP_PX, cap_height_px * width_px / widest)
    fitted: list[str | tuple[str, BGR]] = []
    for line, text in zip(lines, texts, strict=True):
        short = text
        while len(short) > 1 and _text_width_px(short, cap) > width_px:
            short = short[:-4].rstrip() + "..."
        fitted.append(short if isinstance(line, str) else (short, line[1]))
    return fitted, cap


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
            cv2.line(bg, pa, pb, MAP_STYLES["gate"].bgr, 2, cv2.LINE_AA)
            cv2.putText(bg, name, (pb[0] + 4, pb[1] - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.7,
                        MAP_STYLES["gate"].bgr, 2, cv2.LINE_AA)
        end = world.lane_end()
        if end is not None:
            point, heading = end
            nx, ny = -math.sin(heading), math.cos(heading)
            half = world.lane_width_m / 2.0 + 0.1
            pa = self.to_px(point[0] - half * nx, point[1] - half * ny)
            pb = self.to_px(point[0] + half * nx, point[1] + half * ny)
            cv2.line(bg, pa, pb, MAP_STYLES["lane_end"].bgr, 3, cv2.LINE_AA)
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
            cv2.polylines(self._frame, [poly], True, MAP_STYLES["roi"].bgr, 1, cv2.LINE_AA)
        centre = self.to_px(pose.x_m, pose.y_m)
        radius = max(2, round(ROBOT_RADIUS_M / self.m_per_px))
        cv2.circle(self._frame, centre, radius, state_color(state), 2, cv2.LINE_AA)
        nose = self.to_px(pose.x_m + ROBOT_RADIUS_M * c, pose.y_m + ROBOT_RADIUS_M * s)
        cv2.line(self._frame, centre, nose, state_color(state), 2, cv2.LINE_AA)
        return self._frame


def perception_caption(detection: tuple[LaneObservation, str] | None) -> list[str]:
    """The camera panel's caption: perception's view of this frame (observation, decision)."""
    if detection is None:
        return ["PERCEPTION", "no new observation at this step"]
    observation, decision = detection
    return ["PERCEPTION (this frame alone)", *perception_text(observation, decision)]


def controller_caption(title: str, now: float, record: StepRecord,
                       reason: str | None) -> list[str | tuple[str, BGR]]:
    """The map panel's caption: the controller's view (state with its reason, what it acted on,
    whether it trusts the lane, the command sent)."""
    acted = record.filtered_slope_sum
    trusted = getattr(record, "lane_trusted", None)  # per-step supervisor verdict, when recorded
    trust = "" if trusted is None else ("  lane trusted" if trusted else "  lane NOT trusted")
    cmd = record.command
    return [
        (f"t = {now:.1f} s  {title}", _CAPTION_HEAD),  # the time first: a long title is cut
        (state_with_reason(record.state, reason), state_color(record.state)),
        f"acted on slope sum {'-' if acted is None else f'{acted:+.2f}'}{trust}",
        f"command v {cmd.linear_m_s:.2f} m/s  w {cmd.angular_rad_s:+.2f} rad/s",
    ]


class VideoRecorder:
    """Composes [camera | map] frames under a caption band and streams them to an H.264 mp4
    (the caption is on top: a browser's video controls cover the bottom of a paused video).

    Call `step` on every control step (the path and the state's reason need every step) and
    `add` for the steps that become video frames; `close` writes `poster.jpg` beside the video.
    """

    def __init__(self, path: Path, camera_size: tuple[int, int], map_view: MapView,
                 fps: float, crf: int, preset: str, title: str = "") -> None:
        import imageio_ffmpeg

        self.path = path
        self.poster_path = path.with_name("poster.jpg")
        self.title = title
        size = map_view.size
        cam_w, cam_h = camera_size
        panel_w = int(round(cam_w * size / cam_h / 2.0)) * 2
        self._panel_size = (panel_w, size)
        self._caption_h = caption_height_px(size)
        self._map = map_view
        self._frame = np.zeros((size + self._caption_h, panel_w + size, 3), np.uint8)
        self._reasons = StateReasons()
        self._reason: str | None = None
        self._engaged = False
        self._poster: U8 | None = None
        #: What the poster shows ("the halt" or "the last frame") and its time, after close().
        self.poster_shows: str | None = None
        self.poster_time_s: float | None = None
        self._last_time_s: float | None = None
        self._writer: Generator[Any, Any, None] | None = None
        height, width = self._frame.shape[:2]
        # Its only warning ("no frames written", on an interrupt before the first frame) would be
        # a second line beside ours; PARTIAL already says the video is incomplete.
        logging.getLogger("imageio_ffmpeg").setLevel(logging.ERROR)
        try:
            writer = imageio_ffmpeg.write_frames(
                ffmpeg_output(path), (width, height), fps=fps, codec="libx264",
                pix_fmt_in="bgr24", pix_fmt_out="yuv420p", macro_block_size=2,
                output_params=["-preset", preset, "-crf", str(crf), "-movflags", "+faststart"],
                ffmpeg_log_level=FFMPEG_LOG_LEVEL,
            )
            writer.send(None)
        except (OSError, RuntimeError) as exc:
            raise ScenarioOutputError(f"{path}: cannot start the video encoder ({exc})") from exc
        self._writer = writer
        self._process = encoder_process(writer)
        self.frames = 0

    @property
    def frame_size(self) -> tuple[int, int]:
        """(width, height) of the video."""
        return self._frame.shape[1], self._frame.shape[0]

    def step(self, pose: Pose2D, record: StepRecord) -> None:
        """Every control step: extend the path, follow the state's reason."""
        self._map.add_path_point(pose, record.state)
        self._reason = self._reasons.update(record.state, record.events, record.halt_reason)

    def add(self, camera_bgr: U8, pose: Pose2D, now: float, record: StepRecord,
            detection: tuple[LaneObservation, str] | None) -> None:
        """One video frame: `camera_bgr` (overlay already drawn), the map, the captions."""
        panel_w, size = self._panel_size
        top = self._caption_h
        panel = self._frame[top:, :panel_w]
        if camera_bgr.shape[1] == panel_w and camera_bgr.shape[0] == size:
            np.copyto(panel, camera_bgr)
        else:
            cv2.resize(camera_bgr, (panel_w, size), dst=panel, interpolation=cv2.INTER_LINEAR)
        np.copyto(self._frame[top:, panel_w:], self._map.draw(pose, record.state))
        band = self._frame[:top]
        band[:] = _CAPTION_BG
        cap = caption_cap_height_px(size)
        first = line_step_px(cap)
        margin = round(cap * 0.7)
        for area, lines in ((band[:, :panel_w], perception_caption(detection)),
                            (band[:, panel_w:],
                             controller_caption(self.title, now, record, self._reason))):
            fitted, fitted_cap = fit_caption(lines, area.shape[1] - 2 * margin, cap)
            put_text_lines(area, fitted, (margin, first), fitted_cap, shade=False)
        cv2.line(self._frame, (panel_w, 0), (panel_w, self._frame.shape[0] - 1), (0, 0, 0), 2)
        assert self._writer is not None
        try:
            send_whole(self._writer, self._frame)
        except (OSError, RuntimeError) as exc:
            self._writer = None  # ffmpeg is gone: close() has nothing more to say
            raise ScenarioOutputError(f"{self.path}: video encoding failed "
                                      f"({encoder_failure(self._process, exc)})") from exc
        self.frames += 1
        self._last_time_s = now
        if record.state != "HALT":
            self._engaged = True
            if self.poster_shows is not None:  # engaged again (a resume): that halt was not
                # the outcome (a replay's poster had shown an operator's stop long before the
                # halt that ended the run)
                self._poster, self.poster_shows, self.poster_time_s = None, None, None
        elif self._engaged and self.poster_shows is None:
            self._poster = self._frame.copy()
            self.poster_shows, self.poster_time_s = "the halt", now

    def close(self) -> None:
        """Finish the video and write the poster (the halt frame, else the last frame)."""
        if self._writer is None:
            return
        writer, self._writer = self._writer, None
        # before the poster: a video ffmpeg could not finish is the failure, not the poster
        failed = close_encoder(writer, self._process, self.path, self.frames)
        if failed is not None:
            raise ScenarioOutputError(f"{self.path}: video encoding failed ({failed})")
        if self.frames == 0:
            return
        if self._poster is None:
            self._poster = self._frame
            self.poster_shows, self.poster_time_s = "the last frame", self._last_time_s
        # encoded here and written by Python, so a failed write says why (a full disk had given
        # "cannot write the video poster" and no reason)
        encoded, data = cv2.imencode(".jpg", self._poster, [cv2.IMWRITE_JPEG_QUALITY, 90])
        try:
            if not encoded:
                raise OSError("the frame could not be encoded as JPEG")
            self.poster_path.write_bytes(data.tobytes())
        except OSError as exc:
            raise ScenarioOutputError(f"{self.poster_path}: cannot write the video poster "
                                      f"({exc.strerror or exc})") from exc

