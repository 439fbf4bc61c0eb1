"""The reports in a real headless browser (Debian's chromium + chromedriver, driven by selenium):
a run's poster is shown whole, its play button below it turns it into the video; a campaign
report's copy button copies the rerun command (or, where the page may not use the clipboard,
selects it). Screenshots are left in the test's folder. Skipped, with the reason, where chromium,
chromedriver or selenium is absent."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from lanewarden.actuation.base import STOP
from lanewarden.scenarios.campaign.report import report_html, summarize
from lanewarden.scenarios.report import write_report
from lanewarden.scenarios.texture import paint_ground
from lanewarden.scenarios.video import MapView, VideoRecorder
from lanewarden.scenarios.world import build_world
from lanewarden.supervisor.loop import StepRecord
from tests.operator.test_live_page_browser import browser  # noqa: F401 (the fixture)
from tests.scenarios.helpers import straight_spec


def _run_folder(folder: Path) -> dict[str, Any]:
    world = build_world(straight_spec(2.0), margin_m=1.0)
    recorder = VideoRecorder(folder / "video.mp4", (320, 240),
                             MapView(world, paint_ground(world, 0.02, 0), 240), fps=10.0,
                             crf=28, preset="ultrafast", title="straight, supervised controller")
    for i, state in enumerate(["HALT", "FOLLOW", "FOLLOW", "HALT"]):
        record = StepRecord(frame_index=i, time_s=i / 10, observation=None,
                            filtered_slope_sum=None, slope_sum_variance=None, state=state,
                            events=(), command=STOP,
                            halt_reason="LANE_LOST: x" if state == "HALT" else None)
        recorder.step(world.start_pose, record)
        recorder.add(np.full((240, 320, 3), 60 + 40 * i, np.uint8), world.start_pose, i / 10,
                     record, None)
    recorder.close()
    (folder / "plot.png").write_bytes(b"")
    return {"halted": True, "outputs": ["plot.png", "poster.jpg", "run.jsonl", "video.mp4"],
            "video_poster": {"shows": recorder.poster_shows, "time_s": recorder.poster_time_s}}


def test_the_poster_is_whole_and_play_turns_it_into_the_video(
        browser: Any, tmp_path: Path) -> None:  # noqa: F811 (the fixture)
    from selenium.webdriver.common.by import By

    metrics = _run_folder(tmp_path)
    write_report(tmp_path / "report.html", {"supervised": metrics}, "One run.", title="T",
                 folders={"supervised": ""})
    browser.get((tmp_path / "report.html").as_uri())
    image = browser.find_element(By.CSS_SELECTOR, ".player img")
    button = browser.find_element(By.CSS_SELECTOR, ".player button.play")
    browser.save_screenshot(str(tmp_path / "poster.png"))
    shown = browser.execute_script(
        "const i = arguments[0], b = arguments[1].getBoundingClientRect();"
        "return [i.complete && i.naturalWidth, i.getBoundingClientRect().bottom, b.top];",
        image, button)
    assert shown[0] > 0, "the poster loaded"
    assert shown[2] >= shown[1], "the play button is below the poster, not on it"
    button.click()
    videos = browser.find_elements(By.TAG_NAME, "video")
    assert len(videos) == 1 and videos[0].get_attribute("src").endswith("/video.mp4")
    assert videos[0].get_attribute("controls") is not None
    assert browser.find_elements(By.CSS_SELECTOR, ".player") == []
    browser.save_screenshot(str(tmp_path / "playing.png"))


def test_a_rerun_command_is_copied_or_selected(browser: Any,  # noqa: F811 (the fixture)
                                               tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    row = {"id": "r00007", "idx": 7, "scenario": "straight", "camera": "small",
           "fault_kinds": "bumper", "outcome": "unsafe", "reason": "crossed a tape",
           "time_to_halt_s": None, "metrics_json": json.dumps({})}
    page = tmp_path / "report.html"
    page.write_text(report_html("spec", summarize([row]), Path("campaign-out"), "text"),
                    encoding="utf-8")
    browser.get(page.as_uri())
    button = browser.find_element(By.CSS_SELECTOR, "button.copy")
    button.click()
    # The page copies through the clipboard's promise, then relabels the button: wait for it
    # (bounded), as a person would look again, rather than read it in the same instant.
    from selenium.webdriver.support.ui import WebDriverWait
    WebDriverWait(browser, 10).until(lambda _: button.text == "copied")
    assert button.text == "copied"
    code = browser.find_element(By.CSS_SELECTOR, "code.cmd")
    assert code.text == f"lanewarden sim --case {Path('campaign-out').resolve()}/cases/r00007.yaml"
    assert code.value_of_css_property("user-select") == "all", "one click selects it all"
    browser.save_screenshot(str(tmp_path / "campaign.png"))


def _slow_halt(index: int, kinds: str, reason: str) -> dict[str, Any]:
    """A safe halt as results.sqlite holds it, with the longest names the default spec draws."""
    before = {"window_s": 2.0, "frames": 60, "confident": 54, "longest_confident_run": 54,
              "usable": 0, "unusable": 6, "no_frame": 0, "jumped": 0, "outliers": 0,
              "at_slope_cap": 0,
              "weakest": {"lane_width": 2, "tape_pair_left": 2, "tape_pair_right": 1}}
    return {"id": f"r{index:05d}", "idx": index, "scenario": "dark-tape-on-light",
            "camera": "320x240", "fault_kinds": kinds, "outcome": "safe_halt", "reason": reason,
            "time_to_halt_s": 0.167, "metrics_json": json.dumps(
                {"max_cross_track_error_m": 0.0003, "before_halt": before})}


def test_the_slowest_halts_fit_a_1280_px_window(browser: Any,  # noqa: F811 (the fixture)
                                                tmp_path: Path) -> None:
    """The review: at 1280 px the table of the slowest safe halts ran off the window's right
    edge, its rerun column out of sight. Now it fits, the command wrapping after its slashes."""
    from selenium.webdriver.common.by import By

    rows = [_slow_halt(0, "checksum_storm,exposure_jump",
                       "LANE_LOST answering exposure_jump (fault 1)"),
            _slow_halt(6, "frame_from_future,perception_exception",
                       "PERCEPTION_ERROR answering perception_exception (fault 1)")]
    out = tmp_path / "campaigns" / "nightly-2024-06-01" / "default-seed-1"
    page = tmp_path / "report.html"
    page.write_text(report_html("default", summarize(rows), out, "text"), encoding="utf-8")
    browser.set_window_size(1280, 2000)
    browser.get(page.as_uri())
    browser.save_screenshot(str(tmp_path / "slowest.png"))
    window, page_width = browser.execute_script(
        "return [document.documentElement.clientWidth, document.documentElement.scrollWidth]")
    assert page_width == window, "the page does not scroll sideways"
    table = browser.find_element(By.CSS_SELECTOR, "h3 + div.wide > table")
    box = browser.execute_script(
        "const t = arguments[0].getBoundingClientRect(), b = arguments[0].parentElement;"
        "return [t.right, b.getBoundingClientRect().right, b.scrollWidth, b.clientWidth];",
        table)
    assert box[0] <= box[1] <= window and box[2] == box[3], "the table fits its box"
    code = browser.find_elements(By.CSS_SELECTOR, "h3 + div.wide td.rerun code.cmd")[0]
    lines = browser.execute_script(
        "const r = arguments[0].getClientRects(); return r.length;", code)
    assert lines >= 2, "the long command wraps"
    assert code.text == f"lanewarden sim --case {out.resolve()}/cases/r00000.yaml"
