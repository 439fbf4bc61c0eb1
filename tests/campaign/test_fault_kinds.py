"""Every fault kind, injected into a short run: it takes effect (logged with its frame) and the
supervisor answers. The expected answers are written out here, per kind."""

from __future__ import annotations

from typing import Any

import pytest

from lanewarden.scenarios.campaign.outcome import ANSWERS
from lanewarden.scenarios.spec import FaultKind
from tests.campaign.helpers import fault_scenario, run_judged

T = 2.0  # every timed fault starts here (the robot follows the lane by then)

#: kind -> (fault parameters, expected outcome, expected halt reason code or None)
EXPECTED: dict[str, tuple[dict[str, Any], str, str | None]] = {
    "camera_freeze": ({"at_s": T}, "safe_halt", "FRAME_FROZEN"),
    "camera_drop": ({"at_s": T}, "safe_halt", "FRAME_STALE"),
    "camera_error": ({"at_s": T}, "safe_halt", "CAMERA_ERROR"),
    "camera_ring": ({"at_s": T, "buffers": 3}, "safe_halt", "FRAME_FROZEN"),
    "late_frames": ({"at_s": T, "latency_s": 0.3}, "safe_halt", "FRAME_STALE"),
    "frame_from_future": ({"at_s": T, "latency_s": 0.5}, "safe_halt", "FRAME_INVALID"),
    "perception_exception": ({"at_s": T}, "safe_halt", "PERCEPTION_ERROR"),
    "loop_stall": ({"at_s": T, "duration_s": 0.2}, "nominal", None),
    "bumper": ({"at_s": T, "bits": 2}, "safe_halt", "BUMPER"),
    "cliff": ({"at_s": T, "bits": 1}, "safe_halt", "CLIFF"),
    "wheel_drop": ({"at_s": T, "bits": 3}, "safe_halt", "WHEEL_DROP"),
    "base_link_loss": ({"at_s": T}, "safe_halt", "BASE_LINK_LOST"),
    "operator_stop": ({"at_s": T}, "safe_halt", "OPERATOR_STOP"),
    "tape_patch": ({"at_m": 2.5, "offset_m": 0.0, "length_m": 1.0}, "nominal", None),
    "floor_mark": ({"at_m": 2.5, "width_m": 0.03, "intensity": 1.0}, "nominal", None),
    "shadow_edge": ({"at_m": 2.5, "offset_m": 0.0, "length_m": 2.0, "intensity": 0.8},
                    "nominal", None),
    "glare_sweep": ({"at_s": T, "duration_s": 1.0, "intensity": 0.9}, "nominal", None),
    # the right tape hidden for 1 s (the right 45 % of the image, bottom to top): no right
    # edge, so no trusted lane; LANE_LOST after lane_lost_halt_s (0.2 s). (With 60 % of its
    # height hidden, the tape's far part can still give the lane in some frames, depending on
    # the sensor noise: then DEGRADED and recovered, not a halt.)
    "occlusion": ({"at_s": T, "duration_s": 1.0, "intensity": 1.0, "side": "right"},
                  "safe_halt", "LANE_LOST"),
    "lens_smudge": ({"at_s": T, "intensity": 1.0}, "safe_halt", "LANE_LOST"),
    # 2.3x under-exposed for 1 s: the lane stays usable. (4x, intensity 0, leaves a frame
    # the camera's auto-exposure put at mid-grey with ~25 grey levels of tape contrast: LANE_LOST)
    "exposure_jump": ({"at_s": T, "duration_s": 1.0, "intensity": 0.15}, "nominal", None),
    "frame_rate_collapse": ({"at_s": T, "rate_hz": 2.0}, "safe_halt", "FRAME_STALE"),
    "timestamp_jump": ({"at_s": T, "jump_s": -0.5}, "safe_halt", "FRAME_INVALID"),
    "link_garbage": ({"at_s": T, "duration_s": 1.5, "intensity": 1.0}, "nominal", None),
    "checksum_storm": ({"at_s": T, "intensity": 1.0}, "safe_halt", "BASE_LINK_LOST"),
    "write_blocks": ({"at_s": T, "duration_s": 1.0}, "safe_halt", "BASE_LINK_LOST"),
    "low_battery": ({"at_s": T, "battery_v": 12.0}, "safe_halt", "BATTERY_CRITICAL"),
}


def test_every_fault_kind_has_an_expected_answer_and_answers() -> None:
    kinds = set(FaultKind.__args__)  # type: ignore[attr-defined]
    assert set(EXPECTED) == kinds
    assert set(ANSWERS) == kinds


@pytest.mark.parametrize("kind", sorted(EXPECTED))
def test_fault_takes_effect_and_the_supervisor_answers(kind: str) -> None:
    params, outcome, reason = EXPECTED[kind]
    max_time = 7.5 if "at_m" in params else 4.5
    result, verdict = run_judged(fault_scenario([{"kind": kind, **params}], max_time))
    effect = result.fault_effects.get(0)
    print(kind, verdict, effect, result.metrics.get("halt_reason"),
          result.metrics.get("states_visited"))
    assert effect is not None, f"{kind} never took effect"
    if "at_m" in params:  # seen once the robot got close enough, not from the start
        assert effect.frame_index > 30
    else:
        assert effect.frame_index == round(T * 30)  # the frame at T
    code = (result.metrics.get("halt_reason") or "").split(":")[0] or None
    assert (verdict.outcome, code) == (outcome, reason), verdict.reason
