"""What does recording a run cost? CPU time per frame and disk per minute, for each way of storing
frames, at 640x480 and 320x240 and 30 frames per second. (The issue's targets at 640x480/30 fps:
at most 10 % of one core on this machine and 200 MiB a minute, exact replay kept.)

Frames: the lane rendered by the simulator's camera with its sensor noise (sigma 2 grey levels)
over a tiled floor, moving at 0.6 m/s; and the 13 real 640x480 photos of the shared chessboard
set (JPEG-compressed at source; for a second opinion on real pixels).

Two measurements:
- the codec alone, per frame (CPU time of the encode, `time.process_time`): PNG of the colour
  frame with OpenCV at compression 1 (what recording did before run.mcap), PNG of the gray frame
  with OpenCV (zlib at its cheapest), the gray PNG of lanewarden.frame_png (ISA-L, SUB filter:
  `--record-gray`, the default of format 2; gray conversion included), the PNG of perception's
  prepared input (`LaneDetector.prepare`: gray, blur; UP filter: the default now; preparation
  included), JPEG 90 of the colour frame (--record-lossy);
- the whole recorder (lanewarden.recording.RunRecorder: the preparation or gray conversion, PNG,
  the fingerprint, CDR, MCAP, the step messages, the writer thread, the file) fed one step per
  frame as the run feeds it: the process's CPU time per frame, the file's size per minute at 30
  frames per second; for the default also with a lens calibration (undistortion included).

The last column estimates the share of one Raspberry Pi 4 core: this machine's CPU time times
PI4_SLOWDOWN (an estimate, not a measurement; see docs/operator.md). Prints the machine's load
with the figures (a shared machine inflates CPU times; the lead re-measures on a quiet one). On
demand only:
    python benchmarks/recording_cost.py [--frames 90]
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lanewarden.actuation.base import BaseFeedback, VelocityCommand  # noqa: E402
from lanewarden.frame_png import FILTER_UP, gray_png  # noqa: E402
from lanewarden.perception.calibration import Undistorter  # noqa: E402
from lanewarden.perception.config import PerceptionConfig  # noqa: E402
from lanewarden.perception.detector import LaneDetector, perception_gray  # noqa: E402
from lanewarden.recording import RunRecorder, create_run_folder  # noqa: E402
from lanewarden.run_mcap import CAMERA_GRAY, CAMERA_JPEG, PERCEPTION_INPUT  # noqa: E402
from lanewarden.run_record import StepInput  # noqa: E402
from lanewarden.scenarios.camera import CameraModel  # noqa: E402
from lanewarden.supervisor.loop import Frame, StepRecord  # noqa: E402
from tests.operator.clips import lane_end_frames  # noqa: E402

FPS = 30.0
CHESSBOARD = ROOT.parent / "shared" / "data" / "chessboard" / "opencv-left"
MIB = 2**20
#: How many times longer a Raspberry Pi 4 (Cortex-A72, 1.5 GHz) takes for this kind of code than
#: this machine (an estimate from published single-core benchmarks: 3-4 times; see
#: docs/operator.md); the Pi column uses the upper end.
PI4_SLOWDOWN = 4.0
_PREPARE = LaneDetector(PerceptionConfig())

CODECS: dict[str, Callable[[np.ndarray], bytes]] = {
    "PNG colour, OpenCV compression 1 (before)": lambda f: cv2.imencode(
        ".png", f, [cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_FILTER,
                    cv2.IMWRITE_PNG_FILTER_UP])[1].tobytes(),
    "PNG gray, OpenCV compression 1": lambda f: cv2.imencode(
        ".png", perception_gray(f), [cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_FILTER,
                                     cv2.IMWRITE_PNG_FILTER_SUB])[1].tobytes(),
    "PNG gray, frame_png (--record-gray)": lambda f: gray_png(perception_gray(f)),
    "PNG prepared, frame_png (default)": lambda f: gray_png(_PREPARE.prepare(f), FILTER_UP),
    "JPEG 90 colour (--record-lossy)": lambda f: cv2.imencode(
        ".jpg", f, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes(),
}
#: The whole recorder's rows: (name, frames kept, undistort with a lens calibration).
RECORDERS = (
    ("whole recorder, prepared PNG (default)", PERCEPTION_INPUT, False),
    ("whole recorder, prepared PNG, calibrated", PERCEPTION_INPUT, True),
    ("whole recorder, gray PNG (--record-gray)", CAMERA_GRAY, False),
    ("whole recorder, JPEG (--record-lossy)", CAMERA_JPEG, False),
)


def codec_costs(frames: list[np.ndarray], repeat: int = 3) -> dict[str, tuple[float, float]]:
    """{codec: (CPU ms per frame, MiB per minute at FPS)}."""
    out = {}
    for name, encode in CODECS.items():
        encode(frames[0])  # warm up
        started = time.process_time()
        sizes = [len(encode(f)) for _ in range(repeat) for f in frames]
        cpu = (time.process_time() - started) / len(sizes)
        out[name] = (cpu * 1000, float(np.mean(sizes)) * FPS * 60 / MIB)
    return out


def recorder_cost(frames: list[np.ndarray], image_kind: str,
                  calibrated: bool) -> tuple[float, float]:
    """(CPU ms per frame, MiB per minute) of the whole recorder, one step per frame."""
    height, width = frames[0].shape[:2]
    undistorter = (Undistorter(CameraModel(width_px=width, height_px=height).calibration())
                   if calibrated else None)
    with tempfile.TemporaryDirectory() as tmp:
        folder = create_run_folder(Path(tmp) / "run")
        started = time.process_time()
        recorder = RunRecorder(folder, image_kind=image_kind)
        recorder.prepare_with(LaneDetector(PerceptionConfig(), undistorter))
        for i, image in enumerate(frames):
            while i - recorder.summary.frames_written >= 32:  # paced like a camera: no drops
                time.sleep(0.005)
            t = 100.0 + i / FPS
            record = StepRecord(i, t, None, 0.5, 0.01, "FOLLOW", (),
                                VelocityCommand(0.2, 0.01), None, t - 0.01)
            recorder.record(record, StepInput(t=t, frame=(i, t - 0.01),
                                              feedback=BaseFeedback(received_at_s=t),
                                              command=(0.2, 0.01)),
                            Frame(image.copy(), i, t - 0.01))
        summary = recorder.close({})
        cpu = time.process_time() - started
        assert summary.complete, summary
        size = (folder / "run.mcap").stat().st_size
    return cpu / len(frames) * 1000, size / len(frames) * FPS * 60 / MIB


def _row(name: str, ms: float, mib: float) -> None:
    share = ms * FPS / 10
    print(f"  {name:44s} {ms:8.2f} ms {share:10.1f} % {mib:8.0f} {share * PI4_SLOWDOWN:10.0f} %")


def report(title: str, frames: list[np.ndarray]) -> None:
    print(f"\n{title}: {len(frames)} frames {frames[0].shape[1]}x{frames[0].shape[0]}")
    print(f"  {'':44s} {'CPU/frame':>10s} {'% of a core':>12s} {'MiB/min':>8s} "
          f"{'Pi 4 est.':>11s}")
    for name, (ms, mib) in codec_costs(frames).items():
        _row(name, ms, mib)
    for name, image_kind, calibrated in RECORDERS:
        _row(name, *recorder_cost(frames, image_kind, calibrated))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=90)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores")
    seconds = args.frames / FPS
    for size in ((640, 480), (320, 240)):
        frames = lane_end_frames(start_m=0.5, end_m=0.5 + 0.6 * seconds, speed_m_s=0.6,
                                 size=size)[: args.frames]
        report("rendered lane (sensor noise, tiled floor)", frames)
    photos = [cv2.imread(p) for p in sorted(glob.glob(str(CHESSBOARD / "*.jpg")))]
    if photos:
        report("real photos (shared chessboard set)", photos)
    else:
        print(f"\n(no real photos: {CHESSBOARD} is absent)")
    load = os.getloadavg()
    print(f"\nload average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} at the end")


if __name__ == "__main__":
    main()
