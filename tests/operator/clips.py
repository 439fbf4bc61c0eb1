"""Camera clips for the operator's tests, rendered by the scenarios package: the `lane-ends`
scenario's world seen by its camera while moving along the lane at a constant speed, towards and
past the end of the tape (the robot's motion is scripted, not controlled: a recorded clip)."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.library import resolve_scenario
from lanewarden.scenarios.render import CameraRenderer
from lanewarden.scenarios.texture import paint_ground
from lanewarden.scenarios.world import build_world

CLIP_SIZE = (320, 240)
CLIP_FPS = 30.0


def lane_end_frames(*, start_m: float, end_m: float, speed_m_s: float = 0.5,
                    fps: float = CLIP_FPS, size: tuple[int, int] = CLIP_SIZE,
                    seed: int = 0) -> list[np.ndarray]:
    """BGR frames from `start_m` to `end_m` along the lane (the tapes end at 3.5 m)."""
    spec = resolve_scenario("lane-ends")
    world = build_world(spec, margin_m=2.5)
    texture = paint_ground(world, 0.004, seed, color=True)
    camera = CameraModel(width_px=size[0], height_px=size[1])
    renderer = CameraRenderer(texture, camera, noise_sigma=2.0, exposure_s=0.0, seed=seed,
                              distorted=False)
    start = world.start_pose
    c, s = math.cos(start.theta_rad), math.sin(start.theta_rad)
    count = int(round((end_m - start_m) / speed_m_s * fps)) + 1
    frames = []
    for i in range(count):
        along = start_m + speed_m_s * i / fps
        pose = Pose2D(start.x_m + along * c, start.y_m + along * s, start.theta_rad)
        out = np.empty((size[1], size[0], 3), np.uint8)
        renderer.render_bgr(pose, out, (speed_m_s, 0.0), renderer.next_noise_index())
        frames.append(out)
    return frames


def write_video(frames: list[np.ndarray], path: Path, fps: float = CLIP_FPS) -> Path:
    """An mp4 (H.264) like a phone or a robot would record."""
    import imageio_ffmpeg

    height, width = frames[0].shape[:2]
    writer = imageio_ffmpeg.write_frames(str(path), (width, height), fps=fps, codec="libx264",
                                         pix_fmt_in="bgr24", pix_fmt_out="yuv420p",
                                         output_params=["-crf", "18", "-preset", "ultrafast"],
                                         ffmpeg_log_level="error", macro_block_size=2)
    writer.send(None)
    for frame in frames:
        writer.send(np.ascontiguousarray(frame))
    writer.close()
    return path


def write_images(frames: list[np.ndarray], folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for i, frame in enumerate(frames):
        cv2.imwrite(str(folder / f"frame_{i}.png"), frame)
    return folder
