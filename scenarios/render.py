"""The synthetic camera: the painted floor as the robot's camera sees it at a given pose.

Per frame: one `cv2.remap` of the ground texture through per-pixel floor coordinates. The floor
point every (distorted) camera pixel looks at, in the robot frame, is fixed (the camera is rigid,
`CameraModel.pixel_ground_points`) and computed once; a pose only moves those points by a 2-D rigid
transform, one `cv2.transform` into a preallocated map. So lens distortion costs
nothing per frame and there is a single interpolation between texture and image. A rolling
shutter moves each row's points by where the moving robot was when the row was read (two
`cv2.scaleAdd` before the transform). Then, with camera effects (`scenarios.camera_effects`, the
simulator's way): the frame's exposure settings, lens blur, motion blur over that shutter time
(a box blur along the image directions that motion smears: sideways for turning, vertically for
driving forward), exposure and vignetting, the ceiling lights' reflections on glossy surfaces
(`scenarios.highlights`), metering, noise through the gain, fringes, compression. Without them
(a bare renderer for geometry and perception tests): motion blur over a fixed shutter time and
seeded noise of one strength (a bank of precomputed noise frames, one picked per frame by a
seeded generator).

Images are uint8, gray (H, W) or BGR (H, W, 3), in the camera's real (distorted) pixel grid, so the
detector must undistort them with the camera's true calibration
(`CameraCalibration(camera.camera_matrix(), camera.distortion(), (w, h))`).

Never reads a clock (a frame's time is the caller's `now`), never touches the robot; allocations
happen in __init__, not per frame (JPEG's buffers are OpenCV's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.camera_effects import CameraEffects
from lanewarden.scenarios.highlights import Highlights
from lanewarden.scenarios.texture import GroundTexture

U8 = NDArray[np.uint8]
F32 = NDArray[np.float32]

#: Floor coordinate given to pixels that look above the horizon (maps outside any texture).
_FAR_M = 1.0e5


@dataclass(frozen=True)
class _FloorGrid:
    """What a camera's pixels see, fixed for the camera: `points` (H, W, 2) float32, the floor
    point (robot frame) of every pixel (far away above the horizon), read-only; and image pixels
    per metre of forward motion near the image centre (for motion blur)."""

    points: F32
    px_per_m_forward: float


@lru_cache(maxsize=8)
def _floor_grid(camera: CameraModel, distorted: bool) -> _FloorGrid:
    """The camera's floor grid, computed once per camera (a campaign's worker renders many runs
    through the same few cameras)."""
    w, h = camera.width_px, camera.height_px
    gx, gy = camera.pixel_ground_points(distorted=distorted)
    sky = ~(np.isfinite(gx) & np.isfinite(gy))
    gx = np.where(sky, _FAR_M, gx)
    gy = np.where(sky, _FAR_M, gy)
    # (H, W, 2) floor points; one cv2.transform per frame turns them into texture coordinates
    # (a 2-channel map that cv2.remap takes directly).
    points = np.ascontiguousarray(np.dstack([gx, gy]), dtype=np.float32)
    points.setflags(write=False)
    centre = np.array([[gx[h // 2, w // 2], 0.0], [gx[h // 2, w // 2] + 0.01, 0.0]])
    px_per_m_forward = 0.0
    if np.all(np.isfinite(centre)):
        px = camera.project_ground(centre)
        px_per_m_forward = float(abs(px[0, 1] - px[1, 1]) / 0.01)
    return _FloorGrid(points, px_per_m_forward)


class CameraRenderer:
    """Renders camera frames of one painted world for one camera.

    With `effects` (`scenarios.camera_effects.CameraEffects`, the simulator's way): the camera's
    exposure, lens and motion blur, rolling shutter, vignetting, noise, fringes and compression
    as that object describes, and `highlights` of the ceiling lights on glossy surfaces; each
    frame's `now` drives the auto-exposure and the light's changes. Without (a bare renderer
    for tests of geometry and perception):

    - `noise_sigma`: sensor noise standard deviation, grey levels (0 disables).
    - `exposure_s`: shutter time used for motion blur (0 disables).
    - `seed`: seeds the noise bank and the per-frame choice from it.

    `distorted`: render the camera's real (distorted) pixel grid; False renders the ideal
    pinhole image instead (what perception sees after undistortion: used for display only).
    """

    def __init__(
        self,
        texture: GroundTexture,
        camera: CameraModel,
        *,
        noise_sigma: float = 2.0,
        exposure_s: float = 0.01,
        seed: int = 0,
        noise_bank_frames: int = 12,
        distorted: bool = True,
        effects: CameraEffects | None = None,
        highlights: Highlights | None = None,
    ) -> None:
        self.texture = texture
        self.camera = camera
        self.effects = effects
        self.highlights = highlights if texture.gloss is not None else None
        self.exposure_s = exposure_s
        w, h = camera.width_px, camera.height_px
        self.size = (w, h)
        grid = _floor_grid(camera, distorted)
        self._ground = grid.points
        self._map = np.empty((h, w, 2), np.float32)
        self._scratch_gray = np.empty((h, w), np.uint8)
        self._scratch_bgr = np.empty((h, w, 3), np.uint8)
        self._px_from_world = texture.px_from_world_matrix()
        # The texture is also kept transposed: remap reads it along the image's rows, which run
        # across the robot's heading; facing along x they run down texture columns (a cache
        # miss per pixel), so then the transposed copy (columns as rows) is read instead.
        self._gray_t = texture.gray_transposed
        self._bgr_t = texture.bgr_transposed
        self._transposed = False
        self._px_per_m_forward = grid.px_per_m_forward
        self._px_per_rad = camera.focal_px
        self._noise_rng = np.random.default_rng([seed, 0xF4A3E])
        self._noise_index: int | None = None
        self._motion_blur = effects.spec.motion_blur if effects is not None else exposure_s > 0
        self._readout_s = 0.0
        self._shear: tuple[F32, F32, F32] | None = None
        if effects is not None and not effects.display and effects.spec.rolling_shutter_s > 0:
            self._readout_s = effects.spec.rolling_shutter_s
            self._shear = _rolling_shutter_fields(self._ground)
        # Noise frames as (add, subtract) pairs, gray and (for a colour texture) BGR.
        self._noise: list[tuple[U8, U8, U8, U8]] = []
        if effects is None and noise_sigma > 0:
            rng = np.random.default_rng([seed, 0x401E])
            for _ in range(max(1, noise_bank_frames)):
                n = np.rint(rng.normal(0.0, noise_sigma, (h, w))).astype(np.int16)
                pos = np.clip(n, 0, 255).astype(np.uint8)
                neg = np.clip(-n, 0, 255).astype(np.uint8)
                pos3, neg3 = pos, neg  # never read: render_bgr needs a colour texture
                if texture.bgr is not None:
                    pos3 = np.ascontiguousarray(np.repeat(pos[:, :, None], 3, axis=2))
                    neg3 = np.ascontiguousarray(np.repeat(neg[:, :, None], 3, axis=2))
                self._noise.append((pos, neg, pos3, neg3))
        self._noise_frames = (len(self._noise) if effects is None
                              else effects.noise_bank_size)

    def _maps(self, pose: Pose2D, velocity: tuple[float, float]) -> None:
        c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
        world_from_robot = np.array([[c, -s, pose.x_m], [s, c, pose.y_m], [0.0, 0.0, 1.0]])
        a = self._px_from_world @ world_from_robot
        self._transposed = abs(c) > abs(s)
        points = self._ground
        linear, angular = velocity
        if self._shear is not None and (linear != 0.0 or angular != 0.0):
            # Rolling shutter: row r is read `delta_r * readout` after mid-frame, when the robot
            # (moving at `velocity`) had moved on: its floor point, in the mid-frame robot frame,
            # is p + delta_r * readout * (angular * (-p_y, p_x) + (linear, 0)).
            turn, advance, work = self._shear
            cv2.scaleAdd(turn, angular * self._readout_s, points, dst=work)
            cv2.scaleAdd(advance, linear * self._readout_s, work, dst=work)
            points = work
        cv2.transform(points, a[1::-1] if self._transposed else a[:2], dst=self._map)

    def _blur_kernel(self, linear_m_s: float, angular_rad_s: float,
                     exposure_s: float) -> tuple[int, int] | None:
        if exposure_s <= 0 or not self._motion_blur:
            return None
        # A point smeared over L pixels during the exposure: a box of about L pixels.
        kx = max(1, int(round(abs(angular_rad_s) * exposure_s * self._px_per_rad)))
        ky = max(1, int(round(abs(linear_m_s) * exposure_s * self._px_per_m_forward)))
        if kx <= 1 and ky <= 1:
            return None
        return (kx, ky)

    def _finish(self, image: U8, scratch: U8, pose: Pose2D, velocity: tuple[float, float],
                noise_index: int | None, now: float | None) -> None:
        effects = self.effects
        if effects is None:
            kernel = self._blur_kernel(*velocity, self.exposure_s)
            if kernel is not None:
                cv2.blur(image, kernel, dst=scratch)
                np.copyto(image, scratch)
            if noise_index is not None and self._noise:
                pos, neg, pos3, neg3 = self._noise[noise_index % len(self._noise)]
                cv2.add(image, pos if image.ndim == 2 else pos3, dst=image)
                cv2.subtract(image, neg if image.ndim == 2 else neg3, dst=image)
            return
        settings = effects.settle(image, now)
        if effects.blur_sigma_px > 0:
            cv2.GaussianBlur(image, (0, 0), effects.blur_sigma_px, dst=image)
        kernel = self._blur_kernel(*velocity, settings.exposure_s)
        if kernel is not None:
            cv2.blur(image, kernel, dst=scratch)
            np.copyto(image, scratch)
        effects.expose(image, settings)
        if self.highlights is not None:
            gloss = self.texture.gloss_transposed if self._transposed else self.texture.gloss
            assert gloss is not None
            self.highlights.draw(image, pose, self._map, gloss,
                                 settings.scale if image.ndim == 2 else settings.scale_bgr())
        effects.meter(image, settings, now)
        effects.develop(image, settings, noise_index)

    def next_noise_index(self) -> int | None:
        """Draw which noise frame the next capture uses (None without noise): never the one the
        previous capture used, as a real sensor never repeats its noise (a robot standing still
        would otherwise see the exact same image twice, which the supervisor takes for a frozen
        camera and does not count towards engaging)."""
        n = self._noise_frames
        if not n:
            return None
        previous = self._noise_index
        if previous is None or n < 2:
            index = int(self._noise_rng.integers(0, n))
        else:
            index = int(self._noise_rng.integers(0, n - 1))
            index += index >= previous
        self._noise_index = index
        return index

    def render_gray(self, pose: Pose2D, out: U8, velocity: tuple[float, float] = (0.0, 0.0),
                    noise_index: int | None = None, now: float | None = None) -> U8:
        """The gray frame at `pose` into `out` (H, W) uint8; `velocity` = (m/s, rad/s); `now`:
        the capture time (drives the effects' exposure and the light; None: a probe frame that
        changes no state)."""
        self._maps(pose, velocity)
        # map2 is None with a 2-channel float map1 (the stubs do not know that form).
        source = self._gray_t if self._transposed else self.texture.gray
        cv2.remap(source, self._map, None, cv2.INTER_LINEAR, dst=out,  # type: ignore[call-overload]
                  borderMode=cv2.BORDER_CONSTANT, borderValue=self.texture.fill_gray)
        self._finish(out, self._scratch_gray, pose, velocity, noise_index, now)
        return out

    def render_bgr(self, pose: Pose2D, out: U8, velocity: tuple[float, float] = (0.0, 0.0),
                   noise_index: int | None = None, now: float | None = None) -> U8:
        """The colour frame at `pose` into `out` (H, W, 3) uint8 (needs a colour texture)."""
        if self.texture.bgr is None:
            raise ValueError("render_bgr needs a texture painted with color=True")
        self._maps(pose, velocity)
        fill = self.texture.fill_bgr
        source = self._bgr_t if self._transposed and self._bgr_t is not None else self.texture.bgr
        cv2.remap(source, self._map, None, cv2.INTER_LINEAR, dst=out,  # type: ignore[call-overload]
                  borderMode=cv2.BORDER_CONSTANT, borderValue=(fill[0], fill[1], fill[2], 0))
        self._finish(out, self._scratch_bgr, pose, velocity, noise_index, now)
        return out


def _rolling_shutter_fields(points: F32) -> tuple[F32, F32, F32]:
    """For a floor grid (H, W, 2): each pixel's row time from mid-frame as a fraction of the
    readout (-0.5 top .. 0.5 bottom) times (-p_y, p_x) (a turn) and times (1, 0) (driving
    forward), zero above the horizon; and a work buffer."""
    h = points.shape[0]
    delta = (np.arange(h, dtype=np.float32) / max(h - 1, 1) - 0.5)[:, None]
    floor = np.abs(points[:, :, 0]) < _FAR_M / 2
    turn = np.zeros_like(points)
    turn[:, :, 0] = np.where(floor, -points[:, :, 1] * delta, 0.0)
    turn[:, :, 1] = np.where(floor, points[:, :, 0] * delta, 0.0)
    advance = np.zeros_like(points)
    advance[:, :, 0] = np.where(floor, delta, 0.0)
    return turn, advance, np.empty_like(points)
