"""The `simulation:` section of the one validated config: the synthetic camera, the floor texture,
the simulated run's outputs. Every default lives here, with units in the names.

The camera's geometry (height, pitch, field of view, distortion) is `scenarios.camera.CameraModel`'s
defaults, which perception is tuned against; only the resolution is chosen here (the focal length
scales with it). This module only declares numbers: it never renders or runs anything.
"""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field, model_validator

from lanewarden.documents import DocumentModel

_FROZEN = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class VideoConfig(DocumentModel):
    """`simulation.video`: the run's video.mp4 (camera view with the perception overlay beside a
    top-down map, H.264 yuv420p so browsers play it)."""

    model_config = _FROZEN

    fps: float = Field(
        default=15.0, gt=0.0, le=60.0,
        description="video frames per second of simulated time (every k-th camera frame is "
        "written, so the video plays in real time)",
    )
    map_size_px: int = Field(
        default=480, ge=160, le=1440, multiple_of=16,
        description="the top-down map panel is this many pixels square; the camera panel is "
        "scaled to the same height",
    )
    crf: int = Field(default=28, ge=0, le=51, description="x264 quality (lower: better and bigger)")
    preset: Literal[
        "ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow"
    ] = Field(default="ultrafast", description="x264 speed preset")


class SimulationConfig(DocumentModel):
    """`simulation:` the synthetic camera and the simulated run."""

    model_config = _FROZEN

    camera_rate_hz: float = Field(
        default=30.0, gt=1.0, le=120.0,
        description="camera frames per second; the control loop steps once per frame",
    )
    width_px: int = Field(
        default=640, ge=64, le=1920,
        description="camera image width (the focal length scales with it)",
    )
    height_px: int = Field(default=480, ge=48, le=1440, description="camera image height")
    rectified_frames: bool = Field(
        default=False,
        description="the simulated camera delivers rectified frames (no lens distortion, as from "
        "a driver that rectifies, e.g. ROS image_proc): the floor is rendered straight into the "
        "pinhole image and perception's calibration has no distortion, so perception skips its "
        "undistortion remap (one remap per frame instead of two, ~15% less CPU at 320x240; "
        "its frames are sharper than the lens path's: see docs/campaigns.md)",
    )
    texture_mm_per_px: float = Field(
        default=2.5, ge=1.0, le=10.0,
        description="resolution of the painted floor (finer: sharper and slower to paint)",
    )
    world_margin_m: float = Field(
        default=2.5, ge=1.0, le=10.0, description="floor painted beyond the lane on every side"
    )
    noise_bank_frames: int = Field(
        default=12, ge=2, le=64,
        description="precomputed unit-noise frames, one drawn (seeded) per frame, never the "
        "previous frame's (a real sensor never repeats its noise; each capture is also marked "
        "with its count, as the supervisor does not count an image identical to one of its "
        "last 16); the noise's strength is the camera's: the scenario's camera.sensor",
    )
    perception_color: bool = Field(
        default=False,
        description="give perception colour frames (default: gray, which it computes first "
        "anyway; gray rendering is about 2x faster); always on with perception.gray.yellow_boost",
    )
    progress: bool = Field(
        default=True, description="show progress on stderr (a bar on a terminal, else a line "
        "every few seconds)"
    )
    video: VideoConfig = Field(default=VideoConfig(), description="the run's video.mp4")

    @model_validator(mode="after")
    def _even(self) -> SimulationConfig:
        if self.width_px % 2 or self.height_px % 2:
            raise ValueError(
                f"width_px and height_px must be even (got {self.width_px}x{self.height_px}): "
                "the video is encoded as yuv420p"
            )
        return self
