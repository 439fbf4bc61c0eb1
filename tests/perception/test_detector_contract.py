"""The detector's contract: inputs it accepts and refuses, what its output guarantees, the
debug path, the overlay, and the per-size caching of masks and buffers."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lanewarden.perception.confidence import COMPONENT_NAMES
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector, perception_gray
from lanewarden.perception.errors import PerceptionConfigError, PerceptionError
from lanewarden.perception.ground import CameraPose, GroundModel
from lanewarden.perception.observation import LaneObservation
from lanewarden.perception.overlay import draw_overlay
from tests.perception import synthetic as syn

CONFIG = PerceptionConfig()


@pytest.fixture(scope="module")
def detector() -> LaneDetector:
    return LaneDetector(CONFIG)


@pytest.mark.parametrize(
    ("image", "expected"),
    [
        (np.zeros((0, 0, 3), np.uint8), "too small"),
        (np.zeros((8, 640, 3), np.uint8), "too small"),
        (np.zeros((480, 640, 3), np.float32), "dtype uint8"),
        (np.zeros((480, 640, 2), np.uint8), "shape"),
        (np.zeros((4, 480, 640), np.uint8), "shape"),
        ([[0, 0], [0, 0]], "numpy image array"),
    ],
)
def test_unusable_frames_raise_perception_error(
    detector: LaneDetector, image: object, expected: str
) -> None:
    with pytest.raises(PerceptionError, match=expected) as info:
        detector.detect(image, 0, 0.0)  # type: ignore[arg-type]
    assert "\n" not in str(info.value)


def test_gray_bgr_and_bgra_inputs_agree(detector: LaneDetector) -> None:
    bgr = syn.frame(syn.STRAIGHT)
    gray = perception_gray(bgr)
    bgra = cv2.cvtColor(bgr, cv2.COLOR_BGR2BGRA)
    results = [detector.detect(img, 0, 0.0) for img in (bgr, gray, gray[:, :, None], bgra)]
    assert all(r.slope_sum is not None for r in results)
    sums = [r.slope_sum for r in results]
    assert max(sums) - min(sums) < 1e-9  # type: ignore[operator]


def test_the_yellow_boost_lifts_yellow_and_leaves_greys_alone() -> None:
    """gray = luma + b x max(0, luma - blue), saturated; luma values by hand (BGR2GRAY, rounded):
    yellow #e3b21c 176, parquet's light slat #a5763f 126, white #eeeeea 238, a neutral grey 90,
    black tape #1c1c1e 28, and a white tape tinted blue by a camera's white balance (BGR 200,
    176, 168; the simulator's white tape on parquet looks so) 176."""
    bgr = np.array([[(28, 178, 227), (63, 118, 165), (234, 238, 238), (90, 90, 90),
                     (30, 28, 28), (200, 176, 168)]], dtype=np.uint8)
    assert perception_gray(bgr).tolist() == [[176, 126, 238, 90, 28, 176]]
    # 176 + 0.5 x (176 - 28) = 250; 126 + 0.5 x 63 = 157.5 -> 158; 238 + 2 = 240; greys stay;
    # blue above luma (black tape: 30 > 28, the tinted white: 200 > 176) is not subtracted
    # (unclipped, the tinted white would read 176 - 0.5 x 24 = 164, darkened towards the floor)
    assert perception_gray(bgr, yellow_boost=0.5).tolist() == [[250, 158, 240, 90, 28, 176]]
    assert perception_gray(bgr, yellow_boost=1.0)[0, 0] == 255  # 324, saturated
    bgra = cv2.cvtColor(bgr, cv2.COLOR_BGR2BGRA)
    out = np.empty((1, 6), np.uint8)
    assert perception_gray(bgra, dst=out, yellow_boost=0.5) is out
    assert out.tolist() == [[250, 158, 240, 90, 28, 176]]
    gray = perception_gray(bgr)  # a gray camera has no blue: the boost leaves it as it is
    assert perception_gray(gray, yellow_boost=0.5) is gray


def test_the_detector_reads_a_yellow_line_through_its_configured_gray() -> None:
    """The same colour frame: with the boost the detector sees exactly the boosted gray."""
    bgr = np.array(syn.frame(syn.STRAIGHT))
    bgr[:, :, 0] //= 2  # yellowed: less blue
    boosted = LaneDetector(PerceptionConfig.model_validate({"gray": {"yellow_boost": 0.5}}))
    plain = LaneDetector(CONFIG)
    seen = boosted.prepare(bgr)
    assert np.array_equal(seen, plain.prepare(perception_gray(bgr, yellow_boost=0.5)))
    assert not np.array_equal(seen, plain.prepare(bgr))


def test_the_ground_line_names_a_boosted_gray_and_only_then() -> None:
    """Two surveys of one floor, with and without the boost, say which is which."""
    plain = LaneDetector(CONFIG).describe_ground(size=(320, 240))
    boosted = LaneDetector(PerceptionConfig.model_validate(
        {"gray": {"yellow_boost": 0.8}})).describe_ground(size=(320, 240))
    assert "gray" not in plain
    assert boosted == (plain + "; gray of colour frames: luma + 0.8 x max(0, luma - blue) "
                       "(perception.gray.yellow_boost; a gray frame is read as it is)")


def test_observation_is_frozen_with_immutable_components(detector: LaneDetector) -> None:
    obs = detector.detect(syn.frame(syn.STRAIGHT), 7, 1.25)
    assert (obs.frame_index, obs.time_s) == (7, 1.25)
    with pytest.raises(dataclasses.FrozenInstanceError):
        obs.confidence = 0.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        obs.components["both_sides"] = 0.0  # type: ignore[index]
    assert tuple(obs.components) == COMPONENT_NAMES
    assert all(0.0 <= v <= 1.0 for v in obs.components.values())


def test_input_frame_is_not_modified(detector: LaneDetector) -> None:
    image = np.array(syn.frame(syn.TILES_WITH_TAPE))
    before = image.copy()
    detector.detect(image, 0, 0.0)
    assert np.array_equal(image, before)


def test_debug_path_gives_the_same_observation(detector: LaneDetector) -> None:
    image = syn.frame(syn.DASHED)
    plain = detector.detect(image, 3, 0.1)
    obs, debug = detector.detect_debug(image, 3, 0.1)
    assert obs == plain
    assert debug.image_size == (640, 480)
    assert debug.segments.shape[1] == 4 and len(debug.segments) > 0
    assert debug.left is not None and debug.right is not None
    assert debug.left.partner is not None  # the dashed tape's outer edge
    # The floor region (1.6 m ahead, 0.65 m to each side) clipped by the image: the whole bottom
    # edge, the sides up to where the region's far corners leave the image, the far edge.
    polygon = debug.roi_polygon_px
    assert polygon.shape[1] == 2 and len(polygon) >= 4
    assert polygon[:, 0].min() == 0 and polygon[:, 0].max() == 640
    assert polygon[:, 1].max() == 480 and 60 < polygon[:, 1].min() < 100


def test_masks_and_buffers_are_made_once_per_image_size(detector: LaneDetector) -> None:
    big = syn.frame(syn.STRAIGHT)
    small = syn.frame(syn.STRAIGHT, 320, 240)
    detector.detect(big, 0, 0.0)
    setup = detector.setup_for(640, 480)
    mask, edges = setup.mask, setup.edges
    detector.detect(small, 1, 0.0)
    detector.detect(big, 2, 0.0)
    assert detector.setup_for(640, 480) is setup
    assert setup.mask is mask and setup.edges is edges
    assert detector.setup_for(320, 240) is not setup
    # Pixel lengths scale with the image: the 320x240 setup uses half the Hough lengths.
    small_setup = detector.setup_for(320, 240)
    assert small_setup.hough_min_length == pytest.approx(setup.hough_min_length / 2)
    assert setup.blur_kernel == (5, 5) and small_setup.blur_kernel == (3, 3)


def test_consistency_with_a_previous_observation(detector: LaneDetector) -> None:
    straight = detector.detect(syn.frame(syn.STRAIGHT), 0, 0.0)
    again = detector.detect(syn.frame(syn.STRAIGHT), 1, 0.05, previous=straight)
    assert again.components["consistency"] == 1.0
    # The lane jumps sideways by 14% of the image width between two frames: not plausible.
    jumped = detector.detect(
        syn.frame(replace(syn.STRAIGHT, lateral_m=0.08)), 1, 0.05, previous=straight
    )
    alone = detector.detect(syn.frame(replace(syn.STRAIGHT, lateral_m=0.08)), 1, 0.05)
    assert jumped.components["consistency"] < 0.5
    assert jumped.confidence < alone.confidence


def test_consistency_with_several_observations_is_the_best_agreement(
        detector: LaneDetector) -> None:
    """The control loop passes the frame before and the last trusted lane: a frame agreeing
    with either is consistent; one agreeing with neither is not; an empty tuple is neutral."""
    straight = detector.detect(syn.frame(syn.STRAIGHT), 0, 0.0)
    shifted = syn.frame(replace(syn.STRAIGHT, lateral_m=0.08))
    jumped = detector.detect(shifted, 1, 0.05)
    again = detector.detect(syn.frame(syn.STRAIGHT), 2, 0.1, previous=(jumped, straight))
    assert again.components["consistency"] == 1.0
    assert detector.detect(syn.frame(syn.STRAIGHT), 2, 0.1, previous=(straight, jumped)
                           ).components["consistency"] == 1.0
    neither = detector.detect(shifted, 2, 0.1, previous=(straight, straight))
    assert neither.components["consistency"] < 0.5
    assert detector.detect(shifted, 2, 0.1, previous=()).components["consistency"] == 1.0


def test_detector_keeps_no_history(detector: LaneDetector) -> None:
    """Same frame, same answer, whatever came before (state lives in `previous` only)."""
    first = detector.detect(syn.frame(syn.BEND_LEFT), 0, 0.0)
    detector.detect(syn.frame(syn.TILES_ONLY), 1, 0.0)
    assert detector.detect(syn.frame(syn.BEND_LEFT), 0, 0.0) == first


def _finite(obs: LaneObservation) -> bool:
    values = [obs.confidence, *obs.components.values()]
    for edge in (obs.left, obs.right):
        if edge is not None:
            values += [edge.x1, edge.y1, edge.x2, edge.y2, edge.slope]
    values += [v for v in (obs.slope_sum, obs.lane_offset_m, obs.lane_heading_rad)
               if v is not None]
    for edge in (obs.left, obs.right):
        if edge is not None:
            values += [v for v in (edge.offset_m, edge.heading_rad) if v is not None]
    return all(math.isfinite(v) for v in values)


#: A look-ahead near enough for the default camera to tell tape from seam down to 160x120.
NEAR_LOOK_AHEAD = PerceptionConfig.model_validate({"edges": {"look_ahead_m": 0.45}})


@settings(derandomize=True, max_examples=25, deadline=None)
@given(
    seed=st.integers(min_value=0, max_value=2**31),
    width=st.integers(min_value=16, max_value=360),
    height=st.integers(min_value=16, max_value=270),
    kind=st.sampled_from(["noise", "lines", "flat"]),
)
def test_arbitrary_frames_never_crash_or_give_nan(
    seed: int, width: int, height: int, kind: str
) -> None:
    """Any frame of any size is either analysed (finite, bounded) or, at a size where the camera
    cannot tell tape from seam, refused with a one-line PerceptionConfigError."""
    detector = LaneDetector(NEAR_LOOK_AHEAD)
    rng = np.random.default_rng(seed)
    if kind == "noise":
        image = rng.integers(0, 256, (height, width, 3), dtype=np.uint8)
    elif kind == "flat":
        image = np.full((height, width, 3), int(rng.integers(0, 256)), np.uint8)
    else:
        image = np.full((height, width, 3), 128, np.uint8)
        for _ in range(12):
            p = rng.integers(-20, max(width, height) + 20, 4)
            cv2.line(image, (int(p[0]), int(p[1])), (int(p[2]), int(p[3])),
                     (int(rng.integers(0, 256)),) * 3, int(rng.integers(1, 6)))
    try:
        first = detector.detect(image, 0, 0.0)
    except PerceptionConfigError as exc:
        assert "\n" not in str(exc) and "look_ahead_m" in str(exc)
        assert width < 160 or height < 120  # 160x120 and up are analysed
        return
    shifted = np.ascontiguousarray(np.roll(image, int(rng.integers(-8, 9)), axis=1))
    obs = detector.detect(shifted, 1, 0.05, previous=first)
    assert _finite(first) and _finite(obs)
    assert 0.0 <= obs.confidence <= 1.0
    max_slope = NEAR_LOOK_AHEAD.edges.max_abs_slope
    if obs.left is not None:
        assert 0.0 <= obs.left.slope <= max_slope
    if obs.right is not None:
        assert -max_slope <= obs.right.slope <= 0.0


@pytest.mark.parametrize("start_m", [1.2, 2.0, 3.0])
def test_lane_seen_only_far_ahead(detector: LaneDetector, start_m: float) -> None:
    """The tape starts beyond the look-ahead row: edges are still reported near end first and
    compared with a previous observation without trouble (a zero-height edge once divided by
    zero here)."""
    scene = replace(syn.STRAIGHT, lane_start_m=start_m)
    straight = detector.detect(syn.frame(syn.STRAIGHT), 0, 0.0)
    for width in (640, 320):
        obs = detector.detect(syn.frame(scene, width, width * 3 // 4), 1, 0.0, previous=straight)
        assert _finite(obs)
        for edge in (obs.left, obs.right):
            if edge is not None:
                assert edge.y1 > edge.y2


@pytest.mark.parametrize("scene", [syn.STRAIGHT, syn.ONE_EDGE, syn.NO_LANE])
def test_overlay_is_a_same_size_bgr_copy(detector: LaneDetector, scene: syn.Scene) -> None:
    image = syn.frame(scene)
    obs, debug = detector.detect_debug(image, 0, 0.0)
    canvas = draw_overlay(image, obs, debug, "straight")
    assert canvas.shape == image.shape and canvas.dtype == np.uint8
    assert not np.array_equal(canvas, image)  # something was drawn (at least the ROI)
    gray_canvas = draw_overlay(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), obs, debug, "none")
    assert gray_canvas.shape == image.shape


def test_overlay_draws_the_chosen_edges_bold(detector: LaneDetector) -> None:
    image = syn.frame(syn.STRAIGHT)
    obs, debug = detector.detect_debug(image, 0, 0.0)
    canvas = draw_overlay(image, obs, debug, "straight")
    assert obs.left is not None
    # Midpoint of the left edge is painted the left-edge colour (green).
    mx = round((obs.left.x1 + obs.left.x2) / 2)
    my = round((obs.left.y1 + obs.left.y2) / 2)
    b, g, r = canvas[my, mx].astype(int)
    assert g > 200 and b < 80 and r < 80


def test_the_ground_line_names_a_ground_model_given_to_the_detector() -> None:
    ground = GroundModel.from_fov(62.0, (320, 240),
                                  CameraPose(height_m=0.26, pitch_deg=40.0, forward_m=0.15))
    line = LaneDetector(CONFIG, ground=ground).describe_ground()
    assert line.startswith("ground model: the ground model given to the detector (h 0.260 m, "
                           "pitch 40.0°, 0.150 m ahead of the robot's centre); 320x240: "
                           "look-ahead 0.87 m (auto: edges.max_look_ahead_m); there one pixel "
                           "covers 3.6 mm across a tape where the lane's tapes run")
