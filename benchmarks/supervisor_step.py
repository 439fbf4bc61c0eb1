"""How long the supervisor's part of one control step takes (no perception, no I/O).

Runs SupervisedController and the lecture baseline, each behind its SafetyGate, over a synthetic
30 Hz drive with noisy observations, a bend and a few dropouts, and prints microseconds per step.
On demand only:
    python benchmarks/supervisor_step.py
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from lanewarden.actuation.base import BaseFeedback
from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import ControlInputs, FrameInfo
from lanewarden.supervisor.controllers import CONTROLLERS
from lanewarden.supervisor.gate import SafetyGate
from lanewarden.supervisor.watchdog import frame_fingerprint

DT = 1.0 / 30.0
LEFT = LaneEdge(100.0, 480.0, 300.0, 200.0, 1.6, 250.0)
RIGHT = LaneEdge(540.0, 480.0, 340.0, 200.0, -1.6, 250.0)


def inputs(n: int, seed: int = 0) -> list[ControlInputs]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        t = i * DT
        bend = 7.0 * np.sin(2 * np.pi * t / 20.0)
        dropout = (i % 97) in (10, 11)
        obs = LaneObservation(
            frame_index=i,
            time_s=t,
            left=LEFT,
            right=None if dropout else RIGHT,
            slope_sum=None if dropout else float(bend + rng.normal(0, 0.2)),
            confidence=0.0 if dropout else float(rng.uniform(0.6, 1.0)),
            lane_offset_m=None if dropout else float(rng.normal(0, 0.01)),
            lane_heading_rad=None if dropout else float(rng.normal(0, 0.02)),
        )
        out.append(
            ControlInputs(
                frame=FrameInfo(i, t, i.to_bytes(4, "big"), True),
                observation=obs,
                feedback=BaseFeedback(received_at_s=t),
                start_requested=(i == 0),
            )
        )
    return out


def main() -> None:
    steps = inputs(9000)  # 5 minutes of driving at 30 Hz
    config = SupervisorConfig()
    for name, factory in CONTROLLERS.items():
        controller = SafetyGate(factory(config), config)
        per_step = []
        for k, inp in enumerate(steps):
            t0 = time.perf_counter()
            controller.step(inp, k * DT)
            per_step.append(time.perf_counter() - t0)
        us = np.array(per_step) * 1e6
        print(
            f"{name:10s} step: median {statistics.median(us):7.1f} us  "
            f"p99 {np.percentile(us, 99):7.1f} us  max {us.max():7.1f} us  ({len(us)} steps)"
        )
    image = np.random.default_rng(1).integers(0, 256, (480, 640, 3), dtype=np.uint8)
    t0 = time.perf_counter()
    for _ in range(1000):
        frame_fingerprint(image)
    print(f"frame_fingerprint 640x480 BGR: {(time.perf_counter() - t0) * 1e3:.1f} us per frame")


if __name__ == "__main__":
    main()
