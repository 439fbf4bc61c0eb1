"""Closed loop on random cameras and floors (issue 9): the lane ends and the supervised robot
halts before the tape's end, never crossing a tape; a lane that goes on never halts.

Each case is the library's `lane-ends` (or `straight`) course with a random mount and lens
(0.15-0.50 m high, pitched 20-55 deg down, 55-90 deg lens, 0.05-0.25 m ahead of the robot's
centre, 320x240) over random tiles (0.2-0.6 m, seams 2 mm up to half the tape), random tape
(19-50 mm) and lane (0.45-0.8 m). Perception gets what a user would give it: the camera's
ground model (the scenario's camera block is calibrated as `calibrate ground` would), the tape
and lane widths, and the look-ahead its start-up check names when it names one. A camera that
cannot tell tape from seam anywhere is refused at start-up (a config error, never a run), and
one that never finds a confident lane at the start never engages (it stays in HALT: safe, and
what the user sees is "waiting for a confident lane"); the test counts both and draws another,
until it has enough runs that drove. Seeded, on the fake clock; about two minutes of CPU.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from lanewarden.assembly import build_stack
from lanewarden.config import config_from_mapping
from lanewarden.perception.errors import PerceptionConfigError
from lanewarden.scenarios.library import resolve_scenario
from lanewarden.scenarios.simulator import Simulation, SimulationResult, effective_config
from lanewarden.scenarios.spec import parse_scenario

SEED = 2026
LANE_ENDS_CASES = 20
CONTINUING_CASES = 6
#: Halted with the robot's centre at least this far before the tape end (0: before it).
PAST_END_LIMIT_M = 0.0


def random_case(rng: np.random.Generator, course: str) -> dict[str, Any]:
    tape = float(rng.uniform(0.019, 0.050))
    lane = float(rng.uniform(0.45, 0.80))
    tile = float(rng.uniform(0.2, 0.6))
    seam = float(rng.uniform(0.002, tape / 2.0))
    data = resolve_scenario(course).model_dump(mode="json", exclude_none=True)
    data.pop("expect", None)
    data["floor"] = {"kind": "tiles", "tile_m": tile, "seam_m": seam,
                     "grid_offset_m": [float(rng.uniform(0, tile)), float(rng.uniform(0, tile))]}
    data["tape"] = {"width_m": tape}
    data["lane"]["width_m"] = lane
    data["camera"] = {"height_m": float(rng.uniform(0.15, 0.50)),
                      "pitch_deg": float(rng.uniform(20.0, 55.0)),
                      "hfov_deg": float(rng.uniform(55.0, 90.0)),
                      "forward_m": float(rng.uniform(0.05, 0.25)),
                      "width_px": 320, "height_px": 240}
    data["config"] = {"perception": {"tape": {"width_m": tape}, "lane": {"width_m": lane}}}
    return data


def simulate(data: dict[str, Any]) -> SimulationResult | None:
    """The run a user ends up with (None: the camera was refused outright)."""
    for _ in range(3):
        spec = parse_scenario(data, "random camera")
        config = effective_config(config_from_mapping({}), spec)
        try:
            sim = Simulation(spec, config, build_stack)
        except PerceptionConfigError as exc:
            if exc.suggested_look_ahead_m is None:
                return None
            data["config"]["perception"]["edges"] = {"look_ahead_m": exc.suggested_look_ahead_m}
            continue
        return sim.run()
    return None


def cases(course: str, count: int, seed: int) -> list[tuple[str, SimulationResult]]:
    """`count` runs that engaged (drove), with the counts of refused and never-engaged cameras
    printed."""
    rng = np.random.default_rng(seed)
    done: list[tuple[str, SimulationResult]] = []
    refused = idle = 0
    while len(done) < count:
        data = random_case(rng, course)
        result = simulate(data)
        if result is None or "FOLLOW" not in result.metrics["states_visited"]:
            if result is None:
                refused += 1
            else:
                idle += 1
                assert result.metrics["distance_travelled_m"] < 0.01  # never drove
            assert refused + idle < 2 * count, "most random cameras never drove"
            continue
        cam = data["camera"]
        label = (f"h={cam['height_m']:.2f} pitch={cam['pitch_deg']:.0f} "
                 f"hfov={cam['hfov_deg']:.0f} fwd={cam['forward_m']:.2f} "
                 f"tape={1000 * data['tape']['width_m']:.0f}mm lane={data['lane']['width_m']:.2f} "
                 f"look={data['config']['perception'].get('edges', {}).get('look_ahead_m')}")
        done.append((label, result))
    print(f"{course}: {count} runs that drove; {refused} cameras refused at start-up, {idle} "
          "never found a confident lane (stayed halted)")
    return done


@pytest.fixture(scope="module")
def lane_ends() -> list[tuple[str, SimulationResult]]:
    return cases("lane-ends", LANE_ENDS_CASES, SEED)


def test_lane_ends_halts_before_the_tape_end_on_random_cameras(
    lane_ends: list[tuple[str, SimulationResult]],
) -> None:
    bad = []
    for label, result in lane_ends:
        m = result.metrics
        past = m["distance_past_lane_end_m"]
        print(f"{label}: halted={m['halted']} reason={m['halt_reason']} past_end={past}")
        if not m["halted"] or m["crossed_tape"] or past is None or past > PAST_END_LIMIT_M:
            bad.append(f"{label}: halted={m['halted']} past_end={past} "
                       f"crossed_tape={m['crossed_tape']}")
    assert not bad, "\n".join(bad)


def test_continuing_lanes_never_halt_on_random_cameras() -> None:
    bad = []
    for label, result in cases("straight", CONTINUING_CASES, SEED + 1):
        m = result.metrics
        print(f"{label}: halted={m['halted']} states={m['states_visited']}")
        if m["halted"] or m["crossed_tape"]:
            bad.append(f"{label}: halted={m['halted']} reason={m['halt_reason']}")
    assert not bad, "\n".join(bad)
