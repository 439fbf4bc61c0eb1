"""The detector on 1000 real frames it was never tuned on (Donkeycar tub, 160x120, yellow dashed
centre line and white edge lines on a grey floor, a human driving).

Asserts: no error and no NaN on any frame; detection rates no lower than measured (minus a small
margin); and that the slope sum agrees in sign with the human's steering (`user/angle`, positive =
right, so it anti-correlates with the slope sum, whose negative means "turn right"), more
strongly on the frames perception is confident about.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.config import load_config
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from tests.conftest import shared_data

HERE = Path(__file__).parent
#: The confidence the rates below were measured at: a perception quality bar for this test (what
#: the supervisor trusts is its own `confidence_usable_min`).
CONFIDENT = 0.5


@pytest.fixture(scope="module")
def tub() -> list[tuple[np.ndarray, float]]:
    folder = shared_data("donkeycar-tub")
    records = [
        json.loads(line)
        for line in (folder / "catalog_0.catalog").read_text().splitlines()
        if line.strip()
    ]
    frames = []
    for record in records:
        image = cv2.imread(str(folder / "images" / record["cam/image_array"]))
        assert image is not None, record["cam/image_array"]
        frames.append((image, float(record["user/angle"])))
    assert len(frames) == 1000
    return frames


def _run(config: PerceptionConfig, tub: list[tuple[np.ndarray, float]]) -> dict[str, float]:
    detector = LaneDetector(config)
    both = confident = 0
    sums, angles, confident_mask = [], [], []
    for index, (image, angle) in enumerate(tub):
        obs = detector.detect(image, index, index / 20.0)
        values = [obs.confidence, *obs.components.values()]
        values += [v for v in (obs.slope_sum, obs.center_offset) if v is not None]
        assert all(math.isfinite(v) for v in values), (index, obs)
        assert 0.0 <= obs.confidence <= 1.0
        is_confident = obs.confidence >= CONFIDENT and obs.both_edges
        both += obs.both_edges
        confident += is_confident
        if obs.slope_sum is not None:
            sums.append(obs.slope_sum)
            angles.append(angle)
            confident_mask.append(is_confident)
    s, a, m = np.array(sums), np.array(angles), np.array(confident_mask)
    return {
        "both_edges_rate": both / len(tub),
        "confident_rate": confident / len(tub),
        "corr_all": float(np.corrcoef(s, a)[0, 1]),
        "corr_confident": float(np.corrcoef(s[m], a[m])[0, 1]),
    }


@pytest.mark.parametrize(
    ("config_name", "min_both", "min_confident"),
    # Measured: defaults 1.000 / 0.460; with the tub camera's geometry 0.973 / 0.671.
    [("defaults", 0.95, 0.40), ("donkeycar_camera.yaml", 0.92, 0.60)],
)
def test_real_frames_detection_rate(
    tub: list[tuple[np.ndarray, float]],
    config_name: str,
    min_both: float,
    min_confident: float,
    capsys: pytest.CaptureFixture[str],
) -> None:
    config = (
        PerceptionConfig()
        if config_name == "defaults"
        else load_config(HERE / config_name).perception
    )
    result = _run(config, tub)
    with capsys.disabled():
        print(
            f"\n[donkeycar tub, {config_name}] both edges {result['both_edges_rate']:.1%}, "
            f"confident {result['confident_rate']:.1%}, corr(slope_sum, steering) "
            f"all {result['corr_all']:+.2f} / confident {result['corr_confident']:+.2f}"
        )
    assert result["both_edges_rate"] >= min_both
    assert result["confident_rate"] >= min_confident
    assert result["corr_confident"] < -0.4
    assert result["corr_confident"] < result["corr_all"]
