"""`GroundRoi.inside` given `FloorSamples` (only the runs of samples whose circle reaches the
ROI are tested) finds exactly the indices the test of every sample finds."""

from __future__ import annotations

import numpy as np

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.metrics import FloorSamples, GroundRoi, clip_convex
from lanewarden.scenarios.world import build_world
from tests.scenarios.helpers import spec_from

CAMERA = CameraModel(width_px=320, height_px=240)
#: The campaign's ROI (a trapezoid over the lower two thirds) and the lecture's triangle.
ROIS = [np.array([[0.0, 80.0], [55.0, 39.0], [265.0, 39.0], [320.0, 80.0], [320.0, 240.0],
                  [0.0, 240.0]]),
        np.array([[0.0, 239.0], [160.0, 60.0], [319.0, 239.0]])]


def test_clip_convex_keeps_the_side_where_the_plane_is_positive() -> None:
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    half = clip_convex(square, np.array([-1.0, 0.0, 1.0]))  # x <= 1
    assert sorted(map(tuple, half.tolist())) == [(0.0, 0.0), (0.0, 2.0), (1.0, 0.0), (1.0, 2.0)]
    assert clip_convex(square, np.array([1.0, 0.0, -3.0])).shape == (0, 2)  # x >= 3


def test_runs_find_the_same_samples_as_testing_every_one() -> None:
    segments = [{"straight_m": 2.0}, {"arc_radius_m": 1.2, "turn_deg": 90.0},
                {"straight_m": 1.5}, {"arc_radius_m": 1.0, "turn_deg": -120.0}]
    spec = spec_from({"lane": {"segments": segments}})
    world = build_world(spec, margin_m=1.0)
    samples = world.tape_samples
    runs = FloorSamples(samples)
    rng = np.random.default_rng(3)
    found = 0
    for roi in ROIS:
        ground = GroundRoi(CAMERA, roi)
        for _ in range(300):
            x, y = samples[rng.integers(len(samples))] + rng.normal(0.0, 0.5, 2)
            pose = Pose2D(float(x), float(y), float(rng.uniform(-np.pi, np.pi)))
            every = ground.inside(pose, samples)
            assert np.array_equal(ground.inside(pose, runs), every)
            found += len(every)
    assert found > 10_000  # the poses do see tape


def test_no_samples() -> None:
    ground = GroundRoi(CAMERA, ROIS[0])
    assert len(ground.inside(Pose2D(0.0, 0.0, 0.0), FloorSamples(np.zeros((0, 2))))) == 0
