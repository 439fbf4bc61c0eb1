"""What one campaign run costs a worker: CPU seconds per 20 s simulated run and the worker's peak
RSS, at 640x480 and 320x240.

Each resolution gets a fresh worker process (as a Dask worker would be) that runs the same 20 s
run `--runs` times in a row: the first run pays for painting the floor, the next ones reuse it
(`paint_ground_cached`), as a campaign's worker does. The run is the `straight` scenario with no
fault (it drives the whole 20 s), supervised, no video, no plot, judged like a campaign run, with
the default campaign spec's `config:` (through the lens, perception undistorting);
`--rectified` sets `simulation.rectified_frames` (one remap per frame instead of two); `--floor
KIND` lays another floor kind (e.g. `ceramic`: glossy, so the ceiling lights' reflections are
rendered too). The camera is the scenario's (default: a Pi-class camera with its effects).

    python benchmarks/sim_cost.py [--runs 3] [--scenario straight] [--rectified] [--floor KIND]

Prints CPU s per run (first and warm) and how a warm run splits between the robot's own stack
(the control loop's steps: perception, supervisor, base commands: what the robot would spend on
its own computer) and the simulator (rendering, camera effects, ground truth, judging), the
worker's peak RSS, and whether heavy modules (matplotlib, imageio_ffmpeg, dask) were imported.
Targets at 320x240: <= 1.5 s CPU per warm run, <= 300 MB peak RSS per worker.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import resource
import sys
import time
from typing import Any


def _time_robot_steps(simulation: Any) -> list[float]:
    """Count the CPU of the robot's own stack (the control loop's steps: perception, supervisor,
    the command to the simulated base) apart from the simulator's (rendering, camera effects,
    ground truth, judging): returns a one-item list the steps add their CPU to."""
    spent = [0.0]
    step = simulation.loop.step

    def timed(now: float) -> Any:
        before = time.process_time()
        try:
            return step(now)
        finally:
            spent[0] += time.process_time() - before

    simulation.loop.step = timed
    return spent


def _worker(scenario: str, width: int, height: int, runs: int, rectified: bool,
            floor: str | None = None) -> dict[str, Any]:
    started = time.process_time()
    from lanewarden.assembly import build_stack
    from lanewarden.config import config_from_mapping
    from lanewarden.scenarios.campaign.cases import DEFAULT_SPEC, load_campaign_spec
    from lanewarden.scenarios.campaign.run_case import judge
    from lanewarden.scenarios.library import resolve_scenario
    from lanewarden.scenarios.simulator import Simulation, effective_config

    import_cpu = time.process_time() - started
    from lanewarden.scenarios.spec import FloorSpec

    spec = resolve_scenario(scenario)
    spec = spec.model_copy(update={"run": spec.run.model_copy(update={"max_time_s": 20.0})})
    if floor is not None:
        spec = spec.model_copy(update={"floor": FloorSpec(kind=floor)})
    campaign_config = load_campaign_spec(DEFAULT_SPEC)[0].config
    simulation = {**campaign_config.get("simulation", {}), "width_px": width,
                  "height_px": height, "progress": False}
    if rectified:
        simulation["rectified_frames"] = True
    config = effective_config(config_from_mapping({**campaign_config, "simulation": simulation}),
                              spec)
    cpu, sim_s, robot = [], [], []
    for _ in range(runs):
        before = time.process_time()
        simulation = Simulation(spec, config, build_stack, seed=0)
        robot_cpu = _time_robot_steps(simulation)
        result = simulation.run()
        judge(result, config)
        cpu.append(time.process_time() - before)
        robot.append(robot_cpu[0])
        sim_s.append(float(result.trace.time_s[-1]))
    heavy = [m for m in ("matplotlib", "imageio_ffmpeg", "dask", "distributed", "scipy")
             if m in sys.modules]
    return {"resolution": f"{width}x{height}", "rectified": config.simulation.rectified_frames,
            "import_cpu_s": round(import_cpu, 2),
            "cpu_s_per_run": [round(c, 2) for c in cpu], "simulated_s": sim_s,
            "robot_cpu_s_per_run": [round(c, 2) for c in robot],
            "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
            "heavy_modules_imported": heavy}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--scenario", default="straight")
    parser.add_argument("--rectified", action="store_true",
                        help="simulation.rectified_frames: the pinhole image, no undistortion")
    parser.add_argument("--floor", help="another floor kind (e.g. ceramic, terrazzo)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    context = multiprocessing.get_context("spawn")
    results = []
    for width, height in ((640, 480), (320, 240)):
        with context.Pool(1) as pool:
            results.append(pool.apply(_worker, (args.scenario, width, height, args.runs,
                                                    args.rectified, args.floor)))
    if args.json:
        print(json.dumps(results, indent=2))
        return
    for r in results:
        warm = r["cpu_s_per_run"][1:] or r["cpu_s_per_run"]
        robot = r["robot_cpu_s_per_run"][1:] or r["robot_cpu_s_per_run"]
        robot_s = sum(robot) / len(robot)
        frames = "rectified" if r["rectified"] else "lens"
        print(f"{r['resolution']:>8} ({frames}): first run {r['cpu_s_per_run'][0]:.2f} s CPU, "
              f"warm runs "
              f"{sum(warm) / len(warm):.2f} s CPU per {r['simulated_s'][0]:.0f} s simulated "
              f"(robot stack {robot_s:.2f} s, simulator {sum(warm) / len(warm) - robot_s:.2f} s); "
              f"worker peak RSS {r['peak_rss_mb']:.0f} MB; imports {r['import_cpu_s']:.1f} s "
              f"CPU; heavy modules imported: {', '.join(r['heavy_modules_imported']) or 'none'}")


if __name__ == "__main__":
    main()
