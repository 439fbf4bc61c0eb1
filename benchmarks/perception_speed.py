"""Perception speed: the full lane detector against the bare OpenCV floor, single-threaded.

Run on demand from the project root: `python benchmarks/perception_speed.py [--repeats N]`.

The floor is the lecture's pipeline and nothing else: gray + Gaussian blur + Canny + ROI mask +
HoughLinesP, with exactly the detector's parameters at each size (taken from
`LaneDetector.setup_for`). The detector adds candidate lines, tape-vs-seam edge choice, bounded
slopes and the confidence score. Both run on the same synthetic lane frames (the test suite's
scenes: straight, both bends, dashed, tape on tiles, light tape on a dark floor) at 640x480 and
320x240, with `cv2.setNumThreads(1)`. Times are this process's CPU time (`time.process_time`,
single-threaded), so other work on the machine does not count; floor and detector are timed in
alternation and each keeps its best (minimum) time over the repeats.

Target: detector <= 1.5x the floor at 640x480 and at 320x240. Not a test: nothing here asserts
a speed.

Then, for information, 320x240 frames of each of the simulator's floors (`realism.FLOOR_SETS`):
terrazzo's chips and carpet's texture give 500-odd Hough segments a frame in the floor pipeline
where the six scenes give a few dozen, and what follows Hough grows with them (clustering
compares segment pairs, the choice of tapes line pairs: both sift pairs with numpy beyond a few
dozen). There the detector does not run the floor's Hough: its edge budget
(`perception.canny.max_edge_share`) raises Canny's thresholds until the edges cover at most 15 %
of the floor region (the floor's cover 18-22 %), so its HoughLinesP has fewer pixels to vote
with, and its ratio can fall below 1.

`--stages` also splits the detector's time per frame at each size into its stages, timed in the
order the detector runs them (so each stage pays for the caches the one before left cold:
Python right after HoughLinesP costs about 1.6x what it costs alone in a loop).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

# The synthetic scenes live with the tests; make the project root importable when this file is
# run as a script (`python benchmarks/perception_speed.py`).
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lanewarden.assembly import decision_rule  # noqa: E402
from lanewarden.config import LanewardenConfig  # noqa: E402
from lanewarden.perception.calibration import CameraCalibration, Undistorter  # noqa: E402
from lanewarden.perception.config import PerceptionConfig  # noqa: E402
from lanewarden.perception.detector import LaneDetector  # noqa: E402
from lanewarden.perception.edge_choice import choose_edges  # noqa: E402
from lanewarden.perception.lines import build_line_set  # noqa: E402
from lanewarden.perception.overlay import draw_overlay  # noqa: E402
from lanewarden.scenarios.camera import CameraModel  # noqa: E402
from lanewarden.scenarios.realism import FLOOR_SETS, rendered_straight  # noqa: E402
from tests.perception import synthetic as syn  # noqa: E402

SCENES = {
    "straight": syn.STRAIGHT,
    "bend_left": syn.BEND_LEFT,
    "bend_right": syn.BEND_RIGHT,
    "dashed": syn.DASHED,
    "tiles_with_tape": syn.TILES_WITH_TAPE,
    "light_on_dark": syn.LIGHT_ON_DARK,
}


def floor_pipeline(
    detector: LaneDetector, config: PerceptionConfig
) -> Callable[[np.ndarray], object]:
    """The bare OpenCV pipeline with the detector's parameters (fresh arrays, as a script would)."""
    theta = math.radians(config.hough.theta_deg)

    def run(image: np.ndarray) -> object:
        setup = detector.setup_for(image.shape[1], image.shape[0])
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        smooth = cv2.GaussianBlur(gray, setup.blur_kernel, config.blur.sigma_px)
        edges = cv2.Canny(
            smooth, config.canny.low_threshold, config.canny.high_threshold,
            apertureSize=config.canny.aperture_px,
        )
        masked = cv2.bitwise_and(edges, setup.mask)
        return cv2.HoughLinesP(
            masked, config.hough.rho_px, theta, setup.hough_votes,
            minLineLength=setup.hough_min_length, maxLineGap=setup.hough_max_gap,
        )

    return run


def best_ms_per_frame(
    work: Callable[[np.ndarray], object], frames: list[np.ndarray], loops: int
) -> float:
    start = time.process_time()
    for _ in range(loops):
        for frame in frames:
            work(frame)
    return 1000.0 * (time.process_time() - start) / (loops * len(frames))


def measure(
    pipelines: dict[str, Callable[[np.ndarray], object]],
    frames: list[np.ndarray],
    repeats: int,
    loops: int,
) -> dict[str, float]:
    """Each pipeline's best ms/frame over `repeats` rounds, the pipelines alternating."""
    best = dict.fromkeys(pipelines, math.inf)
    for work in pipelines.values():  # warm-up: per-size setup, caches
        for frame in frames:
            work(frame)
    for _ in range(repeats):
        for name, work in pipelines.items():
            best[name] = min(best[name], best_ms_per_frame(work, frames, loops))
    return best


STAGES = ("prepare", "contrast", "canny + mask", "hough", "lines", "rows", "edge choice",
          "observation")


def stage_ms(detector: LaneDetector, frames: list[np.ndarray], loops: int) -> dict[str, float]:
    """CPU ms per frame of each stage of `LaneDetector.detect` (its private steps, in its order;
    best of five rounds per stage)."""
    config = detector.config
    theta = math.radians(config.hough.theta_deg)
    best = dict.fromkeys(STAGES, math.inf)
    clock = time.process_time_ns
    for _ in range(5):
        spent = dict.fromkeys(STAGES, 0)
        for _ in range(loops):
            for frame in frames:
                t0 = clock()
                state = detector._prepare(frame)
                t1 = clock()
                detector._normalise_contrast(state)
                t2 = clock()
                detector._edges_within_budget(state)
                t3 = clock()
                found = cv2.HoughLinesP(state.edges, config.hough.rho_px, theta,
                                        state.hough_votes, minLineLength=state.hough_min_length,
                                        maxLineGap=state.hough_max_gap)
                segments = None if found is None else np.asarray(found, dtype=np.int32)
                t4 = clock()
                lines = build_line_set(segments, state.smooth, state.y_bottom, state.view,
                                       config.edges, config.tape)
                t5 = clock()
                rows = lines.rows()
                t6 = clock()
                left, right = choose_edges(rows, state.smooth, state, config)
                t7 = clock()
                detector._observe(rows, left, right, state, 0, 0.0, None)
                t8 = clock()
                for name, (a, b) in zip(STAGES, itertools.pairwise((t0, t1, t2, t3, t4, t5, t6,
                                                                    t7, t8)), strict=True):
                    spent[name] += b - a
        for name in STAGES:
            best[name] = min(best[name], spent[name] / 1e6 / (loops * len(frames)))
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15, help="rounds (best one counts)")
    parser.add_argument("--loops", type=int, default=10, help="passes over the frames per round")
    parser.add_argument("--stages", action="store_true",
                        help="also the detector's time per stage at each size")
    args = parser.parse_args()

    cv2.setNumThreads(1)
    config = PerceptionConfig()
    detector = LaneDetector(config)  # sets cv2.setNumThreads(config.opencv_threads) == 1
    floor = floor_pipeline(detector, config)
    print(f"OpenCV {cv2.__version__}, threads {cv2.getNumThreads()}, "
          f"scenes: {', '.join(SCENES)}")
    print(f"{'size':>8}  {'floor ms':>9}  {'detector ms':>11}  {'ratio':>6}")
    for width, height in ((640, 480), (320, 240)):
        frames = [np.ascontiguousarray(syn.render(s, width, height)) for s in SCENES.values()]
        best = measure(
            {"floor": floor, "detector": lambda f: detector.detect(f, 0, 0.0)},
            frames, args.repeats, args.loops,
        )
        print(f"{width}x{height:<4}  {best['floor']:9.3f}  {best['detector']:11.3f}  "
              f"{best['detector'] / best['floor']:6.2f}")
        if args.stages:
            stages = stage_ms(detector, frames, args.loops * 3)
            print("          " + ", ".join(f"{name} {ms:.3f}" for name, ms in stages.items()))

    # Per scene at 640x480, and the optional extras, for information.
    print("\n640x480 per scene (floor / detector ms, ratio):")
    for name, scene in SCENES.items():
        frame = [np.ascontiguousarray(syn.render(scene))]
        best = measure(
            {"floor": floor, "detector": lambda f: detector.detect(f, 0, 0.0)},
            frame, max(3, args.repeats // 2), args.loops * 3,
        )
        print(f"  {name:16s} {best['floor']:.3f} / {best['detector']:.3f}  "
              f"{best['detector'] / best['floor']:.2f}")
    camera = CameraModel()
    undistorting = LaneDetector(
        config,
        Undistorter(CameraCalibration(camera.camera_matrix(), camera.distortion(), (640, 480))),
    )
    distorted = [np.ascontiguousarray(syn.render(s, distorted=True)) for s in SCENES.values()]

    decide = decision_rule(LanewardenConfig())  # the supervisor's thresholds, as `detect`'s

    def with_overlay(f: np.ndarray) -> object:
        obs, debug = detector.detect_debug(f, 0, 0.0)
        return draw_overlay(debug.image, obs, debug, decide(obs))

    frames = [np.ascontiguousarray(syn.render(s)) for s in SCENES.values()]
    extra = measure(
        {"undistort": lambda f: undistorting.detect(f, 0, 0.0)}, distorted, 5, args.loops
    ) | measure({"overlay": with_overlay}, frames, 5, args.loops)
    print(f"\n640x480 detector with undistortion (remap): {extra['undistort']:.3f} ms/frame")
    print(f"640x480 detect_debug + draw_overlay (debug path, not the hot path): "
          f"{extra['overlay']:.3f} ms/frame")

    # The six scenes are clean: a few dozen Hough segments. A textured floor gives hundreds (in
    # the floor pipeline; the detector keeps its edges within the budget).
    print("\n320x240 on the simulator's floors (a straight lane, 10 frames each; floor / "
          "detector ms, ratio,\nmost Hough segments in a frame):")
    for name, changes, effects_on in FLOOR_SETS:
        rendered, _ = rendered_straight(changes, effects_on, 10)
        frames = [cv2.cvtColor(f, cv2.COLOR_GRAY2BGR) for f in rendered]  # as a camera gives
        segments = max(len(detector.detect_debug(f, 0, 0.0)[1].segments) for f in frames)
        best = measure(
            {"floor": floor, "detector": lambda f: detector.detect(f, 0, 0.0)},
            frames, max(3, args.repeats // 3), args.loops,
        )
        print(f"  {name:28s} {best['floor']:.3f} / {best['detector']:.3f}  "
              f"{best['detector'] / best['floor']:.2f}  ({segments} segments)")


if __name__ == "__main__":
    main()
