"""Perception's outputs, dumped exactly, to show that a speed-up changed nothing.

Run on demand from the project root:

    python benchmarks/perception_equivalence.py --out /tmp/before.pkl      # on the old code
    python benchmarks/perception_equivalence.py --out /tmp/after.pkl --compare /tmp/before.pkl

Frames: the six scenes of `benchmarks/perception_speed.py` (640x480 and 320x240, each alone and in
sequence with the previous observation, and distorted through an undistorter), 30 frames of each of
the simulator's floors (`realism.FLOOR_SETS`: terrazzo and carpet give 150-360 Hough segments a
frame), and every frame the detector sees in closed-loop simulations of several library scenarios
at 320x240 and 640x480. For each frame it dumps the whole `LaneObservation` (every field and
component) and the `DetectionDebug` data (Hough segments, ROI, every candidate line's arrays, both
side choices). Floats are written with `float.hex` and arrays as their raw bytes, so "identical"
means bit for bit. A closed-loop run whose perception changed would also change the robot's path
and so the frames after it: the simulations check the whole loop.

`--compare FILE` exits non-zero and names the first difference when the dumps differ. Not a
test: it takes a few minutes (`--quick` runs the synthetic scenes and short simulations only).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import pickle
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.perception_speed import SCENES  # noqa: E402  (the same six scenes)
from lanewarden.assembly import ControlStack, build_stack  # noqa: E402
from lanewarden.config import LanewardenConfig, config_from_mapping  # noqa: E402
from lanewarden.perception.calibration import CameraCalibration, Undistorter  # noqa: E402
from lanewarden.perception.config import PerceptionConfig  # noqa: E402
from lanewarden.perception.detector import DetectionDebug, LaneDetector  # noqa: E402
from lanewarden.perception.observation import LaneObservation  # noqa: E402
from lanewarden.scenarios.camera import CameraModel  # noqa: E402
from lanewarden.scenarios.library import resolve_scenario  # noqa: E402
from lanewarden.scenarios.realism import FLOOR_SETS, rendered_straight  # noqa: E402
from lanewarden.scenarios.simulator import Simulation, effective_config  # noqa: E402
from tests.perception import synthetic as syn  # noqa: E402

SCENARIOS = ("straight", "s-curve", "lane-ends", "lecture", "dashed", "glare", "one-edge-gap",
             "fault-shadow-edge", "fault-tape-patch", "fault-occlusion")
SIZES = ((320, 240), (640, 480))


def plain(value: Any) -> Any:
    """`value` as nested tuples of str, int, bytes and hex floats (exact, picklable)."""
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        return ("f", value.hex())
    if isinstance(value, np.ndarray):
        return ("a", str(value.dtype), value.shape, np.ascontiguousarray(value).tobytes())
    if isinstance(value, np.generic):
        return plain(value.item())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (type(value).__name__,
                tuple((f.name, plain(getattr(value, f.name))) for f in dataclasses.fields(value)))
    if isinstance(value, Mapping):
        return ("m", tuple((k, plain(v)) for k, v in value.items()))
    if isinstance(value, (tuple, list)):
        return tuple(plain(v) for v in value)
    raise TypeError(f"cannot dump {type(value).__name__}")


def dump(observation: LaneObservation, debug: DetectionDebug) -> Any:
    """One detection: the observation and the debug data (the analysed image as a digest)."""
    fields = {f.name: getattr(debug, f.name) for f in dataclasses.fields(debug)}
    image = fields.pop("image")
    return plain(observation), plain(fields), hashlib.sha256(image.tobytes()).hexdigest()


def synthetic_records() -> list[Any]:
    config = PerceptionConfig()
    detector = LaneDetector(config)
    camera = CameraModel()
    undistorting = LaneDetector(
        config,
        Undistorter(CameraCalibration(camera.camera_matrix(), camera.distortion(), (640, 480))),
    )
    records: list[Any] = []
    for width, height in SIZES:
        previous: LaneObservation | None = None
        for index, (name, scene) in enumerate(SCENES.items()):
            frame = np.ascontiguousarray(syn.render(scene, width, height))
            alone = detector.detect_debug(frame, index, 0.1 * index)
            chained = detector.detect_debug(frame, index, 0.1 * index, previous)
            previous = chained[0]
            records.append((f"scene {name} {width}x{height}", dump(*alone), dump(*chained)))
    for index, (name, scene) in enumerate(SCENES.items()):
        distorted = np.ascontiguousarray(syn.render(scene, distorted=True))
        records.append((f"scene {name} distorted", dump(*undistorting.detect_debug(
            distorted, index, 0.0))))
    return records


class RecordingTap:
    """The loop's detector: `detect_debug`, each result dumped in order."""

    def __init__(self, detector: LaneDetector, out: list[Any]) -> None:
        self._detector = detector
        self._out = out

    def detect(self, image: np.ndarray, frame_index: int, time_s: float,
               previous: LaneObservation | None = None) -> LaneObservation:
        observation, debug = self._detector.detect_debug(image, frame_index, time_s, previous)
        self._out.append(dump(observation, debug))
        return observation


def recording_stack(out: list[Any]) -> Any:
    """`build_stack` with the loop's detector replaced by a `RecordingTap` into `out`."""

    def build(*args: Any, **kwargs: Any) -> ControlStack:
        stack = build_stack(*args, **kwargs)
        return dataclasses.replace(stack, tap=RecordingTap(stack.detector, out))

    return build


def floor_records() -> list[Any]:
    """Every floor of `realism.FLOOR_SETS` (a straight lane through the default camera at
    320x240, its camera effects on): 30 frames each, each detected alone and with the previous
    observation. Terrazzo and carpet give 150-360 Hough segments (500-odd without the edge
    budget), so clustering's and the tape choice's shortcuts for many lines
    (`lines._compatible_pairs`, `edge_choice._pairs_worth_checking`) are checked here too."""
    detector = LaneDetector(PerceptionConfig())
    records: list[Any] = []
    for name, changes, effects_on in FLOOR_SETS:
        frames, _ = rendered_straight(changes, effects_on, 30)
        previous: LaneObservation | None = None
        for index, frame in enumerate(frames):
            alone = detector.detect_debug(frame, index, index / 30.0)
            chained = detector.detect_debug(frame, index, index / 30.0, previous)
            previous = chained[0]
            records.append((f"floor {name} frame {index}", dump(*alone), dump(*chained)))
    return records


def simulation_records(max_time_s: float | None) -> list[Any]:
    records: list[Any] = []
    for width, height in SIZES:
        for name in SCENARIOS:
            spec = resolve_scenario(name)
            if max_time_s is not None:
                limit = min(spec.run.max_time_s, max_time_s)
                spec = spec.model_copy(
                    update={"run": spec.run.model_copy(update={"max_time_s": limit})})
            config: LanewardenConfig = effective_config(config_from_mapping(
                {"simulation": {"width_px": width, "height_px": height, "progress": False}}), spec)
            frames: list[Any] = []
            started = time.process_time()
            result = Simulation(spec, config, recording_stack(frames), seed=0).run()
            print(f"  {name} {width}x{height}: {len(frames)} frames, end {result.end_reason!r}, "
                  f"{time.process_time() - started:.1f} s CPU", flush=True)
            records.append((f"sim {name} {width}x{height}", result.end_reason,
                            plain(result.trace.poses), tuple(frames)))
    return records


def first_difference(a: Any, b: Any, where: str = "") -> str | None:
    """Where two dumps first differ (a path into the nested tuples), or None."""
    if type(a) is not type(b):
        return f"{where}: {type(a).__name__} vs {type(b).__name__}"
    if isinstance(a, tuple):
        if len(a) != len(b):
            return f"{where}: length {len(a)} vs {len(b)}"
        label = a[0] if a and isinstance(a[0], str) else None
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            found = first_difference(x, y, f"{where}/{label or ''}[{i}]")
            if found:
                return found
        return None
    return None if a == b else f"{where}: {a!r:.200} vs {b!r:.200}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="pickle to write")
    parser.add_argument("--compare", type=Path, help="an earlier dump that must be identical")
    parser.add_argument("--quick", action="store_true", help="simulations cut to 4 s")
    args = parser.parse_args()
    print("synthetic scenes", flush=True)
    records = synthetic_records()
    print("floors", flush=True)
    records += floor_records()
    print("simulations", flush=True)
    records += simulation_records(4.0 if args.quick else None)
    data = pickle.dumps(records, protocol=5)
    args.out.write_bytes(data)
    print(f"{len(records)} groups, {len(data)} bytes, sha256 {hashlib.sha256(data).hexdigest()}")
    if args.compare is not None:
        before = args.compare.read_bytes()
        if before == data:
            print(f"identical to {args.compare}")
            return
        where = first_difference(pickle.loads(before), records)
        print(f"DIFFERENT from {args.compare}: first at {where}")
        sys.exit(1)


if __name__ == "__main__":
    main()
