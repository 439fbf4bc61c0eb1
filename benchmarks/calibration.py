"""Calibration speed: corner detection per view, calibrateCameraExtended, per-frame undistortion.

Run on demand: `python benchmarks/calibration.py`. Prints one line per measurement (median of
repeats, wall clock). Not a test: nothing here asserts a speed.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import cv2
import numpy as np

from lanewarden.perception.calibration import CameraCalibration, Undistorter
from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.chessboard import ChessboardPattern, detect_view
from lanewarden.perception.chessboard_calibration import calibrate_views
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.chessboard import ChessboardRenderer, calibration_poses


def _median_ms(work: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times)


def main() -> None:
    cv2.setNumThreads(1)
    camera = CameraModel()
    config = CalibrationConfig()
    pattern = ChessboardPattern(9, 6)
    start = time.perf_counter()
    renderer = ChessboardRenderer(camera)
    print(f"renderer set-up (viewing rays, 640x480): {1000 * (time.perf_counter() - start):.1f} ms")
    rng = np.random.default_rng(1)
    poses = calibration_poses(renderer, 40, rng)
    images = [renderer.render(p, noise_sigma=2.0, rng=rng) for p in poses]
    print(f"render one view: {_median_ms(lambda: renderer.render(poses[0]), 10):.1f} ms")
    print(f"detect_view, board present: "
          f"{_median_ms(lambda: detect_view(images[0], pattern, config, name='x'), 10):.1f} ms")
    wall = np.full((480, 640), 100, np.uint8)
    wall = np.clip(wall + rng.normal(0, 2, wall.shape), 0, 255).astype(np.uint8)
    print(f"detect_view, no board: "
          f"{_median_ms(lambda: detect_view(wall, pattern, config, name='x'), 5):.1f} ms")
    views = [detect_view(im, pattern, config, name=str(i)) for i, im in enumerate(images)]
    for count in (15, 40):
        ms = _median_ms(
            lambda n=count: calibrate_views(views[:n], pattern, 0.025, (640, 480), config), 3
        )
        print(f"calibrate_views, {count} views: {ms:.0f} ms")
    calibration = CameraCalibration(camera.camera_matrix(), camera.distortion(), (640, 480))
    start = time.perf_counter()
    undistorter = Undistorter(calibration)
    print(f"Undistorter set-up (remap tables): {1000 * (time.perf_counter() - start):.1f} ms")
    frame = cv2.cvtColor(images[0], cv2.COLOR_GRAY2BGR)
    ms = _median_ms(lambda: undistorter.apply(frame), 50)
    print(f"Undistorter.apply, 640x480 BGR: {ms:.2f} ms")
    k, d = calibration.camera_matrix, calibration.dist_coeffs
    print(f"cv2.undistort (no cached tables), 640x480 BGR: "
          f"{_median_ms(lambda: cv2.undistort(frame, k, d), 20):.2f} ms")


if __name__ == "__main__":
    main()
