"""The realism statistics (scenarios.realism) measure what they say, and docs/scenarios.md's
"Does it look real?" tables are what `python benchmarks/realism.py` computes now (the real
Donkeycar frames from the shared data folder: skipped without it; the real JetBot frames from
the repo's data/real). Heavy: the two tables render
and analyse some 2500 frames (about 30 s on the development machine)."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from types import ModuleType

import cv2
import numpy as np
import pytest

from lanewarden.config import LanewardenConfig
from lanewarden.scenarios.realism import confident_runs, noise_levels
from tests.conftest import shared_data

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "scenarios.md"


def test_noise_estimate_reads_the_noise_not_the_shading() -> None:
    rng = np.random.default_rng(0)
    ramp = np.add.outer(np.linspace(40, 200, 240), np.linspace(0, 30, 320))
    for sigma in (2.0, 6.0):
        noisy = np.clip(np.rint(ramp + rng.normal(0, sigma, ramp.shape)), 0, 255).astype(np.uint8)
        assert noise_levels(noisy) == pytest.approx(sigma, rel=0.08)
    assert noise_levels(np.rint(ramp).astype(np.uint8)) < 0.5
    mask = np.zeros((240, 320), np.uint8)
    mask[:, :160] = 255
    half = np.rint(ramp).astype(np.uint8)
    half[:, 160:] = cv2.add(half[:, 160:], rng.integers(0, 40, (240, 160), dtype=np.uint8))
    assert noise_levels(half, mask) < 0.6  # only the masked (smooth) half counts


def test_confident_runs() -> None:
    assert confident_runs([True, True, False, True, False, False, True, True, True]) == [2, 1, 3]
    assert confident_runs([False, False]) == []
    assert confident_runs([True] * 4) == [4]


def _benchmark() -> ModuleType:
    spec = importlib.util.spec_from_file_location("realism_benchmark",
                                                  ROOT / "benchmarks" / "realism.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _doc_table(marker: str) -> list[list[str]]:
    text = DOC.read_text(encoding="utf-8")
    block = text.split(f"<!-- realism:{marker} -->")[1].split(f"<!-- /realism:{marker} -->")[0]
    return [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in block.strip().splitlines()[2:]]


def _numbers(cell: str) -> list[float]:
    return [float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", cell)]


#: How far a documented number may be from today's computation, per column (OpenCV builds
#: differ in the last digits of JPEG and interpolation).
TOLERANCE = (None, 2.0, 0.02, 0.3, 0.005, 2.0, 2.0, 2.0)


def _assert_matches(doc: list[list[str]], computed: str) -> None:
    rows = [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in computed.splitlines()[2:]]
    assert [r[0] for r in doc] == [r[0] for r in rows], "the table's rows changed"
    for want, got in zip(doc, rows, strict=True):
        for column, (a, b) in enumerate(zip(want[1:], got[1:], strict=True), start=1):
            tolerance = TOLERANCE[column]
            assert tolerance is not None
            assert _numbers(a) == pytest.approx(_numbers(b), abs=tolerance), (
                f"docs/scenarios.md, {want[0]}, column {column}: {a} documented, {b} now "
                "(rerun python benchmarks/realism.py and paste its tables)")


ENGAGE = LanewardenConfig().supervisor.engage_confident_frames


def test_the_docs_floor_table_is_current() -> None:
    bench = _benchmark()
    _assert_matches(_doc_table("floors"), bench.table(bench.floors(bench.FRAMES), ENGAGE))


def test_the_docs_real_frames_table_is_current() -> None:
    folder = shared_data("donkeycar-tub")
    bench = _benchmark()
    rows = bench.compare(bench.tub_frames(folder), bench.FRAMES)
    _assert_matches(_doc_table("tub"), bench.table(rows, ENGAGE))


def test_the_docs_jetbot_table_is_current() -> None:
    bench = _benchmark()
    rows = bench.jetbot(bench.jetbot_frames(), bench.FRAMES)
    _assert_matches(_doc_table("jetbot"), bench.table(rows, ENGAGE))
