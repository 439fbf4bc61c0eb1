"""The `simulation:` section of the one validated config: the synthetic camera, the floor texture,
the simulated run's outputs. Every default lives here, with units in the names.

The camera's geometry (height, pitch, field of view, distortion) is `scenarios.camera.CameraModel`'s
defaults, which perception is tuned against; only the resolution is chosen here (the focal length
scales with it). This module only declares numbers: it never renders or runs anything.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

_FROZEN = ConfigDict(extra="forbid", frozen=True)


class VideoConfig(BaseModel):
    """`simulation.video`: the run's video.mp4 (camera view with the perception overlay beside a
    top-down map, H.264 yuv420p so browsers play it).

    - `fps`: frames written per second of simulated time (the camera runs at `camera_rate_hz`;
      every k-th frame is written so the video plays in real time).
    - `map_size_px`: the top-down map panel is this many pixels square; the camera panel is scaled
      to the same height.
    - `crf` / `preset`: x264 quality (lower = better, bigger) and speed.
    """

    model_config = _FROZEN

    fps: Annotated[float, Field(gt=0.0, le=60.0)] = 15.0
    map_size_px: Annotated[int, Field(ge=160, le=1440, multiple_of=16)] = 480
    crf: Annotated[int, Field(ge=0, le=51)] = 28
    preset: Literal[
        "ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow"
    ] = "ultrafast"


class SimulationConfig(BaseModel):
    """`simulation:` the synthetic camera and the simulated run.

    - `camera_rate_hz`: camera frames per second; the control loop steps once per frame.
    - `width_px` / `height_px`: camera resolution (640x480 default; 320x240 scales the focal
      length with it).
    - `texture_mm_per_px`: resolution of the painted floor (finer is sharper and slower to paint).
    - `world_margin_m`: floor painted beyond the lane on every side.
    - `noise_sigma_levels`: sensor noise, standard deviation in grey levels (0: none).
    - `noise_bank_frames`: precomputed noise frames one of which is drawn per frame.
    - `exposure_s`: shutter time for motion blur (0: none).
    - `perception_color`: give perception the colour frame (else the gray one, which is what it
      computes first anyway; gray rendering is ~2x faster).
    - `progress`: show a progress bar on stderr (only when stderr is a terminal).
    """

    model_config = _FROZEN

    camera_rate_hz: Annotated[float, Field(gt=1.0, le=120.0)] = 30.0
    width_px: Annotated[int, Field(ge=64, le=1920)] = 640
    height_px: Annotated[int, Field(ge=48, le=1440)] = 480
    texture_mm_per_px: Annotated[float, Field(ge=1.0, le=10.0)] = 2.5
    world_margin_m: Annotated[float, Field(ge=1.0, le=10.0)] = 2.5
    noise_sigma_levels: Annotated[float, Field(ge=0.0, le=40.0)] = 2.0
    noise_bank_frames: Annotated[int, Field(ge=1, le=64)] = 12
    exposure_s: Annotated[float, Field(ge=0.0, le=0.1)] = 0.01
    perception_color: bool = False
    progress: bool = True
    video: VideoConfig = VideoConfig()

    @model_validator(mode="after")
    def _even(self) -> SimulationConfig:
        if self.width_px % 2 or self.height_px % 2:
            raise ValueError(
                f"width_px and height_px must be even (got {self.width_px}x{self.height_px}): "
                "the video is encoded as yuv420p"
            )
        return self
