"""What a real camera does to the light between the floor and the frame: sensor, exposure, ISP.

A `CameraEffects` belongs to one run of one camera (`scenarios.spec.CameraSpec`'s `sensor`,
`exposure`, `white_balance`, `optics` and `compression`, and the room's light,
`LightingSpec`). It precomputes what the camera fixes (the vignetting map, a seeded bank of
unit-noise frames, the chromatic-aberration maps, the lens blur) and keeps the state a real
camera keeps between frames: the auto-exposure's exposure and the white balance's gains, which
follow a change of light with their time constants. Per frame the renderer calls:

    settings = effects.settle(image, now)   # the settings THIS frame is taken with (what the
                                            # frames before it asked for)
    ... lens blur (`blur_sigma_px`), motion blur over `settings.exposure_s` ...
    effects.expose(image, settings)         # vignetting, light x exposure x gain (saturating),
                                            # white balance
    ... highlights of the ceiling lights (`scenarios.highlights`), in frame levels ...
    effects.meter(image, settings, now)     # auto-exposure and white balance, for later frames
    effects.develop(image, settings, noise_index)
        # shot and read noise (grows with the gain), chromatic fringes, JPEG compression

The rendered scene (the painted floor remapped into the camera) is in units where a 10 ms
exposure at gain 1 under brightness 1 shows it as painted (`REFERENCE_EXPOSURE_S`). Values are
treated as linear in light (no gamma curve).

Never reads a clock (time is the frame's `now`), never renders geometry; every random draw is
seeded; buffers are allocated in __init__ (JPEG's encode buffer is OpenCV's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.detector import GRAY_WEIGHTS_BGR
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.spec import CameraSpec, LightingSpec, color_bgr

U8 = NDArray[np.uint8]
F32 = NDArray[np.float32]

#: At brightness 1, this exposure at gain 1 shows the floor as painted.
REFERENCE_EXPOSURE_S = 0.01
#: The camera's luma (Rec. 601, OpenCV's BGR -> gray), what its auto-exposure meters in colour.
_LUMA = (0.114, 0.587, 0.299)
#: Gray frames are perception's gray (`perception.detector.perception_gray`), so the light and
#: the fringes act on them through its weights (a gray frame's auto-exposure meters it too; the
#: same as `_LUMA` while perception's gray is BGR2GRAY).
_GRAY = GRAY_WEIGHTS_BGR
#: Below this blur (1 sigma, pixels) the lens is left sharp: the renderer's interpolation blurs
#: as much.
MIN_BLUR_SIGMA_PX = 0.3
#: Chromatic fringes smaller than this at the corners (pixels) are left out of gray frames.
MIN_FRINGE_GRAY_PX = 0.5
#: The noise after demosaicing is correlated over about a pixel: the bank is blurred this much.
NOISE_CORRELATION_PX = 0.5
#: The auto-exposure meters every this-many-th pixel along each axis.
_METER_STEP = 4


@dataclass(frozen=True)
class Light:
    """The room's light at one moment: `brightness` and its colour as (b, g, r) factors."""

    brightness: float
    tint_bgr: tuple[float, float, float]

    @property
    def luma(self) -> float:
        """Its brightness in a gray frame (perception's gray of its colour)."""
        return self.brightness * sum(w * c for w, c in zip(_GRAY, self.tint_bgr, strict=True))


def light_at(lighting: LightingSpec, now: float) -> Light:
    """The light at `now`: `brightness`/`color`, then each change from its `at_s` (ramped
    linearly over `ramp_s`)."""
    brightness = lighting.brightness
    tint = np.array(color_bgr(lighting.color), dtype=np.float64) / 255.0
    for change in sorted(lighting.changes, key=lambda c: c.at_s):
        if now < change.at_s:
            break
        share = 1.0 if change.ramp_s <= 0 else min(1.0, (now - change.at_s) / change.ramp_s)
        target = np.array(color_bgr(change.color), dtype=np.float64) / 255.0
        brightness += share * (change.brightness - brightness)
        tint = tint + share * (target - tint)
    return Light(float(brightness), (float(tint[0]), float(tint[1]), float(tint[2])))


@dataclass(frozen=True)
class Settings:
    """What one frame was taken with: `exposure_s` (shutter), `gain` (analog), the `light`,
    and the white balance's (b, g, r) gains."""

    exposure_s: float
    gain: float
    light: Light
    white_balance: tuple[float, float, float]

    @property
    def scale(self) -> float:
        """Rendered scene (gray) -> frame level, before vignetting and noise."""
        return self.light.luma * self.exposure_s * self.gain / REFERENCE_EXPOSURE_S

    def scale_bgr(self) -> tuple[float, float, float]:
        base = self.light.brightness * self.exposure_s * self.gain / REFERENCE_EXPOSURE_S
        t, w = self.light.tint_bgr, self.white_balance
        return (base * t[0] * w[0], base * t[1] * w[1], base * t[2] * w[2])


class CameraEffects:
    """The sensor, exposure, white balance, vignetting, fringes and compression of one camera,
    for one run (`seed` draws the noise). `channels`: 1 (gray frames) or 3 (BGR).
    `frame_period_s` bounds the shutter time. `display`: only exposure, white balance and
    vignetting (a clean view for the video)."""

    def __init__(self, spec: CameraSpec, lighting: LightingSpec, camera: CameraModel, *,
                 channels: int = 1, seed: int = 0, noise_bank_frames: int = 12,
                 frame_period_s: float = 1.0 / 30.0, display: bool = False) -> None:
        self.spec = spec
        self.lighting = lighting
        self.channels = channels
        self.display = display
        w, h = camera.width_px, camera.height_px
        self.size = (w, h)
        exposure = spec.exposure
        self._max_exposure_s = max(exposure.min_exposure_s,
                                   min(exposure.max_exposure_s, frame_period_s))
        self._e_min = exposure.min_exposure_s / REFERENCE_EXPOSURE_S
        self._e_max = self._max_exposure_s * exposure.max_gain / REFERENCE_EXPOSURE_S
        # Vignetting: 1 - v (r / r_corner)^2, as uint8 (255 = all the light).
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        r2 = ((xx - (w - 1) / 2.0) ** 2 + (yy - (h - 1) / 2.0) ** 2) / (
            ((w - 1) / 2.0) ** 2 + ((h - 1) / 2.0) ** 2)
        falloff = 1.0 - spec.optics.vignetting * r2
        self._vignette_mean = float(falloff.mean())
        vignette = np.rint(255.0 * falloff).astype(np.uint8)
        self._vignette = vignette if channels == 1 else np.ascontiguousarray(
            np.repeat(vignette[:, :, None], 3, axis=2))
        self._flat_vignette = spec.optics.vignetting <= 0.0
        self.blur_sigma_px = 0.0 if display else spec.optics.blur_mrad / 1000.0 * camera.focal_px
        if self.blur_sigma_px < MIN_BLUR_SIGMA_PX:
            self.blur_sigma_px = 0.0
        # Lateral chromatic aberration: red magnified, blue shrunk about the image centre.
        corner_px = math.hypot((w - 1) / 2.0, (h - 1) / 2.0) * spec.optics.chromatic
        self._fringe: tuple[F32, F32] | None = None
        # Gray frames show the fringes only through the red and blue shares of perception's gray
        # (none for its green channel).
        fringes_gray = corner_px >= MIN_FRINGE_GRAY_PX and _GRAY[0] + _GRAY[2] > 0.0
        if not display and corner_px > 0 and (channels == 3 or fringes_gray):
            c = spec.optics.chromatic
            cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
            # A channel magnified by m samples the sharp image at centre + (p - centre) / m.
            self._fringe = (np.dstack([cx + (xx - cx) / (1 + c), cy + (yy - cy) / (1 + c)]),
                            np.dstack([cx + (xx - cx) / (1 - c), cy + (yy - cy) / (1 - c)]))
        self._noise: list[F32] = []
        if not display:
            rng = np.random.default_rng([seed, 0x5E2503])
            shape = (h, w) if channels == 1 else (h, w, 3)
            for _ in range(max(1, noise_bank_frames)):
                white = rng.standard_normal(shape, dtype=np.float32)
                z = np.asarray(cv2.GaussianBlur(white, (0, 0), NOISE_CORRELATION_PX),
                               dtype=np.float32)
                z *= np.float32(1.0 / max(float(z.std()), 1e-6))
                self._noise.append(z)
        self._levels = np.arange(256, dtype=np.float32)
        self._scratch = np.empty(self._vignette.shape, np.uint8)
        self._plane = np.empty((h, w), np.uint8)
        self._sigma = np.empty(self._vignette.shape, np.float32)
        # State between frames (None: not settled yet, the first frame settles it).
        self._log_e: float | None = None
        self._log_wb: NDArray[np.float64] | None = None
        self._last_now: float | None = None

    @property
    def noise_bank_size(self) -> int:
        """How many noise frames `develop` picks from (0: no noise)."""
        return len(self._noise)

    # ---- exposure and white balance ----------------------------------------------------------
    def _split(self, e: float) -> tuple[float, float]:
        """Relative exposure -> (shutter time, gain): the shutter first, then the gain."""
        exposure = self.spec.exposure
        if not exposure.auto:
            return exposure.exposure_s, exposure.gain
        wanted = e * REFERENCE_EXPOSURE_S
        shutter = min(max(wanted, exposure.min_exposure_s), self._max_exposure_s)
        return shutter, min(max(wanted / shutter, 1.0), exposure.max_gain)

    def settle(self, scene: U8, now: float | None) -> Settings:
        """The settings the frame at `now` is taken with: what the frames before it asked for
        (`meter`). Before any frame was metered (and for a probe, `now` None, which changes
        nothing), settled on the rendered `scene` itself (before exposure)."""
        light = light_at(self.lighting, 0.0 if now is None else now)
        log_e, log_wb = self._log_e, self._log_wb
        if log_e is None or log_wb is None or now is None:
            means = cv2.mean(scene[::_METER_STEP, ::_METER_STEP])
            if self.channels == 1:
                level = means[0] * light.luma * self._vignette_mean
                log_wb = np.zeros(3)
            else:
                lit = [max(means[c] * light.brightness * light.tint_bgr[c], 1e-3)
                       for c in range(3)]
                level = sum(w * v for w, v in zip(_LUMA, lit, strict=True)) * self._vignette_mean
                log_wb = self._balanced(lit)
            log_e = self._wanted_log_e(1.0, level)
        shutter, gain = self._split(math.exp(log_e))
        wb = np.exp(log_wb)
        return Settings(shutter, gain, light, (float(wb[0]), float(wb[1]), float(wb[2])))

    def meter(self, frame: U8, settings: Settings, now: float | None) -> None:
        """Meter the exposed `frame` (highlights and all, before noise) taken with `settings` at
        `now`: the exposure and white balance move towards what it asks for with their time
        constants (the first frame settles them at once). A probe (`now` None) changes nothing."""
        if now is None:
            return
        means = cv2.mean(frame[::_METER_STEP, ::_METER_STEP])
        relative = settings.exposure_s * settings.gain / REFERENCE_EXPOSURE_S
        if self.channels == 1:
            wanted_e = self._wanted_log_e(relative, means[0])
            wanted_wb = np.zeros(3)
        else:
            wanted_e = self._wanted_log_e(
                relative, sum(w * means[c] for c, w in enumerate(_LUMA)))
            wb = settings.white_balance
            wanted_wb = self._balanced([max(means[c], 1e-3) / wb[c] for c in range(3)])
        if self._log_e is None or self._log_wb is None:
            self._log_e, self._log_wb = wanted_e, wanted_wb
        else:
            dt = 0.0 if self._last_now is None else max(0.0, now - self._last_now)
            self._log_e += _follow(dt, self.spec.exposure.time_constant_s) * (
                wanted_e - self._log_e)
            self._log_wb = self._log_wb + _follow(
                dt, self.spec.white_balance.time_constant_s) * (wanted_wb - self._log_wb)
        self._last_now = now

    def _wanted_log_e(self, relative_exposure: float, level: float) -> float:
        """log of the relative exposure that brings a frame of mean `level`, taken at
        `relative_exposure`, to the target level (within what shutter and gain can do)."""
        target = self.spec.exposure.target_level * 255.0
        wanted = relative_exposure * target / max(level, 1e-3)
        return math.log(min(max(wanted, self._e_min), self._e_max))

    def _balanced(self, channel_means: list[float]) -> NDArray[np.float64]:
        """log white-balance gains that make these (b, g, r) means grey (zero: off)."""
        if not self.spec.white_balance.auto:
            return np.zeros(3)
        grey = sum(channel_means) / 3.0
        return np.log([grey / max(v, 1e-3) for v in channel_means])

    # ---- the frame ---------------------------------------------------------------------------
    def expose(self, image: U8, settings: Settings) -> U8:
        """`image` (the rendered, blurred scene, in place) -> the light the sensor collected, in
        frame levels: vignetting, light, exposure and gain, white balance (saturating)."""
        if self.channels == 1:
            if self._flat_vignette:
                cv2.convertScaleAbs(image, dst=image, alpha=settings.scale)
            else:
                cv2.multiply(image, self._vignette, dst=image, scale=settings.scale / 255.0)
        else:
            if not self._flat_vignette:
                cv2.multiply(image, self._vignette, dst=image, scale=1.0 / 255.0)
            cv2.transform(image, np.diag(settings.scale_bgr()), dst=image)
        return image

    def develop(self, image: U8, settings: Settings, noise_index: int | None) -> U8:
        """The exposed `image` (in place) -> the frame the camera delivers: noise (`noise_index`
        picks the bank's frame; None: none), chromatic fringes, compression."""
        if noise_index is not None and self._noise:
            self._add_noise(image, settings.gain, self._noise[noise_index % len(self._noise)])
        if self._fringe is not None:
            self._fringes(image)
        if self.spec.compression.format == "jpeg" and not self.display:
            ok, data = cv2.imencode(".jpg", image,
                                    [cv2.IMWRITE_JPEG_QUALITY, self.spec.compression.quality])
            decoded = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if ok else None
            if decoded is not None:
                np.copyto(image, decoded.reshape(image.shape))
        return image

    def noise_sigma_levels(self, level: float, gain: float) -> float:
        """Standard deviation of the noise (grey levels) at frame level `level` (0..255) and
        analog `gain`: shot noise sqrt(electrons) and read noise, both times the gain."""
        k = 255.0 * gain / self.spec.sensor.full_well_e
        return math.sqrt(max(level, 0.0) * k + (self.spec.sensor.read_noise_e * k) ** 2)

    def _add_noise(self, image: U8, gain: float, unit: F32) -> None:
        k = 255.0 * gain / self.spec.sensor.full_well_e
        lut = np.sqrt(self._levels * k + (self.spec.sensor.read_noise_e * k) ** 2)
        lut[255] = 0.0  # a saturated pixel stays saturated
        cv2.LUT(image, lut, dst=self._sigma)
        cv2.multiply(self._sigma, unit, dst=self._sigma)
        cv2.add(image, self._sigma, dst=image, dtype=cv2.CV_8U)

    def _fringes(self, image: U8) -> None:
        assert self._fringe is not None
        red_map, blue_map = self._fringe
        if self.channels == 3:
            for channel, grid in ((2, red_map), (0, blue_map)):
                plane = np.ascontiguousarray(image[:, :, channel])
                cv2.remap(plane, grid, None, cv2.INTER_LINEAR,  # type: ignore[call-overload]
                          dst=self._plane, borderMode=cv2.BORDER_REPLICATE)
                image[:, :, channel] = self._plane
            return
        # Gray: perception's gray of the fringed colours of a grey scene.
        red = cv2.remap(image, red_map, None, cv2.INTER_LINEAR,  # type: ignore[call-overload]
                        borderMode=cv2.BORDER_REPLICATE)
        cv2.remap(image, blue_map, None, cv2.INTER_LINEAR,  # type: ignore[call-overload]
                  dst=self._scratch, borderMode=cv2.BORDER_REPLICATE)
        cv2.addWeighted(red, _GRAY[2] / (_GRAY[2] + _GRAY[0]), self._scratch,
                        _GRAY[0] / (_GRAY[2] + _GRAY[0]), 0.0, dst=self._scratch)
        cv2.addWeighted(image, _GRAY[1], self._scratch, 1.0 - _GRAY[1], 0.0, dst=image)


def _follow(dt: float, time_constant_s: float) -> float:
    """Share of the way a first-order lag moves towards its target in `dt`."""
    if time_constant_s <= 0.0:
        return 1.0
    return 1.0 - math.exp(-dt / time_constant_s)
