"""The live page in a real headless browser (Debian's chromium + chromedriver, driven by selenium).

- During a real `lanewarden run --base sim --view`: the page shows the camera image with the panel
  of the same step (the picture's box as tall as the picture, not as the panel beside it), its
  plot updates, its buttons are enabled by the rule, and its Stop halts the run (OPERATOR_STOP)
  and is announced on the terminal. A screenshot is saved in the test's folder.
- Issue 18's attacks where a browser matters, against a halted robot (the view's requests record
  what would reach it): another site's page (a second local server, another host name and port)
  smuggling a POST /resume in the body of a no-cors fetch or a text/plain form; a DNS-rebinding
  page (the same origin, then the view behind it); another site's page showing the camera
  picture in an <img> (review finding 7); and on a non-loopback bind the token, taken from the
  address once and never left in it.
Skipped, with the reason, where chromium, chromedriver or selenium is absent (`apt-get install -y
chromium chromium-driver`)."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import tempfile
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from lanewarden.live_view import LiveView, ViewFrame
from tests.operator.clips import lane_end_frames, write_images
from tests.operator.runs import free_port, run_beside, steps, wait_until
from tests.operator.test_live_view import Requests, View, _wait_for_frame

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
#: Every *.example name resolves to this machine in the test's browser (attacker sites).
RESOLVER_RULES = "MAP *.example 127.0.0.1"
#: This test is about the page, not the watchdog: Chromium shares the CPU with the run, so frames
#: may come late on a loaded machine (the watchdog's own tests keep the defaults).
PATIENT_CONFIG = """supervisor:
  frame_late_s: 0.5
  frame_stale_s: 1.0
  frame_frozen_s: 2.0
  base_feedback_late_s: 0.5
  base_link_timeout_s: 1.0
  lane_lost_halt_s: 1.0
  degraded_budget_s: 10.0
"""


def lasting_lane_images(folder: Path, seconds: float = 20.0) -> Path:
    """A straight lane for `seconds`, the camera moving slowly enough (0.12 m/s from 0.3 m) that
    the rendered tape lasts the whole clip (at 0.4 m/s it ends after about 7 s): a run engages
    and a resume could engage again at any time."""
    return write_images(lane_end_frames(start_m=0.3, end_m=0.3 + 0.12 * seconds,
                                        speed_m_s=0.12), folder / "lane")


@pytest.fixture(scope="module")
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
                 f"--user-data-dir={profile}", "--window-size=1200,900",
                 f"--host-resolver-rules={RESOLVER_RULES}",
                 "--disable-features=HttpsUpgrades,HttpsFirstBalancedModeAutoEnable"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_script_timeout(20)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def js(driver: Any, script: str, *args: Any) -> Any:
    try:
        return driver.execute_script(script, *args)
    except Exception:  # noqa: BLE001 (the page may be loading)
        return None


# ---- the page during a real run -----------------------------------------------------------------
def test_the_page_shows_the_run_and_its_stop_button_halts_it(
        browser: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from selenium.webdriver.common.by import By

    clip = lasting_lane_images(tmp_path)
    record = tmp_path / "run"
    config = tmp_path / "patient.yaml"
    config.write_text(PATIENT_CONFIG, encoding="utf-8")
    port = free_port()
    seen: dict[str, Any] = {}
    live = "return window.lanewarden"

    def buttons() -> dict[str, bool]:
        return {b: browser.find_element(By.ID, b).is_enabled()
                for b in ("start", "resume", "stop")}

    def operator() -> None:
        def page_loaded() -> bool:
            try:
                browser.get(f"http://127.0.0.1:{port}/")
                return True
            except Exception:  # noqa: BLE001 (the server is not up yet)
                return False

        def following_with_its_frame() -> bool:
            state = js(browser, live)
            return bool(state and state["frameStatus"] and state["latest"]
                        and state["latest"]["state"] == "FOLLOW"
                        and state["frameStatus"]["state"] == "FOLLOW"
                        and state["panelStep"] == state["frameStatus"]["step"]
                        and len(state["plot"]["samples"]) > 10)

        try:
            if not wait_until(page_loaded, 30.0, poll_s=0.2):
                return
            seen["image"] = wait_until(lambda: js(
                browser, "const i = document.getElementById('frame');"
                "return i.complete && i.naturalWidth > 0;"), 20.0)
            seen["follow"] = wait_until(following_with_its_frame, 30.0)
            first = js(browser, live)
            # The plot's data changes from one poll to a later one (counted polls, not time).
            wait_until(lambda: js(browser, live)["polls"] >= first["polls"] + 3, 10.0)
            later = js(browser, live)
            seen["plot"] = (first["plot"]["lastStep"], later["plot"]["lastStep"],
                            first["plot"]["draws"], later["plot"]["draws"])
            # all three read in one script: the page polls on while the test reads, and a
            # frame status read a poll earlier than the panel is a race in the test, not a page
            # that shows another frame's panel
            *panel, frame_step = js(browser, "return [window.lanewarden.panelStep, "
                                    "document.getElementById('step').textContent, "
                                    "window.lanewarden.frameStatus.step]")
            seen["same_step"] = (panel, frame_step)
            seen["buttons_follow"] = buttons()
            seen["heights"] = js(browser, "const h = (id) => document.getElementById(id)"
                                 ".getBoundingClientRect().height;"
                                 "return [h('camera'), h('frame'), h('panel')];")
            shot = tmp_path / "live-page.png"
            browser.save_screenshot(str(shot))
            seen["screenshot"] = shot
            browser.find_element(By.ID, "stop").click()
            seen["halt"] = wait_until(lambda: browser.find_element(By.ID, "state").text == "HALT"
                                      and not buttons()["stop"], 10.0)
            seen["reason"] = browser.find_element(By.ID, "reason").text
            seen["buttons_halt"] = buttons()
            browser.save_screenshot(str(tmp_path / "live-page-halted.png"))
        finally:
            os.kill(os.getpid(), signal.SIGINT)  # the operator's Ctrl-C ends the run
        # the page gets the run's last status before the server closes (it had kept showing
        # the last state): why it ended, then, with no more answers, "the run has ended"
        seen["ended"] = wait_until(lambda: (js(browser, "return [document.getElementById("
                                                "'ended').textContent, document.getElementById("
                                                "'conn').textContent]") or ["", ""])[1]
                                   .startswith("the run has ended; this page no longer"), 20.0)
        seen["ended_text"] = js(browser, "return document.getElementById('ended').textContent")
        # nothing is left to press once the run has ended (Resume had been enabled a moment,
        # then Stop alone, under "the run has ended": an instructor's review)
        seen["buttons_ended"] = buttons()

    code = run_beside(operator, ["--camera", str(clip), "--base", "sim", "--view", str(port),
                                 "--record", str(record), "--config", str(config)])
    out, err = capsys.readouterr()
    with capsys.disabled():
        print(f"\nscreenshots of the live page: {tmp_path / 'live-page.png'}, "
              f"{tmp_path / 'live-page-halted.png'}")
    assert code == 0, err
    assert seen.get("image"), f"the page never showed the camera image: {seen}"
    assert seen.get("follow"), f"the page never showed FOLLOW with its own frame's panel: {seen}"
    before, after, draws_before, draws_after = seen["plot"]
    assert after > before and draws_after > draws_before, f"the plot did not update: {seen}"
    (panel_step, step_text), frame_step = seen["same_step"]
    assert panel_step == frame_step and step_text == f"step {frame_step}", seen["same_step"]
    assert seen["buttons_follow"] == {"start": False, "resume": False, "stop": True}
    camera, picture, panel = seen["heights"]
    assert panel > picture + 100, f"the panel beside the picture is taller: {seen['heights']}"
    assert abs(camera - picture) <= 1, f"no black area under the picture: {seen['heights']}"
    assert seen.get("halt") and seen.get("reason", "").startswith("OPERATOR_STOP"), seen
    assert seen["buttons_halt"] == {"start": False, "resume": True, "stop": False}
    assert seen.get("ended"), seen
    assert seen["ended_text"] == "run ended: operator stop (SIGINT)", seen
    assert seen["buttons_ended"] == {"start": False, "resume": False, "stop": False}, seen
    assert seen["screenshot"].stat().st_size > 10_000
    assert "stop requested (page)" in out, "the page's stop is announced like the others"
    assert "Traceback" not in out + err
    records = steps(record)
    stop = next(k for k, r in enumerate(records)
                if "stop" in r["input"].get("requests", []))
    assert records[stop]["state"] == "HALT" and "OPERATOR_STOP" in records[stop]["events"]
    assert records[stop - 1]["state"] == "FOLLOW", "the page's Stop halted a moving run"
    assert all(r["command"]["linear_m_s"] == 0.0 for r in records[stop:])


# ---- attacks from other pages -------------------------------------------------------------------
class Site:
    """A second local web server serving one page: another site (name and port) in the browser."""

    def __init__(self, page: str, port: int = 0) -> None:
        body = page.encode()

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802
                self.send_response(200)
                self.send_header("Content-Type", "text/html; charset=utf-8")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
                pass

        connections: list[socket.socket] = []
        self.connections = connections

        class Server(ThreadingHTTPServer):
            def process_request(self, request: Any, client_address: Any) -> None:
                connections.append(request)
                super().process_request(request, client_address)

        self.server = Server(("127.0.0.1", port), Handler)
        self.port = int(self.server.server_address[1])
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        """Gone for good: also the connections the browser opened ahead and keeps idle."""
        self.server.shutdown()
        self.server.server_close()
        for connection in self.connections:
            try:
                connection.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        self.thread.join(5)


@pytest.fixture
def halted_view() -> Iterator[tuple[LiveView, Requests]]:
    """A view of a robot halted by the operator (what an attacker wants to resume)."""
    requests = Requests()
    view = LiveView("127.0.0.1", 0, requests, log=lambda line: None)
    view.publish({"state": "HALT", "step": 1, "halt_reason": "OPERATOR_STOP: operator stop",
                  "started": True, "armed": False}, None)
    try:
        yield view, requests
    finally:
        view.close()


def _smuggled(port: int) -> str:
    return (f"POST /resume HTTP/1.1\\r\\nHost: 127.0.0.1:{port}\\r\\nX-Lanewarden: 1\\r\\n"
            "Content-Length: 0\\r\\n\\r\\n")


def _reached(view: LiveView, refused: int) -> bool:
    """The attack's request reached the view, was refused, and its connection is closed (so
    anything smuggled in it would have been served by now)."""
    return view.counts["refused"] >= refused and view.open_connections == 0


@pytest.mark.parametrize("padding", [4096, 16])
@pytest.mark.parametrize("how", ["no-cors fetch", "text/plain form"])
def test_another_sites_page_cannot_smuggle_a_resume(
        browser: Any, halted_view: tuple[LiveView, Requests], how: str, padding: int) -> None:
    """Issue 18: a page on another site POSTs /stop with a body of padding then a complete POST
    /resume with the header (4096 bytes: what the old server read; 16: within the limit)."""
    view, requests = halted_view
    target = f"http://127.0.0.1:{view.port}"
    site = Site("<!doctype html><title>cat pictures</title><p>nothing to see")
    try:
        browser.get(f"http://attacker.example:{site.port}/")
        smuggled = _smuggled(view.port)
        if how == "no-cors fetch":
            result = browser.execute_async_script(f"""
                const done = arguments[arguments.length - 1];
                fetch("{target}/stop", {{method: "POST", mode: "no-cors",
                                         body: "a".repeat({padding}) + "{smuggled}"}})
                  .then(() => done("sent"), (e) => done("failed: " + e));""")
            # the answer is withheld from the page (Cross-Origin-Resource-Policy: same-origin),
            # so the fetch's promise rejects; the request itself went out: the view counts it
            # as refused below
            assert result == "failed: TypeError: Failed to fetch"
        else:
            browser.execute_script(f"""
                const form = document.createElement("form");
                form.method = "POST"; form.enctype = "text/plain"; form.action = "{target}/stop";
                const field = document.createElement("textarea");  // keeps the line breaks
                field.name = "x"; field.value = "a".repeat({padding - 2}) + "{smuggled}";
                form.appendChild(field); document.body.appendChild(form); form.submit();""")
        assert wait_until(lambda: _reached(view, 1), 20.0), view.counts
        assert requests.calls == [], "nothing reached the robot: it never left HALT"
    finally:
        site.close()


#: Loads an image from arguments[0] and says "loaded WxH" or "failed".
LOAD_IMAGE = """
    const done = arguments[arguments.length - 1];
    const image = new Image();
    image.onload = () => done("loaded " + image.naturalWidth + "x" + image.naturalHeight);
    image.onerror = () => done("failed");
    image.src = arguments[0] + "?" + Date.now();"""


def test_another_sites_page_cannot_show_the_camera_picture(browser: Any) -> None:
    """Review finding 7: a page from another origin showed the robot's camera picture in the
    operator's browser (<img src=http://127.0.0.1:PORT/frame.jpg>: "loaded cross-origin:
    640x480"). Now the browser's request is refused (Sec-Fetch-Site: cross-site), and the answer
    would not be shown there anyway (Cross-Origin-Resource-Policy). The same image loads on the
    view's own page (the test's own check that it can load at all)."""
    view = View()
    site = Site("<!doctype html><title>cat pictures</title><p>nothing to see")
    try:
        frame = ViewFrame(np.full((120, 160, 3), 90, np.uint8), None, None, "none", "FOLLOW",
                          None)
        _wait_for_frame(view, {"state": "FOLLOW", "step": 7}, frame)
        picture = f"http://127.0.0.1:{view.port}/frame.jpg"
        browser.get(f"http://attacker.example:{site.port}/")
        refused = view.server.counts["refused"]
        assert browser.execute_async_script(LOAD_IMAGE, picture) == "failed"
        assert view.server.counts["refused"] == refused + 1, "the request reached the view"
        browser.get(f"http://127.0.0.1:{view.port}/")
        assert browser.execute_async_script(LOAD_IMAGE, picture) == "loaded 160x120"
        assert view.requests.calls == []
    finally:
        site.close()
        view.server.close()


@pytest.mark.parametrize("bind", ["127.0.0.1", "0.0.0.0"])
def test_a_dns_rebinding_page_is_refused(browser: Any, bind: str) -> None:
    """The attacker's page is loaded from rebind.example:PORT, then the name points at the robot
    (here: the view takes over the same address and port): the page's same-origin requests carry
    the header they want, but name the attacker's host."""
    port = free_port()
    site = Site("<!doctype html><title>rebind</title>", port)
    browser.get(f"http://rebind.example:{port}/")
    site.close()
    requests = Requests()
    view = LiveView(bind, port, requests, log=lambda line: None)
    view.publish({"state": "HALT", "step": 1, "started": True}, None)
    try:
        answers = browser.execute_async_script("""
            const done = arguments[arguments.length - 1];
            const post = (path) => fetch(path, {method: "POST", headers: {"X-Lanewarden": "1"}})
              .then((r) => r.status, (e) => "failed: " + e);
            Promise.all([post("/resume"), post("/start"), fetch("/status").then((r) => r.status)])
              .then(done);""")
        assert answers == [403, 403, 403]
        assert requests.calls == []
    finally:
        view.close()


def test_a_non_loopback_page_takes_the_token_from_the_address_once(browser: Any) -> None:
    from selenium.webdriver.common.by import By

    token = "T0k3n-" + "q" * 18
    requests = Requests()
    view = LiveView("0.0.0.0", 0, requests, log=lambda line: None, token=token)
    view.publish({"state": "FOLLOW", "step": 3, "started": True, "armed": False}, None)
    try:
        assert view.url.endswith(f":{view.port}/#token={token}")
        browser.get(f"http://127.0.0.1:{view.port}/#token={token}")
        assert wait_until(lambda: (js(browser, "return window.lanewarden.polls") or 0) > 0, 20.0)
        assert browser.current_url == f"http://127.0.0.1:{view.port}/", "token left the address"
        assert wait_until(lambda: browser.find_element(By.ID, "stop").is_enabled(), 10.0)
        browser.find_element(By.ID, "stop").click()
        assert wait_until(lambda: requests.calls == [("stop", "page")], 10.0), requests.calls
        # Another origin (localhost) has no token stored: the page asks for it.
        browser.get(f"http://localhost:{view.port}/")
        box = browser.find_element(By.ID, "tokenbox")
        assert wait_until(lambda: box.get_attribute("class") == "needed", 10.0)
        assert js(browser, "return window.lanewarden.polls") == 0
        browser.find_element(By.ID, "token").send_keys(token)
        browser.find_element(By.ID, "usetoken").click()
        assert wait_until(lambda: (js(browser, "return window.lanewarden.polls") or 0) > 0, 20.0)
        assert box.get_attribute("class") == ""
        # A page open without the token, then given the address with it (only the fragment
        # changes: no reload), takes it too.
        other = f"http://127.0.0.2:{view.port}/"
        browser.get(other)
        assert wait_until(lambda: browser.find_element(By.ID, "tokenbox").get_attribute("class")
                          == "needed", 10.0)
        browser.get(f"{other}#token={token}")
        assert wait_until(lambda: (js(browser, "return window.lanewarden.polls") or 0) > 0, 20.0)
        assert browser.current_url == other
        assert browser.find_element(By.ID, "tokenbox").get_attribute("class") == ""
    finally:
        view.close()
