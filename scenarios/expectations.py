"""Checking a run's metrics against the scenario's expected outcome (`expect:` in the YAML).

Pure: metrics dict in, list of one-line failures out (empty: the expectation is met).
"""

from __future__ import annotations

from collections.abc import Mapping

from lanewarden.scenarios.spec import Expectation


def _number(metrics: Mapping[str, object], key: str) -> float | None:
    value = metrics.get(key)
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None


def check_expectation(metrics: Mapping[str, object], expect: Expectation) -> list[str]:
    """Every way `metrics` misses `expect`, one line each."""
    failures: list[str] = []
    halted = bool(metrics.get("halted"))
    reason = str(metrics.get("halt_reason") or "")
    if expect.halted is not None and halted != expect.halted:
        failures.append(
            f"halted = {halted}, expected {expect.halted}"
            + (f" (reason: {reason})" if halted else "")
        )
    # HALT is the controller's state: whatever else is expected, a robot that halted must stop
    # (a base whose commands no longer arrive drives on; a campaign calls that run unsafe)
    if halted and (moving := metrics.get("motion_after_halt")):
        failures.append(f"halted = True, but the robot did not stop: {moving}")
    if expect.halt_reason_any_of and not any(k in reason for k in expect.halt_reason_any_of):
        failures.append(
            f"halt_reason = {reason or None!r}, expected one containing "
            f"{' or '.join(expect.halt_reason_any_of)}"
        )
    if expect.turns_completed is not None:
        done = list(metrics.get("turns_completed") or [])  # type: ignore[call-overload]
        if done != list(expect.turns_completed):
            failures.append(f"turns_completed = {done}, expected {expect.turns_completed}")

    def at_most(key: str, limit: float | None, metric: str | None = None) -> None:
        if limit is None:
            return
        value = _number(metrics, metric or key)
        if value is None or value > limit:
            failures.append(f"{metric or key} = {value}, expected at most {limit}")

    def at_least(key: str, limit: float | None) -> None:
        if limit is None:
            return
        value = _number(metrics, key)
        if value is None or value < limit:
            failures.append(f"{key} = {value}, expected at least {limit}")

    at_most("max_cross_track_error_m", expect.max_cross_track_error_m)
    at_most("distance_past_lane_end_m", expect.max_distance_past_lane_end_m)
    at_least("distance_past_lane_end_m", expect.min_distance_past_lane_end_m)
    at_least("distance_travelled_m", expect.min_distance_travelled_m)
    at_most("distance_travelled_m", expect.max_distance_travelled_m)
    at_most("lane_loss_to_halt_s", expect.max_lane_loss_to_halt_s)
    at_most("halt_time_s", expect.halted_before_s)
    if expect.crossed_tape is not None and bool(metrics.get("crossed_tape")) != expect.crossed_tape:
        failures.append(f"crossed_tape = {metrics.get('crossed_tape')}, "
                        f"expected {expect.crossed_tape}")
    visited = set(metrics.get("states_visited") or [])  # type: ignore[call-overload]
    for state in expect.states_visited_include:
        if state not in visited:
            failures.append(f"states_visited = {sorted(visited)}, expected to include {state}")
    for state in expect.states_visited_exclude:
        if state in visited:
            failures.append(f"states_visited = {sorted(visited)}, expected no {state}")
    counts = metrics.get("event_counts") or {}
    assert isinstance(counts, Mapping)
    for event in expect.events_include:
        if not counts.get(event):
            failures.append(f"event {event} never raised (events: {sorted(counts)})")
    return failures
