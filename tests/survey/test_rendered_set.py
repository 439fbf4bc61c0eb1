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


def test_a_held_still_is_a_live_camera_to_the_supervisor_and_the_same_view_to_perception() -> None:
    """The survey's engage test holds a still in view: no capture may repeat one of the last
    RECENT_IMAGES (the supervisor does not count a repeated image: a frozen camera, or one
    cycling through old buffers), and perception must see the same view in all of them (the
    observation of each committed frame is unchanged)."""
    from lanewarden.config import LanewardenConfig
    from lanewarden.perception.detector import LaneDetector
    from lanewarden.supervisor.watchdog import CAPTURE_MARKS, RECENT_IMAGES, frame_fingerprint
    from lanewarden.survey_run import HeldImage

    detector = LaneDetector(LanewardenConfig().perception)
    for path in sorted(RENDERED.glob("*/*.jpg")):
        image = cv2.imread(str(path))
        held = HeldImage(image)
        captures = [held.image(k) for k in range(3 * RECENT_IMAGES)]
        prints = [frame_fingerprint(c) for c in captures]
        assert all(prints[k] not in prints[max(0, k - RECENT_IMAGES):k]
                   for k in range(len(prints))), path.name
        first = detector.detect(captures[0], 0, 0.0)
        assert all(detector.detect(c, 0, 0.0) == first
                   for c in captures[1:CAPTURE_MARKS]), path.name
