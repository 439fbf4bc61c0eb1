"""How steeply the robot ever faces its lane in the simulator: for every library course (the
fault scenarios left out), at 640x480 and 320x240, the largest |lane heading| perception reports
on a usable frame (confidence at least the supervisor's usable threshold), supervised, seed 0.

Run on demand from the project root (about 30 simulations; a few minutes on two cores):

    python benchmarks/lane_headings.py [--workers 2]

What it backs: `perception.lane.max_heading_deg` (45 by default; docs/perception.md, rule 12)
must leave the simulator's own courses alone. Not a test: nothing here asserts anything.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lanewarden.config import LanewardenConfig  # noqa: E402

LIBRARY = ROOT / "scenarios" / "library"
SIZES = ((640, 480), (320, 240))
USABLE = LanewardenConfig().supervisor.confidence_usable_min


def steepest(job: tuple[str, tuple[int, int], str]) -> tuple[str, str, int, float | None]:
    """(course, size, usable frames, largest |lane heading| in degrees on them)."""
    name, (width, height), folder = job
    doc = yaml.safe_load((LIBRARY / f"{name}.yaml").read_text(encoding="utf-8"))
    doc["camera"] = {**(doc.get("camera") or {}), "width_px": width, "height_px": height}
    out = Path(folder) / f"{name}-{width}"
    out.mkdir(parents=True)
    scenario = out / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(doc), encoding="utf-8")
    subprocess.run([sys.executable, "-m", "lanewarden", "sim", "--scenario", str(scenario),
                    "--out", str(out / "run"), "--no-video", "--quiet"],
                   check=False, capture_output=True)
    headings = []
    for line in (out / "run" / "run.jsonl").read_text(encoding="utf-8").splitlines():
        seen = json.loads(line).get("observation") or {}
        if seen.get("lane_heading_rad") is not None and seen["confidence"] >= USABLE:
            headings.append(abs(math.degrees(seen["lane_heading_rad"])))
    return name, f"{width}x{height}", len(headings), max(headings, default=None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    names = sorted(p.stem for p in LIBRARY.glob("*.yaml") if not p.stem.startswith("fault-"))
    print("| course | size | usable frames | largest lane heading |")
    print("|---|---|---|---|")
    overall = 0.0
    with tempfile.TemporaryDirectory() as folder, ProcessPoolExecutor(args.workers) as pool:
        jobs = [(name, size, folder) for name in names for size in SIZES]
        for name, size, count, worst in pool.map(steepest, jobs):
            shown = "—" if worst is None else f"{worst:.1f}°"
            print(f"| {name} | {size} | {count} | {shown} |", flush=True)
            overall = max(overall, worst or 0.0)
    print(f"\nlargest over all courses: {overall:.1f}° (perception.lane.max_heading_deg: 45)")


if __name__ == "__main__":
    main()
