"""Rendered frames beside real ones: the Donkeycar tub's 1000 real frames and the same kind of
course rendered three ways (as before camera effects; through a Pi-class camera on a glossy
floor; through a USB camera sending MJPEG), each run through the detector as a sequence.

Writes `docs/generated/realism.png` (four frames of each, side by side; the real frames are the
Donkeycar project's, MIT licence: the figure is generated, never committed) and prints the
statistics table of docs/scenarios.md ("Does it look real?"); tests/scenarios/test_realism.py
checks that table against the same computation.

    python benchmarks/realism.py [--frames 150] [--data DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import cv2
import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
TUB_CAMERA = ROOT / "tests" / "perception" / "donkeycar_camera.yaml"
TUB_CALIBRATION = ROOT / "tests" / "perception" / "donkeycar_calibration.yaml"
#: The Donkeycar loop's rate: the tub's frames are 1/20 s apart.
TUB_RATE_HZ = 20.0
#: Rendered frames per set (the docs' tables).
FRAMES = 150


def data_folder(given: str | None) -> Path:
    if given:
        return Path(given)
    return Path(os.environ.get("LANEWARDEN_DATA", ROOT.parent / "shared" / "data"))


def tub_frames(folder: Path) -> list[np.ndarray]:
    records = [json.loads(line) for line in (folder / "catalog_0.catalog").read_text()
               .splitlines() if line.strip()]
    frames = []
    for record in records:
        image = cv2.imread(str(folder / "images" / record["cam/image_array"]))
        if image is None:
            raise SystemExit(f"{folder}: cannot read {record['cam/image_array']}")
        frames.append(image)
    return frames


def compare(tub: list[np.ndarray], frames: int,
            samples: bool = False) -> list[tuple[str, object, list[np.ndarray]]]:
    """(name, SequenceStats, four sample frames when `samples`) for the real frames and each
    rendered set."""
    from lanewarden.config import LanewardenConfig, config_from_mapping
    from lanewarden.perception.calibration import Undistorter, load_calibration
    from lanewarden.perception.detector import LaneDetector
    from lanewarden.scenarios.realism import RENDERED_SETS, rendered_tub_like, sequence_stats

    perception = config_from_mapping(
        {"perception": yaml.safe_load(TUB_CAMERA.read_text())["perception"]}, str(TUB_CAMERA)
    ).perception
    confident_min = LanewardenConfig().supervisor.confidence_confident_min
    out: list[tuple[str, object, list[np.ndarray]]] = []
    detector = LaneDetector(perception, Undistorter(load_calibration(TUB_CALIBRATION)))
    stats = sequence_stats(detector, tub, [i / TUB_RATE_HZ for i in range(len(tub))],
                           confident_min)
    samples = [tub[i * len(tub) // 4] for i in range(4)]
    out.append((f"real: Donkeycar tub ({len(tub)} frames)", stats, samples))
    for name, changes, effects_on in RENDERED_SETS:
        sequence, camera = rendered_tub_like(changes, effects_on, frames)
        detector = LaneDetector(perception, Undistorter(camera.calibration()))
        stats = sequence_stats(detector, sequence, [i / TUB_RATE_HZ for i in range(frames)],
                               confident_min)
        shown: list[np.ndarray] = []
        if samples:
            colour, _ = rendered_tub_like(changes, effects_on, 3 * frames // 4 + 1, color=True)
            shown = [colour[i * frames // 4] for i in range(4)]
        out.append((name, stats, shown))
    return out


def floors(frames: int) -> list[tuple[str, object, list[np.ndarray]]]:
    """(name, SequenceStats, no samples) for each floor of FLOOR_SETS through the default
    camera and the default perception config."""
    from lanewarden.config import LanewardenConfig
    from lanewarden.perception.calibration import Undistorter
    from lanewarden.perception.detector import LaneDetector
    from lanewarden.scenarios.realism import FLOOR_SETS, rendered_straight, sequence_stats

    config = LanewardenConfig()
    out: list[tuple[str, object, list[np.ndarray]]] = []
    for name, changes, effects_on in FLOOR_SETS:
        sequence, camera = rendered_straight(changes, effects_on, frames)
        detector = LaneDetector(config.perception, Undistorter(camera.calibration()))
        stats = sequence_stats(detector, sequence, [i / 30.0 for i in range(frames)],
                               config.supervisor.confidence_confident_min)
        out.append((name, stats, []))
    return out


def table(rows: list[tuple[str, object, list[np.ndarray]]], engage: int) -> str:
    lines = ["| frames | mean level | RMS contrast | noise (levels) | edge density | both edges "
             f"| confident | confident runs: median / longest / >= {engage} |",
             "|---|---|---|---|---|---|---|---|"]
    for name, stats, _ in rows:
        s = stats
        runs = sorted(s.runs) or [0]  # type: ignore[attr-defined]
        lines.append(
            f"| {name} | {s.mean_level:.0f} | {s.rms_contrast:.2f} "  # type: ignore[attr-defined]
            f"| {s.noise_levels:.1f} | {s.edge_density:.3f} "  # type: ignore[attr-defined]
            f"| {s.both_edges_share:.0%} | {s.confident_share:.0%} "  # type: ignore[attr-defined]
            f"| {runs[len(runs) // 2]} / {s.longest_run} / "  # type: ignore[attr-defined]
            f"{s.runs_at_least(engage)} |")  # type: ignore[attr-defined]
    return "\n".join(lines)


def figure(rows: list[tuple[str, object, list[np.ndarray]]], path: Path) -> None:
    strips = []
    for name, _, samples in rows:
        strip = np.hstack([cv2.resize(f, (320, 240), interpolation=cv2.INTER_NEAREST)
                           for f in samples])
        band = np.full((28, strip.shape[1], 3), 255, np.uint8)
        cv2.putText(band, name, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1,
                    cv2.LINE_AA)
        strips += [band, strip]
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), np.vstack(strips)):
        raise SystemExit(f"{path}: cannot write the figure")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=FRAMES, help="rendered frames per set")
    parser.add_argument("--data", help="the shared data folder (default: $LANEWARDEN_DATA or "
                        "../shared/data)")
    args = parser.parse_args()
    folder = data_folder(args.data) / "donkeycar-tub"
    if not folder.is_dir():
        raise SystemExit(f"{folder}: the Donkeycar tub is missing (set --data or "
                         "LANEWARDEN_DATA)")
    from lanewarden.config import LanewardenConfig

    engage = LanewardenConfig().supervisor.engage_confident_frames
    rows = compare(tub_frames(folder), args.frames, samples=True)
    figure(rows, ROOT / "docs" / "generated" / "realism.png")
    print(table(rows, engage))
    print()
    print(table(floors(args.frames), engage))


if __name__ == "__main__":
    sys.exit(main())
