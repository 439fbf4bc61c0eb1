"""The outcome class of one simulated run, judged from ground truth (pure: data in, verdict out).

Classes, checked in this order (the first that applies):

- `error`: the run did not test what it was meant to: it raised, a fault never took effect, or
  the supervisor never engaged, or the run ended while still DEGRADED (undecided).
- `unsafe`: the robot crossed a tape; ended more than `max_past_lane_end_m` past the end of the
  tape; a non-zero command left the controller after its HALT, or the robot still moved
  STOPPED_AFTER_S after it (a stop that never reached the motors); or a hazard the supervisor must
  answer (`MUST_HALT`) was not answered by HALT within its detection limit plus
  `hazard_halt_deadline_s` after it took effect, that time moved on by as long as a loop stall
  hung the control process within it (`stalled_within`: a hung loop answers nothing; what stops
  a robot whose control process hangs is the dead-man process, benchmarks/deadman_latency.py).
- `safe_halt`: halted, for a reason that matches a fault acting then (`ANSWERS`, up to
  `fault_grace_s` after the fault stopped acting) or for real lane loss (LANE_LOST or
  DEGRADED_BUDGET_EXHAUSTED with the robot within `lane_end_window_m` of the end of the tape), or
  a lane halt while the camera showed no lane (`blind_halt`, below), or LANE_DEPARTURE with the
  robot's footprint within `departure_near_m` of a tape in the second before (it was leaving
  the lane; a departure halt farther from every tape is false).
- `false_halt`: halted, with no fault and a good lane to explain it.
- `recovered`: went DEGRADED at some point and was following again at the end, never halted.
- `nominal`: never DEGRADED, never halted.

A blind halt: LANE_LOST or DEGRADED_BUDGET_EXHAUSTED while the frames the camera delivered did
not show the lane (a step that got no new frame showed nothing: `lane_shown_per_step`;
`RunFacts.lane_visible`, the simulator's ground truth per frame:
`scenarios.metrics.LaneContrast`, every tape standing out from the floor beside it by a contrast
the detector can use): in NO frame of the last `lane_lost_halt_s` before the halt (the
supervisor's own window: it halts LANE_LOST because no frame in it gave a usable lane; had the
camera shown the lane in one of them, the detector missed it, and the halt stays false), and for
DEGRADED_BUDGET_EXHAUSTED also in at most half of the frames of the DEGRADED stretch that ran
out (a budget spent mostly on frames that did show the lane is the detector's doing). Every frame
of the window, not most: the measure is a bound in the detector's favour, so a frame it calls
visible may still have been hard, but a halt after even one usable frame is not excused. Whatever
blinded the camera (a light switched up faster than the auto-exposure follows, a flat floor)
does not matter, nor when: a dark tape still darker than a saturated floor is visible, and a
halt then stays false. Its reason says `BLIND_REASON` (`blind_halt` reads it back).

Never reads a clock and never runs anything.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

from lanewarden.scenarios.campaign.config import CampaignConfig
from lanewarden.scenarios.metrics import first_halt_index, motion_after_halt
from lanewarden.scenarios.spec import FaultSpec
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.wording import counted

OUTCOMES = ("safe_halt", "recovered", "nominal", "false_halt", "unsafe", "error")
#: Outcomes a campaign counts as failures of the supervisor (JUnit <failure>).
FAILURES = ("false_halt", "unsafe")

_LANE = ("LANE_LOST", "DEGRADED_BUDGET_EXHAUSTED")
#: A fault on the floor may also put a false edge inside the robot's footprint.
_FLOOR = (*_LANE, "LANE_DEPARTURE")
#: Halt reasons that are a right answer to each fault kind while it acts.
ANSWERS: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "camera_freeze": ("FRAME_FROZEN", "FRAME_STALE", *_LANE),
    "camera_ring": ("FRAME_FROZEN", "FRAME_STALE", *_LANE),
    "camera_drop": ("FRAME_STALE",),
    "camera_error": ("CAMERA_ERROR",),
    "late_frames": ("FRAME_STALE", *_LANE),
    "frame_from_future": ("FRAME_INVALID",),
    "perception_exception": ("PERCEPTION_ERROR",),
    "loop_stall": ("FRAME_STALE", *_LANE),
    "bumper": ("BUMPER",),
    "cliff": ("CLIFF",),
    "wheel_drop": ("WHEEL_DROP",),
    "base_link_loss": ("BASE_LINK_LOST",),
    "operator_stop": ("OPERATOR_STOP",),
    "tape_patch": _FLOOR,
    "floor_mark": _FLOOR,
    "shadow_edge": _FLOOR,
    "glare_sweep": _FLOOR,
    "occlusion": _FLOOR,
    "lens_smudge": _FLOOR,
    "exposure_jump": ("FRAME_FROZEN", *_LANE),
    "frame_rate_collapse": ("FRAME_STALE", *_LANE),
    "timestamp_jump": ("FRAME_INVALID", "FRAME_STALE", *_LANE),
    "link_garbage": ("BASE_LINK_LOST",),
    "checksum_storm": ("BASE_LINK_LOST",),
    "write_blocks": ("BASE_LINK_LOST",),
    "low_battery": ("BATTERY_CRITICAL",),
})


@dataclass(frozen=True)
class Limits:
    """What a must-halt rule needs to know: the supervisor's detection limits and the port's
    write timeout (the quantities live in their own sections; read, never copied)."""

    supervisor: SupervisorConfig
    write_timeout_s: float


def _instant(spec: FaultSpec, limits: Limits) -> float | None:
    return 0.0 if _lasts(spec, 2 * limits.supervisor.camera_period_s) else None


def _lasts(spec: FaultSpec, at_least_s: float) -> bool:
    return spec.duration_s is None or spec.duration_s >= at_least_s


def _after(limit: Callable[[Limits], float]) -> Callable[[FaultSpec, Limits], float | None]:
    def rule(spec: FaultSpec, limits: Limits) -> float | None:
        detect = limit(limits)
        return detect if _lasts(spec, detect + 2 * limits.supervisor.camera_period_s) else None
    return rule


def _jump(spec: FaultSpec, limits: Limits) -> float | None:
    big = abs(spec.jump_s) >= 2 * limits.supervisor.camera_period_s
    return 0.0 if big and _lasts(spec, 2 * limits.supervisor.camera_period_s) else None


def _collapse(spec: FaultSpec, limits: Limits) -> float | None:
    stale = limits.supervisor.frame_stale_s
    if 1.0 / spec.rate_hz <= stale + 2 * limits.supervisor.camera_period_s:
        return None
    return stale if _lasts(spec, 1.0 / spec.rate_hz) else None


def _storm(spec: FaultSpec, limits: Limits) -> float | None:
    if spec.intensity < 1.0:
        return None
    return _after(lambda lim: lim.supervisor.base_link_timeout_s)(spec, limits)


def _late(spec: FaultSpec, limits: Limits) -> float | None:
    stale = limits.supervisor.frame_stale_s
    if spec.latency_s <= stale + limits.supervisor.camera_period_s:
        return None
    return stale if _lasts(spec, stale + 2 * limits.supervisor.camera_period_s) else None


#: Hazards the supervisor MUST answer with HALT: kind -> (fault, limits) -> its detection limit
#: in seconds after the fault took effect, or None when this instance need not halt (too short,
#: too mild). The deadline is that limit plus `hazard_halt_deadline_s`.
MUST_HALT: Mapping[str, Callable[[FaultSpec, Limits], float | None]] = MappingProxyType({
    "bumper": _instant,
    "cliff": _instant,
    "wheel_drop": _instant,
    "operator_stop": lambda spec, limits: 0.0,
    "camera_error": _instant,
    "perception_exception": _instant,
    "frame_from_future": _instant,
    "camera_drop": _after(lambda lim: lim.supervisor.frame_stale_s),
    "camera_freeze": _after(lambda lim: lim.supervisor.frame_frozen_s),
    "camera_ring": _after(lambda lim: lim.supervisor.frame_frozen_s),
    "base_link_loss": _after(lambda lim: lim.supervisor.base_link_timeout_s),
    "write_blocks": _after(lambda lim: lim.write_timeout_s),
    "checksum_storm": _storm,
    "timestamp_jump": _jump,
    "frame_rate_collapse": _collapse,
    "late_frames": _late,
})


@dataclass(frozen=True)
class RunFacts:
    """One finished run as the judge sees it.

    `states`/`times`/`commands_nonzero` per control step; `effects`: fault index -> time it took
    effect; `windows`: (index, kind, from_s, to_s) while each fault acted; `metrics`: the run's
    ground-truth metrics (crossed_tape, distance_past_lane_end_m, stop_lane_s_m, ...);
    `markings_end_s`: where the tape ends along the lane (None: it never ends)."""

    faults: Sequence[FaultSpec]
    states: Sequence[str]
    times: Sequence[float]
    halt_reasons: Sequence[str | None]
    commands_nonzero: Sequence[bool]
    effects: Mapping[int, float]
    windows: Sequence[tuple[int, str, float, float]]
    metrics: Mapping[str, object]
    markings_end_s: float | None
    end_reason: str
    #: the base's true speed at the end of the run (m/s)
    final_speed_m_s: float = 0.0
    #: per captured frame (its index): did it show the lane (None: not measured, no blind
    #: halts); the simulator captures frame k at control step k
    lane_visible: Sequence[bool] | None = None
    #: per control step: the robot footprint's distance to the nearest tape edge, ground truth
    #: (m; None: not measured, no LANE_DEPARTURE halt is right)
    tape_clearance_m: Sequence[float] | None = None
    #: per control step: the index of the newest frame the loop had (None: none yet); a step
    #: whose index is the step before's got no new frame (dropped, late, or none yet). None:
    #: not recorded, every step analysed its own frame k.
    frame_index: Sequence[int | None] | None = None


@dataclass(frozen=True)
class Verdict:
    outcome: str
    reason: str
    #: first HALT after engagement (s), None if it never halted
    halt_time_s: float | None = None
    #: HALT minus the moment the fault it answered took effect (a safe halt), or the hazard
    #: it came too late for (unsafe), in s; None otherwise (no halt, no fault it answered, e.g.
    #: a halt at the end of the tape)
    time_to_halt_s: float | None = None

    def as_json(self) -> dict[str, object]:
        return {"outcome": self.outcome, "reason": self.reason,
                "halt_time_s": self.halt_time_s, "time_to_halt_s": self.time_to_halt_s}


def _code(reason: str | None) -> str:
    return (reason or "").split(":")[0].strip()


_ANSWERING = re.compile(r" answering (\w+) \(fault \d+\)")


def answering_reason(code: str, kind: str, index: int) -> str:
    """A safe halt's reason: the halt code and the fault it answered."""
    return f"{code} answering {kind} (fault {index})"


def answered_kind(reason: str) -> str | None:
    """The fault kind a safe halt answered, read back from `answering_reason`'s text (None for
    any other reason, e.g. a halt at the end of the tape)."""
    found = _ANSWERING.search(reason)
    return found.group(1) if found else None


def classify(facts: RunFacts, config: CampaignConfig, limits: Limits) -> Verdict:
    """The run's outcome class and a one-line reason (see the module docstring)."""
    missing = [f"{i}:{f.kind}" for i, f in enumerate(facts.faults) if i not in facts.effects]
    if missing:
        return Verdict("error", "fault never took effect: " + ", ".join(missing))
    if not any(s != "HALT" for s in facts.states):
        return Verdict("error", f"never engaged ({facts.end_reason})")
    halt = first_halt_index(facts.states) or None  # (0: never engaged, refused above)
    halt_s = None if halt is None else float(facts.times[halt])

    def verdict(outcome: str, reason: str, answered: int | None = None) -> Verdict:
        """`answered`: the fault the halt answered (or was due for); time to halt from it."""
        effect = None if answered is None else facts.effects.get(answered)
        to_halt = None if halt_s is None or effect is None else round(halt_s - effect, 4)
        return Verdict(outcome, reason, None if halt_s is None else round(halt_s, 4), to_halt)

    metrics = facts.metrics
    if metrics.get("crossed_tape"):
        return verdict("unsafe", "crossed a tape")
    past = metrics.get("distance_past_lane_end_m")
    if isinstance(past, int | float) and past > config.max_past_lane_end_m:
        return verdict("unsafe", f"ended {past:.2f} m past the end of the tape "
                                 f"(limit {config.max_past_lane_end_m:g} m)")
    moving = motion_after_halt(facts.times, facts.states, facts.commands_nonzero,
                               facts.final_speed_m_s)  # (the same rule `sim --check` applies)
    if moving is not None:
        return verdict("unsafe", moving)
    unanswered = _unanswered_hazard(facts, config, limits, halt_s)
    if unanswered is not None:
        return verdict("unsafe", *unanswered)
    if halt is not None:
        code = _code(facts.halt_reasons[halt])
        assert halt_s is not None
        for index, kind, start, end in facts.windows:
            if start - 1e-9 <= halt_s <= end + config.fault_grace_s and code in ANSWERS[kind]:
                return verdict("safe_halt", answering_reason(code, kind, index), index)
        if code in _LANE and _near_lane_end(facts, config):
            return verdict("safe_halt", f"{code} at the end of the tape")
        near = _departure_near(facts, halt, code, config)
        if near is not None:
            return verdict("safe_halt", f"{code} at {halt_s:.3f} s: the robot's footprint came "
                                        f"within {near:.3f} m of a tape")
        blind = _blind_window(facts, halt, code, limits)
        if blind is not None:
            return verdict("safe_halt", f"{code} at {halt_s:.3f} s: {BLIND_REASON} {blind}")
        return verdict("false_halt", f"{code} at {halt_s:.3f} s with no fault acting and the "
                                     "tape in place")
    visited = set(facts.states)
    if "DEGRADED" in visited:
        if facts.states[-1] == "DEGRADED":
            return verdict("error", "still DEGRADED when the run ended (undecided)")
        return verdict("recovered", "DEGRADED, then following again")
    return verdict("nominal", "followed the lane throughout")


def _unanswered_hazard(facts: RunFacts, config: CampaignConfig, limits: Limits,
                       halt_s: float | None) -> tuple[str, int] | None:
    """The first hazard not answered by HALT in time: (the reason, its fault's index)."""
    for index, spec in enumerate(facts.faults):
        rule = MUST_HALT.get(spec.kind)
        effect = facts.effects.get(index)
        if rule is None or effect is None:
            continue
        limit = rule(spec, limits)
        if limit is None:
            continue
        deadline = effect + limit + config.hazard_halt_deadline_s
        deadline += stalled_within(facts.windows, effect, deadline)
        run_end = float(facts.times[-1]) if facts.times else 0.0
        if deadline > run_end + 1e-9:
            continue  # the run ended first (settled after another halt, or the time limit)
        if halt_s is None or halt_s > deadline + 1e-9:
            when = "never" if halt_s is None else f"at {halt_s:.3f} s"
            return (f"{spec.kind} (fault {index}) took effect at {effect:.3f} s: HALT due by "
                    f"{deadline:.3f} s, came {when}", index)
    return None


def stalled_within(windows: Sequence[tuple[int, str, float, float]], start_s: float,
                   end_s: float) -> float:
    """How long loop stalls (`windows`: (index, kind, from, to) of the faults that acted) hung
    the control process between `start_s` and the deadline `end_s`, that deadline moving on by
    the stalls already counted (a stall that begins in the extra time counts too): the time no
    control step ran, in which no halt could come from the loop."""
    stalls = sorted((s, e) for _, kind, s, e in windows if kind == "loop_stall")
    extra = 0.0
    for stall_from, stall_to in stalls:
        if stall_to <= start_s or stall_from >= end_s + extra:
            continue
        extra += min(stall_to, end_s + extra) - max(stall_from, start_s)
    return extra


#: How a blind halt's reason names it (after the halt code and time).
BLIND_REASON = "camera showed no lane contrast"


def blind_halt(reason: str) -> bool:
    """Is this a safe halt's reason for a halt while the camera showed no lane?"""
    return BLIND_REASON in reason


def _blind_window(facts: RunFacts, halt: int, code: str, limits: Limits) -> str | None:
    """Why a lane halt at step `halt` was blind (the rest of its reason), or None when the
    camera showed the lane (see the module docstring)."""
    if facts.lane_visible is None or code not in _LANE:
        return None
    shown, new = lane_shown_per_step(facts.lane_visible, facts.frame_index, len(facts.times))
    halt_s = float(facts.times[halt])
    window_s = limits.supervisor.lane_lost_halt_s
    last = [i for i in range(halt + 1) if halt_s - window_s + 1e-9 < float(facts.times[i])]
    if not last or any(shown[i] for i in last):
        return None
    missing = sum(1 for i in last if not new[i])
    why = (f"the detector could use in any of the last {counted(len(last), 'frame')} "
           f"({window_s:g} s)" if not missing else
           f"the detector could use in the last {window_s:g} s "
           f"({counted(len(last) - missing, 'frame')}; {counted(missing, 'step')} got no new "
           "frame)")
    if code == "DEGRADED_BUDGET_EXHAUSTED":
        start = halt
        while start > 0 and facts.states[start - 1] == "DEGRADED":
            start -= 1
        stretch = range(start, halt)
        seen = sum(1 for i in stretch if shown[i])
        if 2 * seen > len(stretch):
            return None
        why += f"; lane shown in {seen} of the {len(stretch)} DEGRADED frames"
    return why


def lane_shown_per_step(frame_visible: Sequence[bool], frame_index: Sequence[int | None] | None,
                        steps: int) -> tuple[list[bool], list[bool]]:
    """Per control step: (whether the loop got a new frame at it that showed the lane, whether
    it got a new frame at all). `frame_visible`: per captured frame, by its index;
    `frame_index`: per step, the newest frame the loop had (None: every step k got frame k).
    A step that got no new frame showed the detector nothing, whatever the camera captured
    then: a dropped frame's picture never reached perception (campaign run r00331 of the
    thirty-first run: three frames dropped, then three blinded by a light switched up, and
    the dropped ones had counted as showing the lane)."""
    if frame_index is None:
        return [bool(v) for v in frame_visible[:steps]], [True] * steps
    shown, new = [], []
    before: int | None = None
    for index in frame_index[:steps]:
        fresh = index is not None and index != before
        new.append(fresh)
        shown.append(fresh and index is not None and 0 <= index < len(frame_visible)
                     and bool(frame_visible[index]))
        before = index
    return shown, new


#: How long before a LANE_DEPARTURE halt the judge looks for the robot near a tape, s.
DEPARTURE_LOOKBACK_S = 1.0


def _departure_near(facts: RunFacts, halt: int, code: str,
                    config: CampaignConfig) -> float | None:
    """For a LANE_DEPARTURE halt: the footprint's least clearance to a tape in the last
    DEPARTURE_LOOKBACK_S before it when that was `departure_near_m` or less (the robot was
    leaving the lane), else None (a departure seen where there was none)."""
    clearance = facts.tape_clearance_m
    if clearance is None or code != "LANE_DEPARTURE":
        return None
    halt_s = float(facts.times[halt])
    recent = [clearance[i] for i in range(halt + 1)
              if halt_s - DEPARTURE_LOOKBACK_S - 1e-9 <= float(facts.times[i])]
    least = min(recent, default=math.inf)
    return least if least <= config.departure_near_m else None


def _near_lane_end(facts: RunFacts, config: CampaignConfig) -> bool:
    if facts.markings_end_s is None:
        return False
    stop_s = facts.metrics.get("stop_lane_s_m")
    return isinstance(stop_s, int | float) and math.isfinite(stop_s) and (
        stop_s >= facts.markings_end_s - config.lane_end_window_m)
