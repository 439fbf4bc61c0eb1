"""The live view's server over real HTTP on loopback: the page is self-contained, the status and the
annotated frame are served, buttons reach the operator's requests, and requests from elsewhere
(another site's page, a rebound host name) are refused. The page in a real browser is in
test_live_page_browser.py."""

from __future__ import annotations

import http.client
import json
import re
import threading
from collections.abc import Iterator

import numpy as np
import pytest

from lanewarden.errors import UsageError
from lanewarden.live_view import LiveView, ViewFrame, annotate, parse_view_address


class Requests:
    def __init__(self) -> None:
        self.calls: list[tuple[str, str]] = []
        self.event = threading.Event()

    def start(self, source: str) -> None:
        self.calls.append(("start", source))
        self.event.set()

    def resume(self, source: str) -> None:
        self.calls.append(("resume", source))
        self.event.set()

    def stop(self, source: str) -> None:
        self.calls.append(("stop", source))
        self.event.set()


@pytest.fixture
def view() -> Iterator[tuple[LiveView, Requests]]:
    requests = Requests()
    server = LiveView("127.0.0.1", 0, requests)
    try:
        yield server, requests
    finally:
        server.close()


def fetch(view: LiveView, method: str, path: str,
          headers: dict[str, str] | None = None) -> tuple[int, bytes, str]:
    connection = http.client.HTTPConnection("127.0.0.1", view.port, timeout=10)
    try:
        connection.request(method, path, headers=headers or {})
        response = connection.getresponse()
        return response.status, response.read(), response.getheader("Content-Type") or ""
    finally:
        connection.close()


def test_view_address() -> None:
    assert parse_view_address("8080") == ("127.0.0.1", 8080)
    assert parse_view_address("0.0.0.0:8081") == ("0.0.0.0", 8081)
    assert parse_view_address("[::1]:9000") == ("::1", 9000)
    for bad in ("http", "host:", "70000", "a:b"):
        with pytest.raises(UsageError, match="--view"):
            parse_view_address(bad)


def test_the_page_is_self_contained(view: tuple[LiveView, Requests]) -> None:
    server, _ = view
    status, body, content_type = fetch(server, "GET", "/")
    assert status == 200 and content_type.startswith("text/html")
    page = body.decode()
    for needed in ('id="start"', 'id="stop"', 'id="resume"', 'id="frame"', "/status",
                   "X-Lanewarden"):
        assert needed in page
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", page), \
        "nothing may be fetched from elsewhere (offline, no CDN)"
    assert "<script src" not in page and "<link" not in page


def test_status_and_frame(view: tuple[LiveView, Requests]) -> None:
    server, _ = view
    status, body, _ = fetch(server, "GET", "/frame.jpg")
    assert status == 503, "no frame yet"
    image = np.full((120, 160, 3), 90, np.uint8)
    server.publish({"state": "FOLLOW", "step": 7, "halt_reason": None},
                   ViewFrame(image, None, None, "none", "FOLLOW", None))
    _, body, content_type = fetch(server, "GET", "/status")
    assert content_type == "application/json"
    assert json.loads(body)["state"] == "FOLLOW"
    for _ in range(200):  # the encoder runs on its own thread: wait for its first picture
        if json.loads(fetch(server, "GET", "/status")[1])["frame_seq"] > 0:
            break
        server.publish({"state": "FOLLOW", "step": 8},
                       ViewFrame(image, None, None, "none", "FOLLOW", None))
        threading.Event().wait(0.05)
    status, body, content_type = fetch(server, "GET", "/frame.jpg")
    assert status == 200 and content_type == "image/jpeg"
    assert body[:2] == b"\xff\xd8"


def test_buttons_reach_the_operator_requests(view: tuple[LiveView, Requests]) -> None:
    server, requests = view
    for action in ("stop", "start", "resume"):
        status, body, _ = fetch(server, "POST", f"/{action}", {"X-Lanewarden": "1"})
        assert status == 200 and json.loads(body) == {"ok": True, "request": action}
    assert requests.calls == [("stop", "page"), ("start", "page"), ("resume", "page")]
    assert fetch(server, "POST", "/launch", {"X-Lanewarden": "1"})[0] == 404


def test_requests_from_elsewhere_are_refused(view: tuple[LiveView, Requests]) -> None:
    server, requests = view
    assert fetch(server, "POST", "/start")[0] == 403, "a cross-site form post has no header"
    assert fetch(server, "GET", "/status", {"Host": "evil.example:80"})[0] == 403
    assert fetch(server, "POST", "/stop", {"Host": "evil.example", "X-Lanewarden": "1"})[0] == 403
    assert requests.calls == []


def test_annotated_frame_shows_the_state_band() -> None:
    image = np.zeros((240, 320), np.uint8)
    picture = annotate(ViewFrame(image, None, None, "none", "HALT", "LANE_LOST: gone"))
    assert picture.shape == (240, 320, 3)
    assert tuple(picture[-2, -2]) == (40, 40, 230), "HALT's colour along the bottom"
    wide = annotate(ViewFrame(np.zeros((720, 1280, 3), np.uint8), None, None, "none",
                              "FOLLOW", None))
    assert wide.shape == (360, 640, 3)
