"""One campaign case, run and judged: what a campaign worker executes (and `sim --case` reuses).

`run_case(case_json, build_stack)` builds the config and scenario from the case, runs the
simulation without video or plot (nothing a campaign does not need) with the composition root's
stack, judges the outcome and returns one result row
(plain JSON-ready data). Any exception inside the run becomes an `error` row with its one-line
reason: a worker never dies of a bad case. CPU and wall time are measured here for the report
(they never feed the simulation).
"""

from __future__ import annotations

import json
import os
import socket
import time
from typing import TYPE_CHECKING, Any

from lanewarden.scenarios.campaign.cases import Case
from lanewarden.scenarios.campaign.config import CampaignConfig
from lanewarden.scenarios.campaign.outcome import Limits, RunFacts, Verdict, classify

if TYPE_CHECKING:
    from lanewarden.assembly import BuildStack
    from lanewarden.config import LanewardenConfig
    from lanewarden.scenarios.simulator import SimulationResult

#: Result row columns that are the same wherever and whenever a case runs (the rest: timings and
#: the worker's name).
DETERMINISTIC_COLUMNS = ("id", "idx", "scenario", "camera", "floor", "tape", "effect", "seed",
                         "fault_kinds", "outcome",
                         "reason", "halt_reason", "halt_time_s", "time_to_halt_s",
                         "sim_time_s", "frames", "metrics_json", "effects_json")


def case_columns(case: Case) -> dict[str, Any]:
    """The result row's columns that say which case it is."""
    return {"id": case.id, "idx": case.index, "scenario": str(case.scenario.get("name")),
            "camera": case.camera, "floor": case.floor, "tape": case.tape,
            "effect": case.effect, "seed": case.seed,
            "fault_kinds": ",".join(case.fault_kinds)}


def judge(result: SimulationResult, config: LanewardenConfig) -> Verdict:
    """The outcome class of a finished simulation (`scenarios.campaign.outcome`)."""
    records = result.records
    facts = RunFacts(
        faults=result.spec.faults,
        states=[r.state for r in records],
        times=[r.time_s for r in records],
        halt_reasons=[r.halt_reason for r in records],
        commands_nonzero=[not r.command.is_stop for r in records],
        effects={i: e.time_s for i, e in result.fault_effects.items()},
        windows=result.fault_windows,
        metrics=result.metrics,
        markings_end_s=result.world.markings_end_s,
        end_reason=result.end_reason,
        final_speed_m_s=float(result.trace.speed_m_s[-1]) if len(result.trace.speed_m_s) else 0.0,
        lane_visible=None if result.trace.lane_visible is None else [
            bool(v) for v in result.trace.lane_visible],
        tape_clearance_m=tape_clearance_m(result),
        frame_index=[r.frame_index for r in records],
    )
    campaign: CampaignConfig = getattr(config, "campaign", CampaignConfig())
    limits = Limits(config.supervisor, config.actuation.write_timeout_s)
    return classify(facts, campaign, limits)


def tape_clearance_m(result: SimulationResult) -> list[float]:
    """Per step: how far the robot's footprint was from the nearest tape edge (ground truth, m;
    negative: over it)."""
    from lanewarden.scenarios.metrics import footprint_clearance_m

    poses = result.trace.poses
    if not len(poses):
        return []
    return [float(c) for c in footprint_clearance_m(result.world, poses)]


def case_config(case: Case, source: str) -> LanewardenConfig:
    from lanewarden.config import config_from_mapping

    return config_from_mapping(case.config, f"{source}: config")


def run_case(case_json: str, build_stack: BuildStack) -> dict[str, Any]:
    """Run one case (its JSON) with the composition root's `build_stack` and return its result
    row."""
    started_cpu, started_wall = time.process_time(), time.perf_counter()
    case = Case.model_validate_json(case_json)
    row: dict[str, Any] = {**case_columns(case),
                           "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        from lanewarden.scenarios.simulator import Simulation, effective_config

        spec = case.scenario_spec(case.id)
        config = effective_config(case_config(case, case.id), spec)
        result = Simulation(spec, config, build_stack, controller=case.controller,
                            seed=case.seed).run()
        verdict = judge(result, config)
    except Exception as exc:  # a bad case is an error row, never a dead worker
        text = " ".join(str(exc).split())
        row.update(outcome="error", reason=f"{type(exc).__name__}: {text}"[:500],
                   halt_reason=None, halt_time_s=None, time_to_halt_s=None, sim_time_s=None,
                   frames=0, metrics_json="{}", effects_json="[]")
    else:
        times = result.trace.time_s
        row.update(
            outcome=verdict.outcome, reason=verdict.reason,
            halt_reason=result.metrics.get("halt_reason"),
            halt_time_s=verdict.halt_time_s, time_to_halt_s=verdict.time_to_halt_s,
            sim_time_s=round(float(times[-1]), 4) if len(times) else 0.0,
            frames=len(result.records),
            metrics_json=json.dumps(result.metrics, sort_keys=True, default=str),
            effects_json=json.dumps([e.as_json() for _, e in sorted(
                result.fault_effects.items())]),
        )
    row["cpu_s"] = round(time.process_time() - started_cpu, 3)
    row["wall_s"] = round(time.perf_counter() - started_wall, 3)
    return row


def judge_metrics(result: SimulationResult, config: LanewardenConfig) -> dict[str, object]:
    """`judge` as metrics.json keys (for `lanewarden sim --case`)."""
    verdict = judge(result, config)
    return {"outcome": verdict.outcome, "outcome_reason": verdict.reason,
            "time_to_halt_s": verdict.time_to_halt_s}  # (fault_effects: every run's metrics)
