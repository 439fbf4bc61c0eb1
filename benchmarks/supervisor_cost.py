"""CPU seconds the supervisor costs in a simulated run: `ControlLoop.step` minus its `_perceive`.

A warm 20 s `straight` run at 320x240 (600 steps), the quantity issue 11 budgets: everything the
loop does per step except reading the frame and running perception (the SafetyGate, the
supervised controller, its filter, watchdog and state machine, the record). Two ways:
- timed: process CPU time around each step and each `_perceive`, no profiler (best of the runs);
- profiled: cProfile's cumulative time of `step` minus `_perceive` (inflated by the profiler,
  which charges every Python call; comparable only with itself).

On demand only:
    python benchmarks/supervisor_cost.py [--runs N] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from collections.abc import Callable
from typing import Any

from lanewarden.assembly import build_stack
from lanewarden.config import config_from_mapping
from lanewarden.scenarios.library import resolve_scenario
from lanewarden.scenarios.simulator import Simulation, effective_config


def simulation() -> Simulation:
    spec = resolve_scenario("straight")
    spec = spec.model_copy(update={"run": spec.run.model_copy(update={"max_time_s": 20.0})})
    base = config_from_mapping({"simulation": {"width_px": 320, "height_px": 240,
                                               "progress": False}})
    return Simulation(spec, effective_config(base, spec), build_stack, seed=0)


def timed_run() -> tuple[float, int]:
    """(CPU seconds in step minus _perceive, steps) for one run."""
    sim = simulation()
    loop: Any = sim.loop
    spent = [0.0, 0.0]  # step, _perceive

    def timing(method: Callable[..., Any], slot: int) -> Callable[..., Any]:
        def timed(*args: Any) -> Any:
            start = time.process_time()
            try:
                return method(*args)
            finally:
                spent[slot] += time.process_time() - start
        return timed

    loop.step = timing(loop.step, 0)
    loop._perceive = timing(loop._perceive, 1)
    steps = len(sim.run().records)
    return spent[0] - spent[1], steps


def profiled_run() -> tuple[float, int]:
    """(cumtime of step minus _perceive under cProfile, steps) for one run."""
    sim = simulation()
    profile = cProfile.Profile()
    profile.enable()
    steps = len(sim.run().records)
    profile.disable()
    stats: Any = pstats.Stats(profile).stats
    cumtime = {name[2]: row[3] for name, row in stats.items()
               if name[0].endswith("supervisor/loop.py")}
    return cumtime["step"] - cumtime["_perceive"], steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--profile", action="store_true")
    args = parser.parse_args()
    measure = profiled_run if args.profile else timed_run
    measure()  # warm: imports, caches
    results = [measure() for _ in range(args.runs)]
    best, steps = min(results)
    how = "profiled cumtime" if args.profile else "CPU"
    print(f"supervisor per 20 s run ({steps} steps), {how}: best {best:.3f} s, "
          f"median {sorted(r[0] for r in results)[len(results) // 2]:.3f} s; "
          f"{best / steps * 1e6:.0f} us per step (best)")


if __name__ == "__main__":
    main()
