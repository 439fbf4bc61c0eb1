"""Perception on labelled frames, per class: decisions, false lanes, edges on the tapes, runs.

Run on demand from the project root:

    python benchmarks/real_frames_eval.py [--footage DIR] [--no-rendered] [--narrow]

Two kinds of sets:
- real footage: every sub-folder of `--footage` (default `$LANEWARDEN_FOOTAGE`, else the repo's
  own `data/real`) holding `labels.csv` (`file,expect`, expect `lane` or `none`, in the
  order the frames were taken), `camera.yaml` (the config a user describes that floor with; its
  `perception:` section is used), `calibration.yaml` (the camera, with its ground pose), a
  `PROVENANCE.md`, and optionally `eval.yaml` (`tapes: dark` for dark tapes on a light floor).
  The repo holds the JetBot tape lane; the shared Donkeycar tub can be one too, outside it.
- the rendered set (`tests/perception/rendered_set.py`): ours, generated here at 640x480 and
  320x240 with the simulator's default camera.

For each set and class (`lane`, `none`, and for the rendered set each frame's `shows`), it
prints: frames, decisions (both edges, confidence at least the supervisor's usable threshold
0.2: what `detect` and the overlay call a decision), confident frames (at least 0.6, the
supervisor's engage threshold), false lanes (decisions on `none` frames), lane frames with a
decision and both reported edges on the tapes, and the longest run of confident frames in the
labels' order (each frame detected with the previous observation, as `replay` does). `--narrow`
repeats everything with `lane.width_m` at the narrowest the config accepts for that set's tape:
the configuration most likely to take one tape's two edges for a lane.

Edges on the tapes: for rendered frames from the world (`rendered_set.edges_on_tapes`); for real
frames, light tapes on a darker floor (an `eval.yaml` beside it may say `tapes: dark`), an edge is
on a tape when along at least 60% of it the image is brighter (darker) 3 px outwards than 3 px
inwards by 20 grey levels: the reported edge is a tape's inner boundary. `--sheet DIR` writes
contact sheets of the decisions to check by eye. `--jitter N` also judges every real `none`
frame in N versions moved by a random fraction of a pixel (seeded): a false lane one such shift
brings is one the camera may deliver on the next frame.

Not a test: it asserts nothing; the tests hold the figures that must not regress.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lanewarden.config import LanewardenConfig, config_from_mapping  # noqa: E402
from lanewarden.perception.calibration import Undistorter, load_calibration  # noqa: E402
from lanewarden.perception.config import PerceptionConfig, narrowest_lane_width_m  # noqa: E402
from lanewarden.perception.decision import decide  # noqa: E402
from lanewarden.perception.detector import LaneDetector  # noqa: E402
from lanewarden.perception.errors import PerceptionConfigError  # noqa: E402
from lanewarden.perception.floor_config import LaneConfig  # noqa: E402
from lanewarden.perception.ground import GroundModel, default_ground_model  # noqa: E402
from lanewarden.perception.observation import LaneEdge, LaneObservation  # noqa: E402
from lanewarden.perception.overlay import draw_overlay  # noqa: E402
from lanewarden.survey import parse_labels  # noqa: E402
from lanewarden.survey_run import judge_shifted  # noqa: E402
from tests.perception import rendered_set  # noqa: E402

SUPERVISOR = LanewardenConfig().supervisor
USABLE = SUPERVISOR.confidence_usable_min
CONFIDENT = SUPERVISOR.confidence_confident_min
TURN = SUPERVISOR.turn_enter_slope_sum
#: Real footage: `$LANEWARDEN_FOOTAGE` (e.g. a folder of sets beside shared data that must not be
#: copied into the repo), else the repo's own `data/real`.
DEFAULT_FOOTAGE = Path(os.environ.get("LANEWARDEN_FOOTAGE", "").strip()
                       or Path(__file__).resolve().parents[1] / "data" / "real")


@dataclass
class Tally:
    frames: int = 0
    decisions: int = 0
    confident: int = 0
    on_tapes: int = 0
    longest_run: int = 0
    weakest: Counter[str] = field(default_factory=Counter)
    false_names: list[str] = field(default_factory=list)

    def add(self, name: str, expect: str, obs: LaneObservation, on_tapes: bool | None) -> None:
        self.frames += 1
        decided = decide(obs, trust_min_confidence=USABLE, turn_slope_sum=TURN) != "none"
        self.decisions += decided
        self.confident += obs.both_edges and obs.confidence >= CONFIDENT
        if decided and expect == "none":
            self.false_names.append(name)
        if decided and expect == "lane" and on_tapes:
            self.on_tapes += 1
        if not decided:
            self.weakest[min(obs.components, key=lambda k: obs.components[k])] += 1

    def row(self, label: str, expect: str) -> str:
        good = (f"{self.on_tapes} ({self.on_tapes / max(self.frames, 1):.0%})"
                if expect == "lane" else "—")
        false = (f"{len(self.false_names)}" if expect == "none" else "—")
        weak = ", ".join(f"{k} {v}" for k, v in self.weakest.most_common(2))
        return (f"| {label} | {self.frames} | {self.decisions} | {self.confident} | {false} | "
                f"{good} | {self.longest_run} | {weak} |")


def _decision(obs: LaneObservation) -> str:
    """`detect`'s decision, with the supervisor's thresholds."""
    return decide(obs, trust_min_confidence=USABLE, turn_slope_sum=TURN)


HEADER = ("| class | frames | decisions | confident | false lanes | decision, edges on tapes "
          "| longest confident run | weakest (no decision) |\n|---|---|---|---|---|---|---|---|")


def _longest(flags: Iterable[bool]) -> int:
    best = run = 0
    for flag in flags:
        run = run + 1 if flag else 0
        best = max(best, run)
    return best


# --------------------------------------------------------------------------- real footage

@dataclass(frozen=True)
class RealSet:
    name: str
    folder: Path
    labels: list[tuple[str, str]]
    perception: dict[str, Any]
    tapes: str
    calibration: Path


def real_sets(footage: Path) -> Iterator[RealSet]:
    for folder in sorted(p for p in footage.iterdir() if (p / "labels.csv").is_file()):
        # the survey's own reading of a labels file (comments, notes); file rows only here
        table = parse_labels((folder / "labels.csv").read_text(encoding="utf-8"),
                             str(folder / "labels.csv"))
        labels = [(row.file, row.expect) for row in table.rows if row.file is not None]
        described = yaml.safe_load((folder / "camera.yaml").read_text()) or {}
        # the tapes' polarity: `eval.yaml` beside camera.yaml (which stays a config `survey`
        # takes as it is), or an `eval:` section in camera.yaml (older footage folders)
        judged = (yaml.safe_load((folder / "eval.yaml").read_text()) or {}
                  if (folder / "eval.yaml").is_file() else described.get("eval", {}))
        yield RealSet(folder.name, folder, labels, described.get("perception", {}),
                      judged.get("tapes", "light"), folder / "calibration.yaml")


#: Perception alone is judged here: no robot has to fit in the lane (a lane narrower than twice
#: the departure clearance is refused otherwise, and the narrowest lanes below are meant).
_NO_ROBOT = {"supervisor": {"lane_departure_clearance_m": 0.0}}


def _perception(overrides: dict[str, Any], narrow: bool, source: str) -> PerceptionConfig:
    config = config_from_mapping({"perception": overrides, **_NO_ROBOT}, source).perception
    if not narrow:
        return config
    # the narrowest the tape allows, or, for a thin tape, just above the field's own bound
    above = next(m.gt for m in LaneConfig.model_fields["width_m"].metadata if hasattr(m, "gt"))
    lane = {**overrides.get("lane", {}), "width_m": max(narrowest_lane_width_m(
        config.tape, config.lane.width_tolerance_fraction), round(above + 0.001, 3))}
    return config_from_mapping({"perception": {**overrides, "lane": lane}, **_NO_ROBOT},
                               source).perception


def edge_on_light_tape(gray: np.ndarray, edge: LaneEdge, side: str, light: bool) -> bool:
    """Along at least 60% of the edge, 3 px outwards is brighter (darker for dark tapes) than
    3 px inwards by 20 grey levels."""
    dx, dy = edge.x2 - edge.x1, edge.y2 - edge.y1
    n = math.hypot(dx, dy)
    if n < 1e-6:
        return False
    # Image normal pointing right of the edge's direction (near -> far, y down): (-dy, dx).
    nx, ny = -dy / n, dx / n
    out = -1.0 if side == "left" else 1.0  # outwards: left of a left edge, right of a right one
    h, w = gray.shape
    hits = seen = 0
    for t in np.linspace(0.05, 0.95, 9):
        x, y = edge.x1 + t * dx, edge.y1 + t * dy
        xo, yo = x + 3 * out * nx, y + 3 * out * ny
        xi, yi = x - 3 * out * nx, y - 3 * out * ny
        if not (0 <= xo < w and 0 <= yo < h and 0 <= xi < w and 0 <= yi < h):
            continue
        seen += 1
        step = float(gray[int(yo), int(xo)]) - float(gray[int(yi), int(xi)])
        hits += (step if light else -step) >= 20.0
    return seen > 0 and hits >= 0.6 * seen


def tape_under_camera(image: np.ndarray, dark: bool) -> bool:
    """Whether a tape runs under the camera: in one of the rows at 89%, 94% and 97% of the
    height (200, 210 and 218 of 224), a point of the central fifth of the columns at least 30
    grey levels darker (lighter, for light tapes) than the row's median, after a 5x5 blur. A
    rough measure of the robot standing on or just beside a line."""
    gray = cv2.GaussianBlur(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), (5, 5), 0).astype(int)
    h, w = gray.shape
    lo, hi = round(w * 0.4), round(w * 0.6)
    for row in (round(h * 0.893), round(h * 0.9375), round(h * 0.973)):
        line = gray[row]
        centre, median = line[lo:hi], float(np.median(line))
        if (centre.min() < median - 30) if dark else (centre.max() > median + 30):
            return True
    return False


def jitter_no_lane(rs: RealSet, detector: LaneDetector, versions: int) -> None:
    """Each `none` frame judged again `versions` times, each shifted by a random sub-pixel
    offset (`lanewarden survey --jitter`'s: uniform in +-0.5 px on each axis, seeded by the
    frame's name): a false lane that one shift brings is a false lane the camera may
    deliver."""
    frames = [file for file, expect in rs.labels if expect == "none"]
    found: dict[str, tuple[float, ...]] = {}
    for file in frames:
        shifted, _ = judge_shifted(cv2.imread(str(rs.folder / file)), file, detector,
                                   _decision, versions)
        if shifted.decided:
            found[file] = shifted.decided
    total = sum(len(v) for v in found.values())
    print(f"none frames shifted by a fraction of a pixel ({versions} versions each): "
          f"{total} decisions in {len(frames) * versions}, on {len(found)} of {len(frames)} "
          f"frames")
    for file, confidences in found.items():
        print(f"  {file}: {len(confidences)} of {versions}, confidence "
              f"{', '.join(f'{c:.2f}' for c in confidences)}")


def evaluate_real(rs: RealSet, narrow: bool, sheet: Path | None, jitter: int = 0) -> None:
    calibration = load_calibration(rs.calibration)
    undistorter = Undistorter(calibration)
    try:
        config = _perception(rs.perception, narrow, str(rs.folder / "camera.yaml"))
        detector = LaneDetector(config, undistorter)
    except PerceptionConfigError as exc:
        print(f"\n{rs.name}: refused: {exc}")
        return
    narrow_text = f" (narrow lane: lane.width_m {config.lane.width_m:g})" if narrow else ""
    print(f"\n### {rs.name}{narrow_text}")
    print(detector.describe_ground(str(rs.calibration)))
    tallies: dict[str, Tally] = {}
    confident_flags: list[bool] = []
    previous: LaneObservation | None = None
    pictures: list[np.ndarray] = []
    under = Counter[tuple[bool, bool]]()  # lane frames by (tape under the camera, decided)
    for index, (file, expect) in enumerate(rs.labels):
        image = cv2.imread(str(rs.folder / file))
        if image is None:
            raise SystemExit(f"{rs.folder / file}: not an image")
        obs, debug = detector.detect_debug(image, index, index / 20.0)
        seq = detector.detect(image, index, index / 20.0, previous=previous)
        previous = seq
        confident_flags.append(seq.both_edges and seq.confidence >= CONFIDENT)
        gray = cv2.cvtColor(debug.image, cv2.COLOR_BGR2GRAY)
        on = (obs.left is not None and obs.right is not None
              and edge_on_light_tape(gray, obs.left, "left", rs.tapes == "light")
              and edge_on_light_tape(gray, obs.right, "right", rs.tapes == "light"))
        tallies.setdefault(expect, Tally()).add(file, expect, obs, on)
        decided = decide(obs, trust_min_confidence=USABLE, turn_slope_sum=TURN) != "none"
        if expect == "lane":
            under[(tape_under_camera(image, rs.tapes == "dark"), decided)] += 1
        if sheet is not None and decided:
            pic = draw_overlay(debug.image, obs, debug, decide(
                obs, trust_min_confidence=USABLE, turn_slope_sum=TURN))
            pic = cv2.resize(pic, (320, 240))
            cv2.putText(pic, f"{index} {'ok' if on else 'OFF'}", (4, 232), 0, 0.5,
                        (0, 255, 0) if on else (0, 0, 255), 1)
            pictures.append(pic)
    print(HEADER)
    for expect, tally in sorted(tallies.items()):
        if expect == "lane":
            tally.longest_run = _longest(confident_flags)
        print(tally.row(expect, expect))
        if tally.false_names:
            print(f"  false lanes: {', '.join(tally.false_names[:20])}")
    for flag, text in ((True, "a tape under the camera"), (False, "no tape under the camera")):
        total = under[(flag, True)] + under[(flag, False)]
        if total:
            done = under[(flag, True)]
            print(f"lane frames with {text} (`tape_under_camera`): {total}, "
                  f"{done} with a decision ({100 * done / total:.0f}%)")
    if jitter:
        jitter_no_lane(rs, detector, jitter)
    if sheet is not None and pictures:
        _write_sheets(pictures, sheet / f"{rs.name}{'-narrow' if narrow else ''}")


def _write_sheets(pictures: list[np.ndarray], stem: Path) -> None:
    stem.parent.mkdir(parents=True, exist_ok=True)
    per = 20
    for k in range(0, len(pictures), per):
        chunk = pictures[k:k + per]
        while len(chunk) % 5:
            chunk.append(np.zeros_like(chunk[0]))
        rows = [np.hstack(chunk[i:i + 5]) for i in range(0, len(chunk), 5)]
        cv2.imwrite(f"{stem}-{k // per:03d}.png", np.vstack(rows))


# --------------------------------------------------------------------------- rendered set

def evaluate_rendered(size: tuple[int, int], narrow: bool) -> None:
    width, height = size
    ground: GroundModel = default_ground_model(size)
    print(f"\n### rendered set, {width}x{height}{' (narrow lane)' if narrow else ''}")
    print(HEADER)
    totals: dict[str, Tally] = {}
    for item in rendered_set.labelled_frames():
        try:
            config = _perception(item.perception_overrides(), narrow, "rendered")
            detector = LaneDetector(config, ground=ground)
        except PerceptionConfigError as exc:
            print(f"| {item.name} | refused: {exc} |")
            continue
        image = rendered_set.render(item.picture, width, height)
        obs = detector.detect(image, 0, 0.0)
        on = (obs.left is not None and obs.right is not None
              and rendered_set.edges_on_tapes(obs.left, item.picture, ground)
              and rendered_set.edges_on_tapes(obs.right, item.picture, ground))
        tally = Tally()
        tally.add(item.name, item.expect, obs, on)
        totals.setdefault(item.expect, Tally())
        total = totals[item.expect]
        total.add(item.name, item.expect, obs, on)
        print(tally.row(f"{item.name} ({item.expect}: {item.shows}) c={obs.confidence:.2f}",
                        item.expect))
    for expect, tally in sorted(totals.items()):
        print(tally.row(f"**all {expect}**", expect))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--footage", type=Path, default=DEFAULT_FOOTAGE)
    parser.add_argument("--no-rendered", action="store_true")
    parser.add_argument("--no-real", action="store_true")
    parser.add_argument("--narrow", action="store_true",
                        help="also with lane.width_m at the narrowest the config accepts")
    parser.add_argument("--sheet", type=Path, help="write contact sheets of decisions here")
    parser.add_argument("--jitter", type=int, default=0, metavar="N",
                        help="also judge each real none frame in N versions shifted by a "
                        "fraction of a pixel (seeded)")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    for narrow in (False, True) if args.narrow else (False,):
        if not args.no_real and args.footage.is_dir():
            for rs in real_sets(args.footage):
                evaluate_real(rs, narrow, args.sheet, args.jitter)
        if not args.no_rendered:
            for size in ((640, 480), (320, 240)):
                evaluate_rendered(size, narrow)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
