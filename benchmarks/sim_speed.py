"""Simulation speed: the closed loop as a multiple of real time, and `lanewarden demo`'s wall time.

Run on demand: `python benchmarks/sim_speed.py [--skip-demo]`. The simulation is pinned to ONE
core (os.sched_setaffinity) and runs without video, as the brief's target is stated (>= 10x real
time at 640x480). Per-frame costs are broken down by stage (render, perception, the rest of the
loop) so a slow stage is easy to find. The demo is timed as a user runs it, from a fresh process,
video encoding included. Not a test: nothing here asserts a speed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from lanewarden.assembly import build_stack
from lanewarden.config import LanewardenConfig
from lanewarden.scenarios.library import resolve_scenario
from lanewarden.scenarios.simulator import Simulation, effective_config
from lanewarden.scenarios.spec import with_overrides

SCENARIO = "straight"


def _config(width: int, height: int) -> LanewardenConfig:
    return with_overrides(
        LanewardenConfig(), {"simulation": {"width_px": width, "height_px": height}}, "benchmark")


def stage_costs(sim: Simulation, frames: int = 150) -> dict[str, float]:
    """Median ms per frame of rendering and of perception, on the start of the lane."""
    w, h = sim.camera.width_px, sim.camera.height_px
    image = np.empty((h, w), np.uint8)
    start = sim.world.start_pose
    render, detect = [], []
    previous = None
    for k in range(frames):
        pose = type(start)(start.x_m + 0.006 * k, start.y_m, start.theta_rad)
        t0 = time.perf_counter()
        sim.renderer.render_gray(pose, image, (0.2, 0.0), sim.renderer.next_noise_index())
        t1 = time.perf_counter()
        previous = sim.detector.detect(image, k, k / 30.0, previous)
        t2 = time.perf_counter()
        render.append(t1 - t0)
        detect.append(t2 - t1)
    return {"render_ms": 1000 * statistics.median(render),
            "perception_ms": 1000 * statistics.median(detect)}


def closed_loop(width: int, height: int) -> None:
    spec = resolve_scenario(SCENARIO)
    config = effective_config(_config(width, height), spec)
    t0 = time.perf_counter()
    sim = Simulation(spec, config, build_stack, controller="supervised", seed=0)
    setup = time.perf_counter() - t0
    costs = stage_costs(Simulation(spec, config, build_stack, controller="supervised", seed=0))
    t1 = time.perf_counter()
    result = sim.run()
    run = time.perf_counter() - t1
    sim_time = float(result.trace.time_s[-1])
    frames = len(result.records)
    per_frame = 1000 * run / frames
    print(f"{width}x{height}: {frames} frames, {sim_time:.1f} s simulated in {run:.2f} s "
          f"-> {sim_time / run:.1f}x real time ({per_frame:.2f} ms/frame: render "
          f"{costs['render_ms']:.2f}, perception {costs['perception_ms']:.2f}, loop+metrics "
          f"{per_frame - costs['render_ms'] - costs['perception_ms']:.2f}); "
          f"set-up (world, texture, tables) {setup:.2f} s")


def demo_wall_time() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-m", "lanewarden", "demo", "--out", str(Path(tmp) / "out"),
             "--quiet"], capture_output=True, text=True, check=False)
        wall = time.perf_counter() - start
    status = "ok" if done.returncode == 0 else f"FAILED (exit {done.returncode})"
    print(f"lanewarden demo (2 processes, videos included): {wall:.1f} s wall time, {status}")
    if done.returncode != 0:
        print(done.stderr.strip())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-demo", action="store_true")
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} (other work on the machine skews this)")
    if args.skip_demo is False:
        demo_wall_time()
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    for width, height in ((640, 480), (320, 240)):
        closed_loop(width, height)


if __name__ == "__main__":
    main()
