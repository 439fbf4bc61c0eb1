"""Does a change to the supervisor leave every simulated run exactly as it was?

Runs every library scenario (fault-* included) at 320x240 with seeds 0 and 1 under the supervised
controller, and a few under the lecture's controller (the SafetyGate wraps both), and reduces each
run to a canonical nested tuple: every StepRecord (state, halt reason, events, command, filtered
slope sum, its variance, innovation, centre offset, lane trust, observation), the trace arrays,
the metrics, the end reason and the faults' effects and windows. Floats are kept exactly (as
float.hex), arrays as dtype, shape and bytes.

On demand only (a few minutes of CPU):
    python benchmarks/supervisor_equivalence.py dump before.pkl
    python benchmarks/supervisor_equivalence.py dump after.pkl
    python benchmarks/supervisor_equivalence.py compare before.pkl after.pkl
`compare` exits 1 and names the first run and step that differ.
"""

from __future__ import annotations

import dataclasses
import enum
import pickle
import sys
import time
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np

from lanewarden.assembly import build_stack
from lanewarden.config import config_from_mapping
from lanewarden.scenarios.library import library_names, resolve_scenario
from lanewarden.scenarios.simulator import Simulation, SimulationResult, effective_config

SEEDS = (0, 1)
#: Scenarios also run under the lecture's controller (seed 0).
LECTURE_SCENARIOS = ("lecture", "straight", "s-curve", "fault-bumper", "fault-camera-freeze")


def canonical(value: object) -> object:
    """A value that compares equal exactly when `value` is the same, bit for bit."""
    if isinstance(value, float):
        return ("f", value.hex())
    if isinstance(value, enum.Enum):
        return ("enum", type(value).__name__, value.name)
    if isinstance(value, np.ndarray):
        return ("nd", value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, np.generic):
        return canonical(value.item())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = dataclasses.fields(value)
        return (type(value).__name__, tuple((f.name, canonical(getattr(value, f.name)))
                                            for f in fields))
    if isinstance(value, Mapping):
        return ("map", tuple(sorted((repr(k), canonical(v)) for k, v in value.items())))
    if isinstance(value, set | frozenset):
        return ("set", tuple(sorted(repr(canonical(v)) for v in value)))
    if isinstance(value, list | tuple):
        return tuple(canonical(v) for v in value)
    if value is None or isinstance(value, bool | int | str | bytes):
        return value
    raise TypeError(f"no canonical form for {type(value).__name__}")


def run_digest(result: SimulationResult) -> dict[str, object]:
    """Everything a run produced, except the world and the spec (inputs, not outputs)."""
    return {
        "records": [canonical(r) for r in result.records],
        "trace": canonical(result.trace),
        "metrics": canonical(result.metrics),
        "end_reason": result.end_reason,
        "fault_effects": canonical(result.fault_effects),
        "fault_windows": canonical(result.fault_windows),
    }


def runs() -> Iterator[tuple[str, str, int]]:
    for name in library_names():
        for seed in SEEDS:
            yield name, "supervised", seed
    for name in LECTURE_SCENARIOS:
        yield name, "lecture", 0


def dump(path: Path) -> None:
    base = config_from_mapping({"simulation": {"width_px": 320, "height_px": 240,
                                               "progress": False}})
    out: dict[tuple[str, str, int], dict[str, object]] = {}
    for name, controller, seed in runs():
        spec = resolve_scenario(name)
        config = effective_config(base, spec)
        start = time.process_time()
        result = Simulation(spec, config, build_stack, controller=controller, seed=seed).run()
        out[(name, controller, seed)] = run_digest(result)
        print(f"{name:28s} {controller:10s} seed {seed}: {len(result.records):4d} steps, "
              f"{result.end_reason}, {time.process_time() - start:.1f} s CPU", flush=True)
    path.write_bytes(pickle.dumps(out))


def compare(before_path: Path, after_path: Path) -> int:
    before = pickle.loads(before_path.read_bytes())
    after = pickle.loads(after_path.read_bytes())
    if before.keys() != after.keys():
        print(f"different runs: {sorted(before.keys() ^ after.keys())}")
        return 1
    for key, old in before.items():
        new = after[key]
        for part, old_value in old.items():
            if new[part] == old_value:
                continue
            if part == "records":
                pairs = enumerate(zip(old_value, new[part], strict=False))
                step = next((i for i, (a, b) in pairs if a != b),
                            min(len(old_value), len(new[part])))
                print(f"{key}: records differ first at step {step} "
                      f"(lengths {len(old_value)} / {len(new[part])})")
            else:
                print(f"{key}: {part} differs")
            return 1
    print(f"identical: {len(before)} runs")
    return 0


def main(argv: list[str]) -> int:
    if len(argv) == 2 and argv[0] == "dump":
        dump(Path(argv[1]))
        return 0
    if len(argv) == 3 and argv[0] == "compare":
        return compare(Path(argv[1]), Path(argv[2]))
    print(__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
