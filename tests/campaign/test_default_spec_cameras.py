"""Every camera of the default campaign works with every scenario it is drawn with: perception
accepts it at start-up (it can tell tape from seam at its look-ahead), so no run of
`lanewarden campaign --spec default` can end as an `error` for the spec's own sake."""

from __future__ import annotations

import pytest

from lanewarden.config import config_from_mapping
from lanewarden.perception.calibration import Undistorter
from lanewarden.perception.detector import LaneDetector
from lanewarden.scenarios.campaign.cases import CameraChoice, load_campaign_spec
from lanewarden.scenarios.library import resolve_scenario
from lanewarden.scenarios.simulator import effective_config, sim_camera_model
from lanewarden.scenarios.spec import merge_overrides, parse_scenario

SPEC, _ = load_campaign_spec("default")


@pytest.mark.parametrize("camera", SPEC.cameras, ids=[c.name for c in SPEC.cameras])
@pytest.mark.parametrize("scenario", SPEC.scenarios)
def test_perception_accepts_the_camera(scenario: str, camera: CameraChoice) -> None:
    data = resolve_scenario(scenario).model_dump(mode="json", exclude_defaults=True)
    data.pop("expect", None)
    if camera.camera:
        data["camera"] = merge_overrides(data.get("camera", {}), camera.camera)
    spec = parse_scenario(data, scenario)
    overrides = merge_overrides(SPEC.config, camera.config)
    overrides = merge_overrides(overrides, {"simulation": {
        "width_px": camera.width_px, "height_px": camera.height_px}})
    config = effective_config(config_from_mapping(overrides), spec)
    model = sim_camera_model(config, spec.camera)
    LaneDetector(config.perception, Undistorter(model.calibration()))  # raises if refused
