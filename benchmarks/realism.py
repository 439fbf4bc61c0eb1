"""Rendered frames beside real ones: the Donkeycar tub's 1000 real frames and the same kind of
course rendered three ways (as before camera effects; through a Pi-class camera on a glossy
floor; through a USB camera sending MJPEG), each run through the detector as a sequence.

Also the repo's real JetBot tape-lane stills beside the same kind of course rendered (plain and
through a Pi-class camera). Writes `docs/generated/realism.png` and `realism-jetbot.png` (four
frames of each set, side by side: generated, never committed) and prints the statistics tables
of docs/scenarios.md ("Does it look real?"); tests/scenarios/test_realism.py checks those tables
against the same computation.

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


def read_frames(paths: list[Path]) -> list[np.ndarray]:
    """The images, in order; a missing or unreadable one ends the script naming it."""
    frames = []
    for path in paths:
        image = cv2.imread(str(path))
        if image is None:
            raise SystemExit(f"{path}: cannot read it")
        frames.append(image)
    return frames


def tub_frames(folder: Path) -> list[np.ndarray]:
    records = [json.loads(line) for line in (folder / "catalog_0.catalog").read_text()
               .splitlines() if line.strip()]
    return read_frames([folder / "images" / record["cam/image_array"] for record in records])


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


JETBOT = ROOT / "data" / "real" / "jetbot-tape-lane"


def jetbot_frames() -> list[np.ndarray]:
    """The repo's real JetBot frames labelled lane (data/real/jetbot-tape-lane, MIT as its
    PROVENANCE.md reads it), in the labels file's order."""
    from lanewarden.survey import parse_labels

    table = parse_labels((JETBOT / "labels.csv").read_text(encoding="utf-8"),
                         str(JETBOT / "labels.csv"))
    return read_frames([JETBOT / row.file for row in table.rows
                        if row.expect == "lane" and row.file is not None])


def jetbot(real: list[np.ndarray], frames: int,
           samples: bool = False) -> list[tuple[str, object, list[np.ndarray]]]:
    """(name, SequenceStats, four sample frames when `samples`) for the real JetBot stills (each
    judged on its own, through the folder's camera description) and the JetBot-like course
    rendered (a sequence, driven at 0.2 m/s), with the folder's perception config."""
    from lanewarden.config import LanewardenConfig, config_from_mapping
    from lanewarden.perception.calibration import Undistorter, load_calibration
    from lanewarden.perception.detector import LaneDetector
    from lanewarden.scenarios.realism import JETBOT_SETS, rendered_jetbot_like, sequence_stats

    described = yaml.safe_load((JETBOT / "camera.yaml").read_text())
    # (the whole description: its supervisor section says the robot fits in this lane)
    perception = config_from_mapping(described, str(JETBOT / "camera.yaml")).perception
    confident_min = LanewardenConfig().supervisor.confidence_confident_min
    detector = LaneDetector(perception, Undistorter(load_calibration(JETBOT / "calibration.yaml")))
    stats = sequence_stats(detector, real, [i / 20.0 for i in range(len(real))], confident_min,
                           stills=True)
    out: list[tuple[str, object, list[np.ndarray]]] = [
        (f"real: JetBot tape lane ({len(real)} lane stills)", stats,
         [real[i * len(real) // 4] for i in range(4)] if samples else [])]
    for name, changes, effects_on in JETBOT_SETS:
        sequence, camera = rendered_jetbot_like(changes, effects_on, frames)
        detector = LaneDetector(perception, Undistorter(camera.calibration()))
        stats = sequence_stats(detector, sequence, [i / 20.0 for i in range(frames)],
                               confident_min)
        shown: list[np.ndarray] = []
        if samples:
            colour, _ = rendered_jetbot_like(changes, effects_on, 3 * frames // 4 + 1,
                                             color=True)
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
            + ("| — (stills) |" if s.stills else  # type: ignore[attr-defined]
               f"| {runs[len(runs) // 2]} / {s.longest_run} / "  # type: ignore[attr-defined]
               f"{s.runs_at_least(engage)} |"))  # type: ignore[attr-defined]
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
    from lanewarden.config import LanewardenConfig

    engage = LanewardenConfig().supervisor.engage_confident_frames
    if folder.is_dir():
        rows = compare(tub_frames(folder), args.frames, samples=True)
        figure(rows, ROOT / "docs" / "generated" / "realism.png")
        print(table(rows, engage))
    else:
        print(f"(no tub table: {folder} is missing; set --data or LANEWARDEN_DATA)")
    print()
    rows = jetbot(jetbot_frames(), args.frames, samples=True)
    figure(rows, ROOT / "docs" / "generated" / "realism-jetbot.png")
    print(table(rows, engage))
    print()
    print(table(floors(args.frames), engage))


if __name__ == "__main__":
    sys.exit(main())
