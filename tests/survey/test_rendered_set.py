"""The committed rendered survey set (data/survey/rendered) is what `tests.survey.rendered_set`
draws: the same scenes in the same class folders, and a frame rendered again matches its
committed JPEG (up to the JPEG's own error)."""

from __future__ import annotations

import cv2
import numpy as np

from tests.conftest import PROJECT_ROOT
from tests.survey.rendered_set import SCENES, render

RENDERED = PROJECT_ROOT / "data" / "survey" / "rendered"


def test_the_committed_set_has_every_scene_in_its_class_folder() -> None:
    committed = sorted(str(p.relative_to(RENDERED)) for p in RENDERED.glob("*/*.jpg"))
    assert committed == sorted(f"{s.folder}/{s.name}.jpg" for s in SCENES)
    assert sum(s.expect == "lane" for s in SCENES) == 9
    assert sum(s.expect == "none" for s in SCENES) == 10


def test_a_scene_rendered_again_matches_its_committed_frame() -> None:
    scene = next(s for s in SCENES if s.name == "one-tape-left")
    committed = cv2.imread(str(RENDERED / "no-lane" / "one-tape-left.jpg"))
    fresh = render(scene)
    assert committed.shape == fresh.shape == (480, 640, 3)
    difference = np.abs(committed.astype(np.int16) - fresh.astype(np.int16))
    assert float(difference.mean()) < 2.0
