"""The live page in a real headless browser (Debian's chromium + chromedriver, driven by selenium)
during a real `lanewarden run --base sim --view`: it shows the camera image, the state follows the
run, and its Stop button halts the run (OPERATOR_STOP). Skipped, with the reason, where chromium,
chromedriver or selenium is absent (`apt-get install -y chromium chromium-driver`)."""

from __future__ import annotations

import os
import shutil
import signal
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.operator.runs import free_port, long_lane_images, run_beside, steps, wait_until

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")


@pytest.fixture
def browser() -> Iterator[Any]:
    if CHROMIUM is None or CHROMEDRIVER is None:
        pytest.skip("chromium and chromedriver not installed (apt-get install -y chromium "
                    "chromium-driver)")
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium not installed")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    profile = tempfile.mkdtemp(prefix="lanewarden-chromium-")
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage",
                 f"--user-data-dir={profile}", "--window-size=1200,900"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def test_the_page_shows_the_run_and_its_stop_button_halts_it(
        browser: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from selenium.webdriver.common.by import By

    clip = long_lane_images(tmp_path, seconds=12.0)
    record = tmp_path / "run"
    port = free_port()
    seen: dict[str, Any] = {}

    def operator() -> None:
        def text(element_id: str) -> str:
            try:
                return str(browser.find_element(By.ID, element_id).text)
            except Exception:  # noqa: BLE001 (the page may be reloading)
                return ""

        def page_loaded() -> bool:
            try:
                browser.get(f"http://127.0.0.1:{port}/")
                return True
            except Exception:  # noqa: BLE001 (the server is not up yet)
                return False

        try:
            if not wait_until(page_loaded, 30.0, poll_s=0.2):
                return
            seen["image"] = wait_until(lambda: browser.execute_script(
                "const i = document.getElementById('frame');"
                "return i.complete && i.naturalWidth > 0;"), 20.0)
            seen["follow"] = wait_until(lambda: text("state") == "FOLLOW", 20.0)
            browser.save_screenshot(str(tmp_path / "page.png"))
            browser.find_element(By.ID, "stop").click()
            seen["halt"] = wait_until(lambda: text("state") == "HALT", 10.0)
            seen["reason"] = text("reason")
        finally:
            os.kill(os.getpid(), signal.SIGINT)  # the operator's Ctrl-C ends the run

    code = run_beside(operator, ["--camera", str(clip), "--base", "sim", "--view", str(port),
                                 "--record", str(record)])
    assert code == 0, capsys.readouterr().err
    assert seen.get("image"), f"the page never showed the camera image: {seen}"
    assert seen.get("follow"), f"the page never showed FOLLOW: {seen}"
    assert seen.get("halt") and seen.get("reason", "").startswith("OPERATOR_STOP"), seen
    records = steps(record)
    stop = next(k for k, r in enumerate(records)
                if "stop" in r["input"].get("requests", []))
    assert records[stop]["state"] == "HALT" and "OPERATOR_STOP" in records[stop]["events"]
    assert records[stop - 1]["state"] == "FOLLOW", "the page's Stop halted a moving run"
    assert all(r["command"]["linear_m_s"] == 0.0 for r in records[stop:])
