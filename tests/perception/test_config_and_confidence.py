"""Perception config validation (through the one config loader), the confidence combination and
the decision rule."""

from __future__ import annotations

from pathlib import Path
from types import MappingProxyType

import pytest

from lanewarden.config import LanewardenConfig, load_config
from lanewarden.errors import ConfigError
from lanewarden.perception.confidence import COMPONENT_NAMES, combine
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.decision import decide
from lanewarden.perception.observation import LaneEdge, LaneObservation


@pytest.mark.parametrize(
    ("yaml_text", "expected"),
    [
        ("blur: {kernel_px: 4}", "perception.blur.kernel_px = 4: must be an odd"),
        ("canny: {low_threshold: 150, high_threshold: 100}", "must be below high_threshold"),
        ("canny: {aperture_px: 4}", "must be 3, 5 or 7"),
        ("canny: {low_treshold: 10}", "unknown key 'perception.canny.low_treshold'"),
        ("roi: {polygon_norm: [[0, 1], [1, 1]]}", "unknown key 'perception.roi.polygon_norm'"),
        ("roi: {near_m: 2.0, far_m: 1.0}", "near_m (2) must be below far_m (1)"),
        ("roi: {lateral_m: 0}", "perception.roi.lateral_m = 0"),
        ("tape: {width_min_frac_of_width: 0.2}", "unknown key 'perception.tape.width_min_frac"),
        ("tape: {width_m: 0.002}", "perception.tape.width_m = 0.002"),
        ("tape: {max_seam_width_m: 0.045}", "max_seam_width_m (0.045) must be below the narrowest"),
        ("tape: {width_m: 0.03, max_seam_width_m: 0.026}", "width_tolerance_fraction) = 0.0255"),
        # One tape's own two edges (up to 69 mm apart) must never score as the lane's free
        # width: the narrowest lane is (60 + 69) / (1 - 2 x 0.15) = 184.3 mm, next mm up.
        ("tape: {width_m: 0.06}\n  lane: {width_m: 0.11}",
         "lane.width_m (0.11) is too narrow for 60 mm tape: with lane.width_tolerance_fraction "
         "0.15 a gap of 17 mm between the two edges would still count as the lane, and one "
         "tape's own two edges measure up to 69 mm apart; expected lane.width_m of at least "
         "0.185 m"),
        ("tape: {width_m: 0.048, right_width_m: 0.06}\n  lane: {width_m: 0.17}",
         "lane.width_m (0.17) is too narrow for 60 mm tape"),
        ("lane: {width_tolerance_m: 0.1}",
         "unknown key 'perception.lane.width_tolerance_m': did you mean "
         "'perception.lane.width_tolerance_fraction'?"),
        ("lane: {width_tolerance_fraction: 0.5}", "perception.lane.width_tolerance_fraction = 0.5"),
        ("tape: {left_width_m: 0.025, max_seam_width_m: 0.022}",
         "max_seam_width_m (0.022) must be below the narrowest tape, the narrower tape x (1 - "
         "width_tolerance_fraction) = 0.02125 m"),
        ("tape: {right_width_m: 0.3}", "perception.tape.right_width_m = 0.3"),
        ("lane: {horizon_y_norm: 0.3}", "unknown key 'perception.lane.horizon_y_norm'"),
        ("lane: {dashed_side: centre}",
         "perception.lane.dashed_side = 'centre': input should be 'left', 'right' or 'both'"),
        ("edges: {look_ahead_y_norm: 0.4}", "unknown key 'perception.edges.look_ahead_y_norm'"),
        ("edges: {look_ahead_m: -1}", "perception.edges.look_ahead_m = -1: expected a distance "
         "in metres above 0 and at most 10, or auto"),
        ("edges: {look_ahead_m: far}", "perception.edges.look_ahead_m = 'far': expected a"),
        ("edges: {max_look_ahead_m: 1.7}",
         "edges.max_look_ahead_m (1.7) must lie within the region of interest"),
        ("contrast: {max_gain: 0.5}", "perception.contrast.max_gain = 0.5"),
        ("edges: {look_ahead_m: 2.0}", "edges.look_ahead_m (2) must lie within the region of"),
        ("confidence: {min_confidence: 0.5}",
         "unknown key 'perception.confidence.min_confidence'"),  # trust is the supervisor's
        ("tape: {width_m: .inf}", "perception.tape.width_m"),
        ("confidence: {weights: {tape_pair: -1}}", "perception.confidence.weights.tape_pair"),
        ("edges: {max_abs_slope: 2.5}", "two clamped slopes could never reach"),  # vs supervisor
        ("hough: {votes_frac_of_height: 0}", "perception.hough.votes_frac_of_height = 0"),
    ],
)
def test_bad_perception_values_name_key_value_and_expectation(
    yaml_text: str, expected: str, tmp_path: Path
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("perception:\n  " + yaml_text + "\n")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    message = str(info.value)
    assert expected in message
    assert str(path) in message


def test_defaults_round_trip_and_partial_override(tmp_path: Path) -> None:
    path = tmp_path / "ok.yaml"
    path.write_text(
        "perception:\n"
        "  blur: {kernel_px: 7}\n"
        "  roi: {far_m: 1.2}\n"
        "  tape: {width_m: 0.025}\n"
    )
    config = load_config(path).perception
    assert config.blur.kernel_px == 7
    assert (config.roi.near_m, config.roi.far_m, config.roi.lateral_m) == (0.0, 1.2, 0.65)
    # The seam bound follows the tape unless it is set: half the tape, the narrower one when
    # the sides differ.
    assert config.tape.seam_width_m == 0.0125
    assert LanewardenConfig().perception.tape.seam_width_m == 0.024
    duck = PerceptionConfig.model_validate({"tape": {"left_width_m": 0.025}}).tape
    assert duck.seam_width_m == 0.0125
    assert (duck.for_side("left").width_m, duck.for_side("right").width_m) == (0.025, 0.048)
    assert duck.for_side("right").seam_width_m == 0.0125  # one floor, one widest seam
    # The look-ahead is chosen by the detector unless set.
    assert config.edges.look_ahead_m == "auto"
    assert config.edges.max_look_ahead_m == 0.87
    assert config.canny == PerceptionConfig().canny  # untouched sections keep defaults


def _components(**overrides: float) -> MappingProxyType[str, float]:
    values = dict.fromkeys(COMPONENT_NAMES, 1.0)
    values.update(overrides)
    return MappingProxyType(values)


def test_confidence_is_a_weighted_geometric_product() -> None:
    assert COMPONENT_NAMES == (
        "both_sides", "support_left", "support_right", "lane_width", "parallel",
        "tape_pair_left", "tape_pair_right", "verified_tape", "floor_between", "heading",
        "consistency",
    )
    config = PerceptionConfig()
    assert combine(_components(), config) == 1.0
    # Weight 0.5 on lane_width: 0.25 ** 0.5.
    assert combine(_components(lane_width=0.25), config) == pytest.approx(0.5)
    # Per-side components share their weight (tape_pair 1.0 -> 0.5 each side).
    assert combine(_components(tape_pair_left=0.25), config) == pytest.approx(0.5)
    # A zero in a weighted component is a veto.
    assert combine(_components(tape_pair_right=0.0), config) == 0.0
    # Weight 0 ignores a component entirely.
    ignore = config.model_copy(
        update={
            "confidence": config.confidence.model_copy(
                update={"weights": config.confidence.weights.model_copy(update={"tape_pair": 0.0})}
            )
        }
    )
    assert combine(_components(tape_pair_right=0.0), ignore) == 1.0
    # verified_tape and floor_between have no weight: always full gates.
    assert combine(_components(verified_tape=0.0), ignore) == 0.0
    assert combine(_components(floor_between=0.0), ignore) == 0.0


def _observation(slope_sum: float | None, confidence: float) -> LaneObservation:
    edge = LaneEdge(0.0, 100.0, 10.0, 0.0, 1.0)
    return LaneObservation(
        frame_index=0,
        time_s=0.0,
        left=edge if slope_sum is not None else None,
        right=edge if slope_sum is not None else None,
        slope_sum=slope_sum,
        confidence=confidence,
    )


@pytest.mark.parametrize(
    ("slope_sum", "confidence", "expected"),
    [
        (0.0, 0.9, "straight"),
        (-6.0, 0.9, "straight"),  # the lecture: strictly below -6 turns right
        (-6.01, 0.9, "right"),
        (6.01, 0.9, "left"),
        (-11.0, 0.49, "right"),
        (-11.0, 0.19, "none"),  # below the trust threshold: no decision, however strong
        (None, 1.0, "none"),
    ],
)
def test_decision_rule(slope_sum: float | None, confidence: float, expected: str) -> None:
    # The thresholds are the supervisor's (confidence_usable_min 0.2, turn_enter_slope_sum 6),
    # passed in by the composition root.
    observation = _observation(slope_sum, confidence)
    assert decide(observation, trust_min_confidence=0.2, turn_slope_sum=6.0) == expected
