"""Perception hazards that live in the camera's image, applied to a rendered frame in place.

- glare_sweep: a bright reflection (a Gaussian blob, 1 sigma = a fifth of the image width) sweeps
  across the image at 60 % of its height, from the `side` edge to the other, over the fault's
  duration; `intensity` is the fraction of full white added at its centre.
- occlusion: something in front of the lens (out of focus: flat grey, the frame's mean) hides the
  `side` 45 % of the image from the bottom up to `intensity` of its height: one tape, partly.
- lens_smudge: a Gaussian blur of sigma 0.5 + 6 * `intensity` pixels.
- exposure_jump: the frame times 4 ** (2 * `intensity` - 1), saturating (0.25x .. 4x).

Pure image operations on uint8 frames (gray or BGR), sized in fractions of the frame so they mean
the same at any resolution. Never reads a clock: the sweep's position comes from the caller's
`now`. Each returns True when it changed the frame (it took effect).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.scenarios.spec import FaultSpec

U8 = NDArray[np.uint8]

#: Image hazard kinds handled here.
IMAGE_FAULT_KINDS = ("glare_sweep", "occlusion", "lens_smudge", "exposure_jump")
#: A glare sweep without a duration crosses the image in this long.
DEFAULT_SWEEP_S = 2.0


def exposure_gain(intensity: float) -> float:
    return float(4.0 ** (2.0 * intensity - 1.0))


def smudge_sigma_px(intensity: float) -> float:
    return 0.5 + 6.0 * intensity


class ImageHazard:
    """One image fault, with whatever it needs precomputed for the frame size."""

    def __init__(self, spec: FaultSpec, shape: tuple[int, ...]) -> None:
        self.spec = spec
        h, w = shape[0], shape[1]
        self._h, self._w = h, w
        self._blob: NDArray[np.float32] | None = None
        if spec.kind == "glare_sweep":
            sigma = w / 5.0
            radius = int(math.ceil(3 * sigma))
            ax = np.arange(-radius, radius + 1, dtype=np.float32)
            blob = np.exp(-(ax[:, None] ** 2 + ax[None, :] ** 2) / (2 * sigma * sigma))
            self._blob = (255.0 * spec.intensity * blob).astype(np.float32)
            self._radius = radius

    def apply(self, image: U8, now: float) -> bool:
        kind = self.spec.kind
        if kind == "glare_sweep":
            return self._glare(image, now)
        if kind == "occlusion":
            return self._occlude(image)
        if kind == "lens_smudge":
            sigma = smudge_sigma_px(self.spec.intensity)
            cv2.GaussianBlur(image, (0, 0), sigma, dst=image)
            return True
        if kind == "exposure_jump":
            gain = exposure_gain(self.spec.intensity)
            if abs(gain - 1.0) < 1e-6:
                return False
            cv2.convertScaleAbs(image, dst=image, alpha=gain)
            return True
        raise ValueError(f"not an image fault: {kind}")

    def _glare(self, image: U8, now: float) -> bool:
        assert self._blob is not None
        duration = self.spec.duration_s or DEFAULT_SWEEP_S
        progress = min(max((now - self.spec.at_s) / duration, 0.0), 1.0)
        if self.spec.side == "right":
            progress = 1.0 - progress
        cx = int(round(progress * (self._w - 1)))
        cy = int(round(0.6 * (self._h - 1)))
        r = self._radius
        x0, x1 = max(0, cx - r), min(self._w, cx + r + 1)
        y0, y1 = max(0, cy - r), min(self._h, cy + r + 1)
        if x0 >= x1 or y0 >= y1 or self.spec.intensity <= 0:
            return False
        patch = self._blob[y0 - (cy - r):y1 - (cy - r), x0 - (cx - r):x1 - (cx - r)]
        region = image[y0:y1, x0:x1]
        if region.ndim == 3:
            patch = np.repeat(patch[:, :, None], region.shape[2], axis=2)
        lit = region.astype(np.float32) + patch
        np.clip(lit, 0, 255, out=lit)
        region[...] = lit.astype(np.uint8)
        return True

    def _occlude(self, image: U8) -> bool:
        rows = int(round(self.spec.intensity * self._h))
        if rows <= 0:
            return False
        cols = int(round(0.45 * self._w))
        mean = image[::8, ::8].reshape(-1, *image.shape[2:]).mean(axis=0)
        if self.spec.side == "left":
            image[self._h - rows:, :cols] = np.asarray(mean, dtype=np.float64).round()
        else:
            image[self._h - rows:, self._w - cols:] = np.asarray(mean,
                                                                   dtype=np.float64).round()
        return True
