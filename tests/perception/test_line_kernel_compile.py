"""Perception's compiled kernel (`perception.line_kernel`, numba): the first detector of a fresh
install compiles it, once, and says so in one line on stderr before the wait; every later run
loads it from numba's cache and says nothing (a command's stderr stays its own)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from lanewarden.perception.line_kernel import COMPILING

MAKE_A_DETECTOR = ("from lanewarden.perception.config import PerceptionConfig; "
                   "from lanewarden.perception.detector import LaneDetector; "
                   "LaneDetector(PerceptionConfig())")


def detector_stderr(cache: Path) -> str:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}  # an empty cache: a fresh install
    done = subprocess.run([sys.executable, "-c", MAKE_A_DETECTOR], env=env, capture_output=True,
                          text=True, timeout=300, check=True)
    return done.stderr


def test_the_first_detector_says_it_compiles_and_later_ones_load_quietly(tmp_path: Path) -> None:
    assert detector_stderr(tmp_path) == COMPILING + "\n"
    assert any(tmp_path.rglob("*.nbi"))  # (the cache numba wrote)
    assert detector_stderr(tmp_path) == ""
