"""Small, fast campaign runs for the tests: a short straight lane at 320x240."""

from __future__ import annotations

from typing import Any

from lanewarden.assembly import build_stack
from lanewarden.config import config_from_mapping
from lanewarden.scenarios.campaign.outcome import Verdict
from lanewarden.scenarios.campaign.run_case import judge
from lanewarden.scenarios.simulator import Simulation, SimulationResult, effective_config
from lanewarden.scenarios.spec import ScenarioSpec, parse_scenario

SMALL_CONFIG: dict[str, Any] = {"simulation": {"width_px": 320, "height_px": 240,
                                               "progress": False}}


def fault_scenario(faults: list[dict[str, Any]], max_time_s: float = 4.5,
                   length_m: float = 6.0) -> ScenarioSpec:
    return parse_scenario({"name": "fault-test", "lane": {"segments": [{"straight_m": length_m}]},
                           "run": {"max_time_s": max_time_s}, "faults": faults}, "test.yaml")


def run_judged(spec: ScenarioSpec, seed: int = 0) -> tuple[SimulationResult, Verdict]:
    config = effective_config(config_from_mapping(SMALL_CONFIG), spec)
    result = Simulation(spec, config, build_stack, seed=seed).run()
    return result, judge(result, config)
