"""A scenario's `camera:` block: validated, rendered with, and handed to perception with its ground
pose (as a calibrated robot's camera would be)."""

from __future__ import annotations

import numpy as np
import pytest

from lanewarden.assembly import build_stack
from lanewarden.config import LanewardenConfig
from lanewarden.perception.ground import CameraPose, ground_model_for
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.simulator import Simulation, effective_config, sim_camera_model
from lanewarden.scenarios.spec import with_overrides
from tests.scenarios.helpers import spec_from

CAMERA = {"height_m": 0.26, "pitch_deg": 40.0, "roll_deg": 2.0, "hfov_deg": 62.0,
          "forward_m": 0.10, "width_px": 320, "height_px": 240,
          "distortion": [-0.1, 0.02, 0.0, 0.0, 0.0]}
LANE = {"segments": [{"straight_m": 3.0}]}


def test_the_camera_block_renders_and_is_what_perception_gets() -> None:
    spec = spec_from({"camera": CAMERA, "lane": LANE, "floor": {"kind": "plain"}})
    config = effective_config(LanewardenConfig(), spec)
    assert (config.simulation.width_px, config.simulation.height_px) == (320, 240)
    sim = Simulation(spec, config, build_stack)
    camera = sim.camera
    assert (camera.width_px, camera.height_px, camera.hfov_deg) == (320, 240, 62.0)
    assert camera.dist_coeffs == (-0.1, 0.02, 0.0, 0.0, 0.0)
    pose = CameraPose(height_m=0.26, pitch_deg=40.0, roll_deg=2.0, forward_m=0.10)
    assert camera.pose == pose
    # perception's calibration: the camera's K and distortion, and its ground pose
    assert sim.detector.undistorter is not None
    calibration = sim.detector.undistorter.calibration
    assert calibration is sim.calibration and calibration.ground is not None
    assert calibration.ground.pose == pose
    np.testing.assert_array_equal(calibration.camera_matrix, camera.camera_matrix())
    np.testing.assert_array_equal(calibration.dist_coeffs, [-0.1, 0.02, 0.0, 0.0, 0.0])
    model, line = ground_model_for(calibration, (320, 240), "the scenario")
    np.testing.assert_allclose(model.floor_to_image_h, camera.ground.floor_to_image_h)
    assert line.startswith("ground calibration from the scenario: h 0.260 m, pitch 40.0°")
    # the rendered frame shows the tape where this camera's model puts it (f = 266 px)
    image = sim.renderer.render_gray(sim.world.start_pose, np.empty((240, 320), np.uint8))
    tape_u, tape_v = camera.project_ground(np.array([[0.8, 0.30]]))[0]
    floor_u, floor_v = camera.project_ground(np.array([[0.8, 0.0]]))[0]
    assert image[round(tape_v), round(tape_u)] < 80 < image[round(floor_v), round(floor_u)]


def test_without_a_block_the_default_camera_at_the_configured_size() -> None:
    spec = spec_from({"lane": LANE})
    fast = {"simulation": {"width_px": 320, "height_px": 240}}
    config = effective_config(with_overrides(LanewardenConfig(), fast, "test"), spec)
    camera = sim_camera_model(config, spec.camera)
    assert (camera.width_px, camera.height_px) == (320, 240)
    assert camera.pose == CameraPose(height_m=0.40, pitch_deg=35.0, forward_m=0.15)


def test_a_block_without_a_size_renders_at_the_configured_size() -> None:
    spec = spec_from({"camera": {"height_m": 0.3, "pitch_deg": 45.0}, "lane": LANE})
    fast = {"simulation": {"width_px": 320, "height_px": 240}}
    config = effective_config(with_overrides(LanewardenConfig(), fast, "test"), spec)
    camera = sim_camera_model(config, spec.camera)
    assert (camera.width_px, camera.height_px, camera.height_m) == (320, 240, 0.3)
    assert camera.hfov_deg == 70.0 and camera.dist_coeffs == (-0.2, 0.05, 0.0, 0.0, 0.0)


def test_a_block_size_is_the_one_render_size() -> None:
    spec = spec_from({"camera": CAMERA, "lane": LANE})
    # a config asking for another size gets the camera's size for this scenario
    other = with_overrides(LanewardenConfig(), {"simulation": {"width_px": 640,
                                                                "height_px": 480}}, "test")
    assert effective_config(other, spec).simulation.width_px == 320
    # ... but a Simulation built from a config that disagrees is refused, not silently resized
    with pytest.raises(ScenarioError, match="camera block: 320x240 px but the config renders "
                                            "640x480 px"):
        sim_camera_model(other, spec.camera)


def test_a_perception_that_takes_colour_apart_gets_colour_frames() -> None:
    """`perception.gray.yellow_boost` reads a colour frame's blue: the simulator hands
    perception colour frames then (a gray frame would leave the boost nothing to act on)."""
    spec = spec_from({"lane": LANE})
    assert not effective_config(LanewardenConfig(), spec).simulation.perception_color
    boosted = with_overrides(LanewardenConfig(), {"perception": {"gray": {"yellow_boost": 0.5}}},
                             "test")
    assert effective_config(boosted, spec).simulation.perception_color
    fast = {"simulation": {"progress": False}}
    sim = Simulation(spec, effective_config(with_overrides(boosted, fast, "test"), spec),
                     build_stack)
    assert sim.sim_camera.buffer().shape == (sim.camera.height_px, sim.camera.width_px, 3)
    assert sim.lane_contrast.yellow_boost == 0.5


@pytest.mark.parametrize(("camera", "extra", "message"), [
    ({"width_px": 320}, {}, "give width_px and height_px together"),
    ({"width_px": 320, "height_px": 240}, {"config": {"simulation": {"width_px": 640}}},
     "both give the render size: give it in one place"),
    ({"height_m": 0.0}, {}, "camera.height_m"),
    ({"pitch_deg": 95.0}, {}, "camera.pitch_deg"),
    ({"hfov_deg": 200.0}, {}, "camera.hfov_deg"),
    ({"width_px": 321, "height_px": 240}, {}, "camera.width_px"),
    ({"distortion": [0.1, 0.2]}, {}, "camera.distortion"),
    ({"focal_px": 500}, {}, "camera.focal_px"),
])
def test_bad_camera_blocks_name_the_key(camera: dict[str, object], extra: dict[str, object],
                                        message: str) -> None:
    with pytest.raises(ScenarioError, match=message.replace(".", r"\.")):
        spec_from({"camera": camera, "lane": LANE, **extra})


def test_rectified_frames_render_the_pinhole_image_that_perception_does_not_remap() -> None:
    spec = spec_from({"camera": CAMERA, "lane": LANE, "floor": {"kind": "plain"},
                      "run": {"max_time_s": 4}})
    rectified = {"simulation": {"rectified_frames": True}}
    config = effective_config(with_overrides(LanewardenConfig(), rectified, "test"), spec)
    sim = Simulation(spec, config, build_stack)
    assert sim.camera.dist_coeffs == (0.0, 0.0, 0.0, 0.0, 0.0)
    assert sim.camera.pose == CameraPose(height_m=0.26, pitch_deg=40.0, roll_deg=2.0,
                                         forward_m=0.10)
    assert sim.detector.undistorter is not None and sim.detector.undistorter.identity
    np.testing.assert_array_equal(sim.calibration.dist_coeffs, np.zeros(5))
    # The tape's outer edge 0.8 m ahead (y 0.32 m, inside the 48 mm tape at 0.30 m) is tape in
    # the pinhole image; the distorted render of this lens (-0.1 barrel) shows floor there.
    image = sim.renderer.render_gray(sim.world.start_pose, np.empty((240, 320), np.uint8))
    tape_u, tape_v = sim.camera.project_ground(np.array([[0.8, 0.32]]), distort=False)[0]
    floor_u, floor_v = sim.camera.project_ground(np.array([[0.8, 0.0]]), distort=False)[0]
    assert image[round(tape_v), round(tape_u)] < 80 < image[round(floor_v), round(floor_u)]
    result = sim.run()
    assert result.end_reason == "time limit" and result.trace.states[-1] == "FOLLOW"
