"""A tiny campaign spec (short runs at 320x240) for the campaign tests."""

from __future__ import annotations

from pathlib import Path

import pytest

SHORT_LANE = """\
name: short-straight
lane:
  segments:
    - straight_m: 4.0
run:
  max_time_s: 3.5
"""

TINY_SPEC = """\
name: tiny
scenarios: [short-straight.yaml]
cameras:
  - {name: small, width_px: 320, height_px: 240}
floor_seeds: 2
max_time_s: 3.5
faults_per_run: [1, 1]
fault_start_s: [1.8, 2.2]
faults:
  - kind: bumper
    params: {bits: [1, 7]}
  - kind: camera_drop
  - kind: exposure_jump
    params: {intensity: {one_of: [0.1, 0.9]}, duration_s: [0.3, 0.8]}
"""


@pytest.fixture
def tiny_spec(tmp_path: Path) -> Path:
    (tmp_path / "short-straight.yaml").write_text(SHORT_LANE, encoding="utf-8")
    spec = tmp_path / "tiny.yaml"
    spec.write_text(TINY_SPEC, encoding="utf-8")
    return spec
