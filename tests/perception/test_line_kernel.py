"""Perception's compiled kernel (`perception.line_kernel`, numba): the first detector of a fresh
install compiles it, once, and says so in one line on stderr before the wait; every later run
loads it from numba's cache and says nothing (a command's stderr stays its own). Where numba is
not installed (no wheels for 32-bit ARM) the same loops run interpreted, with the same lines, bit
for bit, and the detector says so."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from benchmarks.perception_speed import SCENES
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.line_kernel import COMPILING, INTERPRETED
from tests.conftest import PROJECT_ROOT
from tests.perception import synthetic

MAKE_A_DETECTOR = ("from lanewarden.perception.config import PerceptionConfig; "
                   "from lanewarden.perception.detector import LaneDetector; "
                   "LaneDetector(PerceptionConfig())")
#: In a fresh interpreter, before anything imports it: `import numba` fails, as where it is not
#: installed.
WITHOUT_NUMBA = "import sys; sys.modules['numba'] = None; "


def python(code: str, **env: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], cwd=PROJECT_ROOT,
                          env={**os.environ, **env}, capture_output=True, text=True,
                          timeout=300, check=True)


def test_the_first_detector_says_it_compiles_and_later_ones_load_quietly(tmp_path: Path) -> None:
    cache = str(tmp_path)  # an empty cache: a fresh install
    assert python(MAKE_A_DETECTOR, NUMBA_CACHE_DIR=cache).stderr == COMPILING + "\n"
    assert any(tmp_path.rglob("*.nbi"))  # (the cache numba wrote)
    assert python(MAKE_A_DETECTOR, NUMBA_CACHE_DIR=cache).stderr == ""


def test_the_first_frames_compile_nothing_more() -> None:
    """`ready` (at the detector's construction, before `run` opens the base) compiles the
    kernel for the very types perception passes it: the first frames, rendered at both sizes
    and real, wait for no compile (a warm-up of other types once left a second compile of
    about 2 s, longer on a Pi, for the first frame: a stalled loop)."""
    # each entry point perception calls: compiled once by the detector's construction (before
    # any frame), and for no other types by the frames (median_signs, called by `lines` for a
    # line's least-lit half, had been left to the first frame that needed it)
    done = python("from tests.perception.test_line_kernel import lines_digest; "
                  "from lanewarden.perception import line_kernel; "
                  "from lanewarden.perception.config import PerceptionConfig; "
                  "from lanewarden.perception.detector import LaneDetector; "
                  "count = lambda: [len(f.signatures) for f in "
                  "(line_kernel.measure_lines, line_kernel.median_signs)]; "
                  "LaneDetector(PerceptionConfig()); made = count(); lines_digest(); "
                  "print(made, count())")
    assert done.stdout.strip() == "[1, 1] [1, 1]"


def test_with_nowhere_to_cache_it_the_kernel_is_compiled_in_each_run() -> None:
    """A read-only install and home (a hardened service, a read-only robot image): numba finds
    no writable place for its cache (here: none of its places is tried) and refuses to cache;
    perception then compiles the kernel in every run, and says so each time, instead of failing
    to start."""
    no_place = "import numba.core.caching as c; c.CacheImpl._locator_classes = []; "
    for _ in range(2):
        assert python(no_place + MAKE_A_DETECTOR).stderr == COMPILING + "\n"


def lines_digest() -> str:
    """Every candidate line's numbers and every observation of the speed benchmark's rendered
    scenes at 320x240 and of every 40th frame of the repo's real JetBot set, as one digest."""
    frames = [np.ascontiguousarray(synthetic.render(scene, width, height))
              for scene in SCENES.values() for width, height in ((320, 240), (640, 480))]
    real = sorted((PROJECT_ROOT / "data/real/jetbot-tape-lane").glob("*/*.jpg"))[::40]
    frames += [cv2.imread(str(path)) for path in real]
    assert len(frames) >= 20  # (not vacuous)
    digest = hashlib.sha256()
    for frame in frames:
        observation, debug = LaneDetector(PerceptionConfig()).detect_debug(frame, 0, 0.0)
        for name, value in sorted(vars(debug.lines).items()):
            digest.update(name.encode() + value.tobytes())
        digest.update(repr(observation).encode())
    return digest.hexdigest()


def test_the_loops_interpreted_give_the_compiled_lines_bit_for_bit() -> None:
    """A machine without numba runs the same loops as plain Python: every candidate line and
    observation of real and rendered frames is the same, bit for bit, and the detector says,
    once, that it runs them interpreted."""
    done = python(WITHOUT_NUMBA + "from tests.perception.test_line_kernel import lines_digest; "
                  "print(lines_digest())")
    assert done.stdout.strip() == lines_digest()
    assert done.stderr == INTERPRETED + "\n"
