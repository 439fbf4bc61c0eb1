"""The image hazards on a frame: literal sizes, gains and positions."""

from __future__ import annotations

import numpy as np

from lanewarden.scenarios.fault_image import ImageHazard, exposure_gain, smudge_sigma_px
from lanewarden.scenarios.spec import FaultSpec


def test_exposure_and_smudge_scales() -> None:
    assert [exposure_gain(i) for i in (0.0, 0.5, 1.0)] == [0.25, 1.0, 4.0]
    assert [smudge_sigma_px(i) for i in (0.0, 1.0)] == [0.5, 6.5]


def test_occlusion_hides_the_right_side_from_the_bottom_up() -> None:
    image = np.zeros((100, 200), np.uint8)
    image[:, :100] = 200
    hazard = ImageHazard(FaultSpec(kind="occlusion", at_s=0.0, side="right", intensity=0.3),
                         image.shape)
    assert hazard.apply(image, 0.0)
    # flat grey: the mean of every 8th pixel (13 of its 25 sampled columns are 200)
    assert np.all(image[70:, 110:] == 104)
    assert np.all(image[:70, 110:] == 0) and np.all(image[:, :100] == 200)


def test_exposure_jump_saturates() -> None:
    image = np.full((10, 10, 3), 100, np.uint8)
    hazard = ImageHazard(FaultSpec(kind="exposure_jump", at_s=0.0, intensity=1.0), image.shape)
    assert hazard.apply(image, 0.0) and np.all(image == 255)
    neutral = ImageHazard(FaultSpec(kind="exposure_jump", at_s=0.0, intensity=0.5), image.shape)
    assert not neutral.apply(image, 0.0)  # gain 1: no effect, so it did not take effect


def test_glare_sweeps_from_the_left_edge_to_the_right() -> None:
    spec = FaultSpec(kind="glare_sweep", at_s=1.0, duration_s=2.0, intensity=0.8, side="left")
    hazard = ImageHazard(spec, (60, 100))
    brightest = []
    for now in (1.0, 2.0, 3.0):
        image = np.zeros((60, 100), np.uint8)
        assert hazard.apply(image, now)
        row, col = np.unravel_index(int(np.argmax(image)), image.shape)
        brightest.append((int(row), int(col)))
    assert brightest == [(35, 0), (35, 50), (35, 99)]  # at 60 % of the height
    assert int(image.max()) == 204  # 0.8 of full white at the centre
