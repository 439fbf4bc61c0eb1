"""The live view's server over real HTTP on loopback: the page is self-contained, the status and the
annotated frame (with its own step's status) are served, buttons reach the operator's requests,
and every attack of issue 18 is refused at socket level: request smuggling through a body, bad
`Content-Length`s, a foreign Host (DNS rebinding) or Origin, a missing or wrong token on a
non-loopback bind, slow and many connections, huge headers, a GET with a body, unknown methods.
For each: nothing reaches the operator's requests (the robot never leaves HALT), nothing is
printed but one line, and what the server reads stays within its budget. The page in a real
browser is in test_live_page_browser.py."""

from __future__ import annotations

import http.client
import json
import re
import socket
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from lanewarden.errors import UsageError
from lanewarden.live_view import (
    MAX_CONNECTIONS,
    MAX_CONNECTIONS_PER_CLIENT,
    MAX_REQUEST_BYTES,
    AccessRules,
    LiveView,
    ViewFrame,
    annotate,
    is_loopback,
    json_text,
    parse_view_address,
    split_host,
    url_name,
)
from tests.operator.runs import wait_until

SMUGGLED_RESUME = b"POST /resume HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nX-Lanewarden: 1\r\n" \
                  b"Content-Length: 0\r\n\r\n"


class Requests:
    """The operator's requests as the view calls them (the robot leaves HALT only through
    start or resume)."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, str]] = []

    def start(self, source: str) -> None:
        self.calls.append(("start", source))

    def resume(self, source: str) -> None:
        self.calls.append(("resume", source))

    def stop(self, source: str) -> None:
        self.calls.append(("stop", source))


class View:
    """A LiveView on loopback (or `host`) with its requests and the lines it printed."""

    def __init__(self, host: str = "127.0.0.1", **options: Any) -> None:
        self.requests = Requests()
        self.lines: list[str] = []
        self.server = LiveView(host, 0, self.requests, log=self.lines.append, **options)
        self.port = self.server.port

    def idle(self) -> bool:
        """Every connection the server accepted is closed again."""
        counts = self.server.counts
        return self.server.open_connections == 0 and counts["closed"] > 0


@pytest.fixture
def view() -> Iterator[View]:
    v = View()
    try:
        yield v
    finally:
        v.server.close()


def fetch(port: int, method: str, path: str, headers: dict[str, str] | None = None,
          host: str = "127.0.0.1") -> tuple[int, bytes, http.client.HTTPResponse]:
    connection = http.client.HTTPConnection(host, port, timeout=10)
    try:
        connection.request(method, path, headers=headers or {})
        response = connection.getresponse()
        return response.status, response.read(), response
    finally:
        connection.close()


def exchange(port: int, data: bytes, *, host: str = "127.0.0.1") -> bytes:
    """Send raw bytes, then read everything the server sends until it closes the connection."""
    with socket.create_connection((host, port), timeout=10) as s:
        s.sendall(data)
        received = b""
        while chunk := s.recv(65536):
            received += chunk
    return received


def statuses(received: bytes) -> list[int]:
    """The status codes of every HTTP response in `received`, in order."""
    return [int(code) for code in re.findall(rb"HTTP/1\.[01] (\d{3}) ", received)]


def post(path: str, port: int, body: bytes = b"", extra: bytes = b"") -> bytes:
    return (f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Lanewarden: 1\r\n"
            f"Content-Length: {len(body)}\r\n").encode() + extra + b"\r\n" + body


# ---- addresses and rules (pure) -----------------------------------------------------------------
def test_view_address() -> None:
    assert parse_view_address("8080") == ("127.0.0.1", 8080)
    assert parse_view_address("0.0.0.0:8081") == ("0.0.0.0", 8081)
    assert parse_view_address("[::1]:9000") == ("::1", 9000)
    for bad in ("http", "host:", "70000", "a:b"):
        with pytest.raises(UsageError, match="--view"):
            parse_view_address(bad)


def test_host_names_and_loopback() -> None:
    assert split_host("127.0.0.1:8080") == ("127.0.0.1", 8080)
    assert split_host("LocalHost:8080") == ("localhost", 8080)
    assert split_host("[::1]:9000") == ("[::1]", 9000)
    assert split_host("[::1]") == ("[::1]", 80)
    assert split_host("robot") == ("robot", 80)
    assert split_host("robot:80x") == ("robot", None)
    assert split_host("robot:999999") == ("robot", None)
    assert url_name("::1") == "[::1]"
    assert url_name("::ffff:192.168.1.5") == "192.168.1.5"
    assert url_name("Robot.Lab") == "robot.lab"
    assert [is_loopback(h) for h in ("127.0.0.1", "127.0.0.2", "::1", "localhost",
                                     "0.0.0.0", "::", "192.168.1.5", "robot")] == [
        True, True, True, True, False, False, False, False]


def test_access_rules_for_a_loopback_bind() -> None:
    rules = AccessRules.for_bind("127.0.0.1", 8080)
    assert rules.token is None, "a loopback bind needs no token"
    ok = [["127.0.0.1:8080"], ["localhost:8080"], ["[::1]:8080"], ["LOCALHOST:8080"]]
    assert [rules.host_problem(h, "127.0.0.1") for h in ok] == [None] * 4
    for bad in (["evil.example:8080"], ["127.0.0.1:8081"], ["127.0.0.1"], [],
                ["127.0.0.1:8080", "evil.example:8080"], [socket.gethostname() + ":8080"]):
        assert rules.host_problem(bad, "127.0.0.1") is not None, bad
    same = "127.0.0.1:8080"
    assert rules.origin_problem("http://127.0.0.1:8080", "same-origin", same, True) is None
    assert rules.origin_problem(None, None, same, True) is None, "curl: no Origin, the header"
    assert rules.origin_problem(None, None, same, False) == "missing X-Lanewarden header"
    for origin, site in (("http://evil.example", "cross-site"), ("null", None),
                         ("http://127.0.0.1:9999", "same-site"), (None, "cross-site"),
                         ("http://localhost:8080", None), ("https://127.0.0.1:8080", None)):
        assert rules.origin_problem(origin, site, same, True) is not None, (origin, site)
    # a GET: the page's own, an address typed (none) or no browser (no header); not another
    # site's page
    for site in ("same-origin", "none", "None ", None):
        assert rules.fetch_site_problem(site, state_changing=False) is None, site
    for site in ("cross-site", "same-site", "CROSS-SITE", "sameorigin", ""):
        assert rules.fetch_site_problem(site, state_changing=False) == (
            f"a {site!r} request (Sec-Fetch-Site)"), site
    assert rules.origin_problem(None, "none", same, True) == "a 'none' request (Sec-Fetch-Site)"


def test_access_rules_for_any_other_bind_need_the_token() -> None:
    rules = AccessRules.for_bind("0.0.0.0", 8080, token="s3cret-token")
    assert rules.token == "s3cret-token"
    assert rules.token_problem("s3cret-token") is None
    assert rules.token_problem(" s3cret-token ") is None
    assert [rules.token_problem(t) for t in (None, "", "s3cret", "s3cret-token2", "é")] == [
        "no token", "wrong token", "wrong token", "wrong token", "wrong token"]
    assert rules.host_problem(["192.168.1.5:8080"], "192.168.1.5") is None, "its own address"
    assert rules.host_problem(["192.168.1.6:8080"], "192.168.1.5") is not None
    assert rules.host_problem([f"{socket.gethostname()}:8080"], "192.168.1.5") is None
    assert rules.host_problem(["evil.example:8080"], "192.168.1.5") is not None
    named = AccessRules.for_bind("robot.lab", 8080)
    assert named.token is not None and len(named.token) >= 20, "a fresh random token"
    assert named.token != AccessRules.for_bind("robot.lab", 8080).token
    assert named.host_problem(["robot.lab:8080"], "10.0.0.2") is None, "the name it was bound to"


# ---- what the page gets -------------------------------------------------------------------------
def test_the_page_is_self_contained(view: View) -> None:
    status, body, response = fetch(view.port, "GET", "/")
    assert status == 200 and response.getheader("Content-Type", "").startswith("text/html")
    page = body.decode()
    for needed in ('id="start"', 'id="stop"', 'id="resume"', 'id="frame"', 'id="plot"',
                   "/status", "X-Lanewarden", "X-Lanewarden-Token", "X-Lanewarden-Status"):
        assert needed in page
    assert not re.search(r"""(src|href|action)\s*=\s*["']?(https?:)?//""", page), \
        "nothing may be fetched from elsewhere (offline, no CDN)"
    assert "<script src" not in page and "<link" not in page
    assert response.getheader("Connection") == "close"
    assert "frame-ancestors 'none'" in response.getheader("Content-Security-Policy", "")
    assert response.getheader("X-Frame-Options") == "DENY", "no clickjacking of the buttons"
    assert response.getheader("Referrer-Policy") == "no-referrer"
    assert response.getheader("Cross-Origin-Resource-Policy") == "same-origin"


def _wait_for_frame(view: View, status: dict[str, Any], frame: ViewFrame) -> None:
    def encoded() -> bool:
        view.server.publish(status, frame)
        return json.loads(fetch(view.port, "GET", "/status")[1])["frame_seq"] > 0

    assert wait_until(encoded, 20.0, poll_s=0.05), "the encoder never encoded a frame"


def test_the_frame_carries_the_status_of_its_own_step(view: View) -> None:
    """Overlay and panel from one step: /frame.jpg's header holds the status the frame was
    published with, even after later steps (without a new frame) changed the newest status."""
    assert fetch(view.port, "GET", "/frame.jpg")[0] == 503, "no frame yet"
    image = np.full((120, 160, 3), 90, np.uint8)
    frame = ViewFrame(image, None, None, "none", "FOLLOW", None)
    _wait_for_frame(view, {"state": "FOLLOW", "step": 7, "confidence": 1.0}, frame)
    view.server.publish({"state": "HALT", "step": 8, "confidence": 0.0}, None)
    view.server.publish({"state": "HALT", "step": 9, "confidence": 0.0,
                         "halt_reason": "LANE_LOST: gone"}, None)
    status, body, response = fetch(view.port, "GET", "/frame.jpg")
    assert status == 200 and response.getheader("Content-Type") == "image/jpeg"
    assert body[:2] == b"\xff\xd8"
    assert json.loads(response.getheader("X-Lanewarden-Status", "")) == {
        "state": "FOLLOW", "step": 7, "confidence": 1.0}
    newest = json.loads(fetch(view.port, "GET", "/status")[1])
    assert (newest["step"], newest["state"], newest["confidence"]) == (9, "HALT", 0.0)


def test_every_frame_served_carries_its_own_steps_status(view: View) -> None:
    """A run publishes a status every step and a frame every third: whatever the encoder and the
    page catch, the picture served (its grey level says its step) and the status beside it are
    of the same step, never the newest step's status with an older picture."""
    fetch(view.port, "GET", "/status")  # a page is watching: the encoder works
    done = threading.Event()

    def run() -> None:
        step = 0
        while not done.is_set():
            step += 1
            frame = None
            if step % 3 == 0:
                image = np.full((48, 64), (step // 3) % 40 * 6, np.uint8)
                frame = ViewFrame(image, None, None, "none", "FOLLOW", None)
            view.server.publish({"state": "FOLLOW", "step": step}, frame)
            done.wait(0.0005)

    publisher = threading.Thread(target=run, daemon=True)
    publisher.start()
    served: dict[int, int] = {}

    def collect() -> bool:
        status, body, response = fetch(view.port, "GET", "/frame.jpg")
        if status == 200:
            import cv2

            grey = int(cv2.imdecode(np.frombuffer(body, np.uint8), cv2.IMREAD_GRAYSCALE)[10, 10])
            served[json.loads(response.getheader("X-Lanewarden-Status", ""))["step"]] = grey
        return len(served) >= 8

    try:
        assert wait_until(collect, 30.0, poll_s=0.01), served
    finally:
        done.set()
        publisher.join(5)
    for step, grey in served.items():
        assert step % 3 == 0, f"a frame served with the status of step {step} (no frame)"
        assert abs(grey - (step // 3) % 40 * 6) <= 2, f"step {step}'s status, grey {grey}"


def test_the_plot_gets_the_new_samples_of_the_last_ten_seconds() -> None:
    v = View(plot={"turn_enter_slope_sum": 6.0, "turn_exit_slope_sum": 4.0})
    try:
        for step in range(1, 41):  # steps 0.5 s apart: 20 s of run time
            v.server.publish({"step": step, "time_s": step * 0.5, "slope_sum": step * 0.1,
                              "filtered_slope_sum": step * 0.05, "confidence": 0.5}, None)
        plot = json.loads(fetch(v.port, "GET", "/status")[1])["plot"]
        assert (plot["turn_enter_slope_sum"], plot["turn_exit_slope_sum"], plot["window_s"]) == (
            6.0, 4.0, 10.0)
        assert [s[0] for s in plot["samples"]] == list(range(20, 41)), "10 s back from 20 s"
        assert plot["samples"][-1] == [40, 20.0, 4.0, 2.0, 0.5]
        newer = json.loads(fetch(v.port, "GET", "/status?since=38")[1])["plot"]["samples"]
        assert [s[0] for s in newer] == [39, 40]
        assert json.loads(fetch(v.port, "GET", "/status?since=x")[1])["plot"]["samples"]
    finally:
        v.server.close()


def test_a_non_finite_number_reaches_the_page_as_null() -> None:
    assert json.loads(json_text({"a": float("nan"), "b": [float("inf"), 1.0]})) == {
        "a": None, "b": [None, 1.0]}


def test_buttons_reach_the_operator_requests(view: View) -> None:
    for action in ("stop", "start", "resume"):
        status, body, response = fetch(view.port, "POST", f"/{action}", {"X-Lanewarden": "1"})
        assert status == 200 and json.loads(body) == {"ok": True, "request": action}
        assert response.getheader("Connection") == "close"
    origin = {"X-Lanewarden": "1", "Origin": f"http://127.0.0.1:{view.port}",
              "Sec-Fetch-Site": "same-origin"}
    assert fetch(view.port, "POST", "/stop", origin)[0] == 200, "the page's own request"
    assert fetch(view.port, "POST", "/launch", {"X-Lanewarden": "1"})[0] == 404
    assert view.requests.calls == [("stop", "page"), ("start", "page"), ("resume", "page"),
                                   ("stop", "page")]
    assert view.lines == []


# ---- the attacks --------------------------------------------------------------------------------
def test_a_body_is_never_served_as_a_second_request(view: View) -> None:
    """Issue 18's smuggling: a cross-site POST /stop whose body is 4096 bytes of padding and then
    a complete POST /resume with the header. Also a body within the limit followed by a second
    request, and a second request right after a bodiless one: one response, then the server
    closes; the second request is never served."""
    smuggled = SMUGGLED_RESUME % view.port
    attack = (f"POST /stop HTTP/1.1\r\nHost: 127.0.0.1:{view.port}\r\n"
              f"Content-Type: text/plain\r\nContent-Length: {4096 + len(smuggled)}\r\n"
              "Origin: http://evil.example\r\n\r\n").encode() + b"a" * 4096 + smuggled
    assert statuses(exchange(view.port, attack)) == [413]
    small = b"a" * 64 + smuggled
    within = (f"POST /stop HTTP/1.1\r\nHost: 127.0.0.1:{view.port}\r\n"
              f"Content-Length: {len(small)}\r\nOrigin: http://evil.example\r\n\r\n").encode()
    assert statuses(exchange(view.port, within + small)) == [403], "the body was only a body"
    assert view.requests.calls == []
    received = exchange(view.port, post("/stop", view.port, b"0123456789") + smuggled)
    assert statuses(received) == [200] and b"Connection: close" in received
    received = exchange(view.port, post("/stop", view.port) + smuggled + smuggled)
    assert statuses(received) == [200]
    assert view.requests.calls == [("stop", "page"), ("stop", "page")], "never a resume"


@pytest.mark.parametrize(("length", "expected"), [
    ("-1", 400), ("abc", 400), ("+5", 400), ("1e3", 400), ("5 5", 400), ("0x10", 400),
    ("99999999999", 400), ("2000", 413), (None, 411),
])
def test_a_bad_content_length_is_refused_before_reading(view: View, length: str | None,
                                                        expected: int) -> None:
    """Refused at once, whatever follows: the client keeps sending and never closes, and the
    server still answers (the old server read a body of -1 until the client closed)."""
    head = f"POST /resume HTTP/1.1\r\nHost: 127.0.0.1:{view.port}\r\nX-Lanewarden: 1\r\n"
    if length is not None:
        head += f"Content-Length: {length}\r\n"
    with socket.create_connection(("127.0.0.1", view.port), timeout=10) as s:
        s.sendall(head.encode() + b"\r\n" + b"x" * 2000)
        answer = s.recv(4096)  # the client has not closed: the server must answer anyway
    assert statuses(answer) == [expected]
    assert view.requests.calls == []
    assert wait_until(view.idle, 10.0)
    assert view.server.counts["largest_request"] <= MAX_REQUEST_BYTES


def test_a_flood_after_a_negative_length_is_cut_off_within_the_budget(view: View) -> None:
    """`Content-Length: -1` and then megabytes: the server answers 400, closes, and has read no
    more than its budget (memory bounded); the client's sending fails, not the server."""
    head = (f"POST /resume HTTP/1.1\r\nHost: 127.0.0.1:{view.port}\r\nX-Lanewarden: 1\r\n"
            "Content-Length: -1\r\n\r\n").encode()
    with socket.create_connection(("127.0.0.1", view.port), timeout=10) as s:
        s.sendall(head)
        try:
            for _ in range(64):
                s.sendall(b"x" * 65536)  # 4 MiB unless the server has closed
        except OSError:
            pass  # the server closed the connection: expected
        try:
            answer = s.recv(4096)
        except OSError:
            answer = b""
    assert statuses(answer) in ([400], []), answer[:200]
    assert wait_until(view.idle, 10.0)
    assert view.server.counts["largest_request"] <= MAX_REQUEST_BYTES
    assert view.requests.calls == []


@pytest.mark.parametrize("framing", [
    "Transfer-Encoding: chunked\r\n", "Content-Length: 0\r\nContent-Length: 0\r\n",
    "Content-Length: 0\r\nTransfer-Encoding: chunked\r\n",
])
def test_chunked_or_repeated_lengths_are_refused(view: View, framing: str) -> None:
    data = (f"POST /resume HTTP/1.1\r\nHost: 127.0.0.1:{view.port}\r\nX-Lanewarden: 1\r\n"
            f"{framing}\r\n0\r\n\r\n").encode() + SMUGGLED_RESUME % view.port
    assert statuses(exchange(view.port, data)) == [400]
    assert view.requests.calls == []


def test_a_foreign_host_or_origin_is_refused(view: View) -> None:
    """DNS rebinding (Host: evil.example), another port, no Host, two Hosts, a foreign Origin,
    a cross-site fetch, no header: refused, GET and POST."""
    port = view.port
    assert fetch(port, "GET", "/status", {"Host": "evil.example"})[0] == 403
    assert fetch(port, "GET", "/", {"Host": f"evil.example:{port}"})[0] == 403
    assert fetch(port, "GET", "/frame.jpg", {"Host": f"127.0.0.1:{port + 1}"})[0] == 403
    assert fetch(port, "POST", "/resume", {"Host": f"evil.example:{port}",
                                           "X-Lanewarden": "1"})[0] == 403
    for headers in ({"Origin": "http://evil.example"}, {"Origin": "null"},
                    {"Sec-Fetch-Site": "cross-site"}, {"Sec-Fetch-Site": "same-site"},
                    {"Origin": f"http://localhost:{port}"}):
        assert fetch(port, "POST", "/resume", {"X-Lanewarden": "1", **headers})[0] == 403
    assert fetch(port, "POST", "/resume")[0] == 403, "a cross-site form post has no header"
    no_host = b"POST /resume HTTP/1.0\r\nX-Lanewarden: 1\r\nContent-Length: 0\r\n\r\n"
    assert statuses(exchange(port, no_host)) == [403]
    two_hosts = (f"POST /resume HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nHost: evil.example\r\n"
                 "X-Lanewarden: 1\r\nContent-Length: 0\r\n\r\n").encode()
    assert statuses(exchange(port, two_hosts)) == [403]
    assert view.requests.calls == []
    assert fetch(port, "GET", "/status", {"Host": f"localhost:{port}"})[0] == 200


def _get(port: int, path: str, fetch_site: str | None) -> bytes:
    """A raw GET as a browser sends it (`fetch_site`: its Sec-Fetch-Site; None: curl's, none)."""
    site = "" if fetch_site is None else f"Sec-Fetch-Site: {fetch_site}\r\n"
    return exchange(port, f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n{site}\r\n"
                    .encode())


def test_another_sites_page_cannot_get_the_picture(view: View) -> None:
    """Review finding 7: any web page could show the robot's camera picture in the operator's
    browser (<img src=http://127.0.0.1:PORT/frame.jpg>), tell a run was live on that port, and
    keep the encoder busy by polling. A GET another site's page makes (its browser says
    cross-site, or same-site for another port of this machine) is refused like a POST; the
    page's own, an address typed (none) and a client that is no browser are served. Every
    answer says Cross-Origin-Resource-Policy: same-origin (a browser without Sec-Fetch-Site
    then still shows no other site the picture)."""
    frame = ViewFrame(np.full((120, 160, 3), 90, np.uint8), None, None, "none", "FOLLOW", None)
    _wait_for_frame(view, {"state": "FOLLOW", "step": 7}, frame)
    refused = view.server.counts["refused"]
    for site in ("cross-site", "same-site", "Cross-Site", "bogus"):
        for path in ("/frame.jpg", "/status", "/"):
            answer = _get(view.port, path, site)
            assert statuses(answer) == [403], (site, path, answer[:200])
            assert answer.endswith(f"a {site!r} request (Sec-Fetch-Site)\n".encode()), answer
            assert b"\xff\xd8" not in answer and b'"step"' not in answer
    assert view.server.counts["refused"] == refused + 12
    for site in ("same-origin", "none", None):
        answer = _get(view.port, "/frame.jpg", site)
        assert statuses(answer) == [200] and b"\r\n\r\n\xff\xd8" in answer, site
    answers = [_get(view.port, "/frame.jpg", None), _get(view.port, "/frame.jpg", "cross-site"),
               _get(view.port, "/nowhere", None),
               exchange(view.port, f"PUT / HTTP/1.1\r\nHost: 127.0.0.1:{view.port}\r\n\r\n"
                        .encode())]
    assert [statuses(a) for a in answers] == [[200], [403], [404], [501]]
    for answer in answers:
        assert b"\r\nCross-Origin-Resource-Policy: same-origin\r\n" in answer
    assert view.requests.calls == []


def test_refused_requests_are_reported_in_one_line_now_and_then(view: View) -> None:
    for _ in range(3):
        fetch(view.port, "POST", "/resume", {"Host": f"evil.example:{view.port}",
                                             "X-Lanewarden": "1"})
    assert view.server.counts["refused"] == 3
    assert view.lines == [f"live view: refused POST /resume from 127.0.0.1: unexpected Host "
                          f"header 'evil.example:{view.port}'"], "the next two: counted, later"
    # a burst that ends is still counted on the terminal: at the latest when the page closes
    # (the count had only come with a refusal 5 s later, so a burst's tail went unsaid)
    view.server.close()
    assert view.lines[1:] == ["live view: 2 more requests refused after the last one reported"]


def test_a_refusal_prints_no_escape_sequence(view: View) -> None:
    """What a client sends is never written raw to the operator's terminal."""
    data = (f"POST /resume\x1b[2J\x1b]0;pwned\x07 HTTP/1.1\r\nHost: 127.0.0.1:{view.port}\r\n"
            "Origin: http://e\x1b[31mvil\r\nX-Lanewarden: 1\r\nContent-Length: 0\r\n\r\n")
    assert statuses(exchange(view.port, data.encode("latin-1"))) == [403]
    assert view.lines == ["live view: refused POST /resume?[2J?]0;pwned? from 127.0.0.1: "
                          "unexpected Origin 'http://e\\x1b[31mvil'"]
    assert view.requests.calls == []


def test_a_non_loopback_bind_needs_the_token() -> None:
    v = View("0.0.0.0", token="tok-" + "x" * 20)
    try:
        port, token = v.port, "tok-" + "x" * 20
        assert v.server.url.endswith(f":{port}/#token={token}")
        assert fetch(port, "GET", "/")[0] == 200, "the page itself: it asks for the token"
        for method, path in (("GET", "/status"), ("GET", "/frame.jpg"), ("POST", "/resume"),
                             ("POST", "/start")):
            for given in ({}, {"X-Lanewarden-Token": "wrong"},
                          {"X-Lanewarden-Token": token[:-1]}):
                assert fetch(port, method, path, {"X-Lanewarden": "1", **given})[0] == 401
        with_token = {"X-Lanewarden": "1", "X-Lanewarden-Token": token}
        rebound = {**with_token, "Host": f"evil.example:{port}"}
        assert fetch(port, "POST", "/resume", rebound)[0] == 403, "DNS rebinding with the token"
        assert v.requests.calls == []
        assert fetch(port, "GET", "/status", with_token)[0] == 200
        assert fetch(port, "POST", "/stop", with_token)[0] == 200
        # Another address of this machine (all of 127/8 reaches a 0.0.0.0 bind): its own name.
        other = {**with_token, "Host": f"127.0.0.2:{port}"}
        assert fetch(port, "POST", "/resume", other, host="127.0.0.2")[0] == 200
        assert fetch(port, "POST", "/resume", other, host="127.0.0.1")[0] == 403
        assert v.requests.calls == [("stop", "page"), ("resume", "page")]
    finally:
        v.server.close()


def test_a_loopback_url_has_no_token(view: View) -> None:
    assert view.server.url == f"http://127.0.0.1:{view.port}/"
    assert view.server.token is None


def test_a_slow_client_is_cut_off_at_its_deadline() -> None:
    """Slowloris: a client sending its headers a byte at a time (each byte well within any
    per-read timeout) is closed at the connection's deadline, before its request is complete."""
    v = View(connection_deadline_s=0.5)
    request = (f"GET /status HTTP/1.1\r\nHost: 127.0.0.1:{v.port}\r\n"
               + "".join(f"X-Pad-{i}: {'y' * 20}\r\n" for i in range(12)) + "\r\n").encode()
    sent = {"bytes": 0}
    pause = threading.Event()
    try:
        with socket.create_connection(("127.0.0.1", v.port), timeout=30) as s:
            def dribble() -> None:
                for byte in request:  # about 400 bytes, 0.05 s apart: 20 s unless cut off
                    try:
                        s.sendall(bytes([byte]))
                    except OSError:  # closed by the server
                        return
                    sent["bytes"] += 1
                    pause.wait(0.05)

            sender = threading.Thread(target=dribble, daemon=True)
            sender.start()
            answer = s.recv(4096)  # blocks until the server answers or closes
            sent_when_closed = sent["bytes"]
            pause.set()  # the rest goes at once (the sender must end)
            sender.join(10)
        assert answer == b"", "closed without an answer"
        assert sent_when_closed < len(request), "cut off before the request was complete"
        assert wait_until(v.idle, 10.0)
        assert v.requests.calls == [] and v.lines == []
    finally:
        v.server.close()


def _from(address: str, port: int) -> socket.socket:
    """A connection to the view on 127.0.0.1 from another loopback address (another client)."""
    return socket.create_connection(("127.0.0.1", port), timeout=10,
                                    source_address=(address, 0))


def test_many_connections_are_bounded_and_idle_ones_give_way() -> None:
    """Three times MAX_CONNECTIONS idle connections from six client addresses (each within
    MAX_CONNECTIONS_PER_CLIENT): at most MAX_CONNECTIONS are served at once (one thread each);
    every slot taken, each new one takes the slot of the oldest whose request has not come
    through, so the operator's Stop still gets through (many hosts' idle connections had kept it
    out, an attacker's review); the control side's publish never waits."""
    # none is cut off by a deadline meanwhile
    v = View(connection_deadline_s=60.0, header_deadline_s=60.0)
    before = threading.active_count()
    idle = []
    try:
        for k in range(3 * MAX_CONNECTIONS):
            idle.append(_from(f"127.0.0.{2 + k // MAX_CONNECTIONS_PER_CLIENT}", v.port))
        counts = v.server.counts
        assert wait_until(lambda: counts["evicted"] >= 2 * MAX_CONNECTIONS, 20.0), counts
        assert counts["peak_open"] == MAX_CONNECTIONS
        assert counts["evicted"] == 2 * MAX_CONNECTIONS and counts["busy"] == 0
        assert threading.active_count() <= before + MAX_CONNECTIONS
        # said on the terminal, once for the burst (the rest within REFUSAL_REPORT_EVERY_S)
        assert len(v.lines) == 1, v.lines
        assert v.lines[0].startswith(f"live view: all {MAX_CONNECTIONS} connections busy: closed "
                                     "the oldest whose request had not come through, from "
                                     "127.0.0.2:"), v.lines
        assert " for one from 127.0.0.4:" in v.lines[0]
        v.server.publish({"state": "HALT", "step": 1}, None)
        assert exchange(v.port, post("/stop", v.port)).startswith(b"HTTP/1.1 200 ")
        assert v.requests.calls == [("stop", "page")]
        assert counts["peak_open"] == MAX_CONNECTIONS
    finally:
        for s in idle:
            s.close()
    try:
        assert wait_until(lambda: v.server.open_connections == 0, 20.0)
        assert fetch(v.port, "GET", "/status")[0] == 200
    finally:
        v.server.close()


def test_one_client_cannot_take_every_connection() -> None:
    """An attacker's review: idle connections from one host, no token needed, took every slot,
    and the operator's Stop got 'not connected' for as long as it went on. One client address
    holds at most MAX_CONNECTIONS_PER_CLIENT; the others' requests are served meanwhile."""
    v = View(connection_deadline_s=60.0, header_deadline_s=60.0)
    idle = []
    try:
        for _ in range(3 * MAX_CONNECTIONS_PER_CLIENT):
            idle.append(_from("127.0.0.2", v.port))
        counts = v.server.counts
        assert wait_until(lambda: counts["busy"] + counts["peak_open"]
                          >= 3 * MAX_CONNECTIONS_PER_CLIENT, 20.0), counts
        assert counts["peak_open"] == MAX_CONNECTIONS_PER_CLIENT
        assert counts["busy"] == 2 * MAX_CONNECTIONS_PER_CLIENT
        assert v.lines[0].startswith(f"live view: {MAX_CONNECTIONS_PER_CLIENT} connections from "
                                     "one client open, one from 127.0.0.2:"), v.lines
        # the operator, from another address, is served while they are held
        assert exchange(v.port, post("/stop", v.port)).startswith(b"HTTP/1.1 200 ")
        assert v.requests.calls == [("stop", "page")]
    finally:
        for s in idle:
            s.close()
        v.server.close()


def test_an_idle_connection_holds_its_slot_only_until_the_header_deadline() -> None:
    """A connection that sends nothing is closed at `header_deadline_s` (1 s by default), long
    before the connection's own deadline (60 s here: the recv below would wait that long)."""
    v = View(connection_deadline_s=60.0, header_deadline_s=0.3)
    try:
        with socket.create_connection(("127.0.0.1", v.port), timeout=10) as s:
            assert s.recv(4096) == b"", "closed without an answer"
        assert wait_until(v.idle, 10.0)
        assert exchange(v.port, post("/stop", v.port)).startswith(b"HTTP/1.1 200 ")
        assert v.requests.calls == [("stop", "page")]
    finally:
        v.server.close()


def test_a_websocket_or_another_origin_gets_no_picture(view: View) -> None:
    """An attacker's review: a browser's WebSocket handshake carries Origin but no
    Sec-Fetch-Site, so another site's page opening ws://127.0.0.1:PORT/frame.jpg had been
    served, and kept the picture encoder busy. A GET with another Origin, or an Upgrade, is
    refused; the page's own Origin is served."""
    base = f"GET /frame.jpg HTTP/1.1\r\nHost: 127.0.0.1:{view.port}\r\n"
    websocket = (base + "Origin: http://localhost:9000\r\nUpgrade: websocket\r\n"
                 "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                 "Sec-WebSocket-Version: 13\r\n\r\n")
    answers = {
        "websocket": exchange(view.port, websocket.encode()),
        "own upgrade": exchange(view.port, (base + f"Origin: http://127.0.0.1:{view.port}\r\n"
                                            "Upgrade: websocket\r\n\r\n").encode()),
        "other origin": exchange(view.port, (base + "Origin: http://evil.example\r\n\r\n")
                                 .encode()),
        "null origin": exchange(view.port, (base + "Origin: null\r\n\r\n").encode()),
        "own origin": exchange(view.port, (base + f"Origin: http://127.0.0.1:{view.port}\r\n"
                                           "\r\n").encode()),
    }
    assert {k: statuses(a) for k, a in answers.items()} == {
        "websocket": [403], "own upgrade": [403], "other origin": [403], "null origin": [403],
        "own origin": [503]}  # (served: no frame published yet)
    assert answers["websocket"].endswith(b"an Upgrade to 'websocket' (only plain HTTP is "
                                         b"served)\n")
    assert answers["other origin"].endswith(b"unexpected Origin 'http://evil.example'\n")


def test_the_browsers_icon_request_is_answered_without_a_token_or_a_line() -> None:
    """On a non-loopback bind every page load asked /favicon.ico without the token, and the
    refusal it printed could be the line shown while a real refusal was only counted."""
    v = View(host="0.0.0.0")
    try:
        answer = exchange(v.port, f"GET /favicon.ico HTTP/1.1\r\nHost: 127.0.0.1:{v.port}\r\n"
                          "\r\n".encode())
        assert statuses(answer) == [404]
        assert v.server.counts["refused"] == 0 and v.lines == []
        status = exchange(v.port, f"GET /status HTTP/1.1\r\nHost: 127.0.0.1:{v.port}\r\n\r\n"
                          .encode())
        assert statuses(status) == [401]  # (everything else still needs the token)
    finally:
        v.server.close()


def test_closing_waits_for_a_watching_page_to_get_the_end_reason() -> None:
    """An attacker's review: the run published its last status (why it ended) and closed the view
    at once, so the page, polling every 150 ms, kept showing FOLLOW at 0.20 m/s. Closing now
    waits until a page that was watching has fetched that status (at most final_status_wait_s;
    here long, so the test never depends on timing); with no page watching, it does not wait."""
    v = View(final_status_wait_s=60.0)
    v.server.publish({"state": "FOLLOW", "step": 5}, None)
    assert fetch(v.port, "GET", "/status")[0] == 200  # a page is watching
    v.server.publish({"state": "FOLLOW", "step": 6, "end_reason": "stopped by Ctrl-C"}, None)
    closer = threading.Thread(target=v.server.close)
    closer.start()
    status, body, _ = fetch(v.port, "GET", "/status")  # the page's next poll: still served
    closer.join(30)
    assert not closer.is_alive()
    assert status == 200 and json.loads(body)["end_reason"] == "stopped by Ctrl-C"
    unwatched = View(final_status_wait_s=3600.0)
    unwatched.server.publish({"state": "HALT", "step": 1, "end_reason": "done"}, None)
    unwatched.server.close()  # no page has asked: returns at once (a wait would hang the test)


def test_huge_headers_are_refused_within_the_budget(view: View) -> None:
    many = (f"POST /resume HTTP/1.1\r\nHost: 127.0.0.1:{view.port}\r\nX-Lanewarden: 1\r\n"
            + "".join(f"X-Big-{i}: {'z' * 1000}\r\n" for i in range(200))
            + "Content-Length: 0\r\n\r\n").encode()
    long_line = b"GET /" + b"a" * 20000 + b" HTTP/1.1\r\n\r\n"
    for data in (many, long_line):
        with socket.create_connection(("127.0.0.1", view.port), timeout=10) as s:
            try:
                s.sendall(data)
            except OSError:
                pass  # the server may close while we still send
            try:
                answer = s.recv(4096)
            except OSError:
                answer = b""
        assert statuses(answer) in ([431], []), answer[:200]
    assert wait_until(view.idle, 10.0)
    assert view.server.counts["largest_request"] <= MAX_REQUEST_BYTES
    assert view.requests.calls == []


def test_a_get_with_a_body_and_unknown_methods_are_refused(view: View) -> None:
    port = view.port
    get_body = (f"GET /status HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Length: "
                f"{len(SMUGGLED_RESUME % port)}\r\n\r\n").encode() + SMUGGLED_RESUME % port
    assert statuses(exchange(port, get_body)) == [400]
    for method in ("PUT", "DELETE", "PATCH", "OPTIONS", "TRACE", "CONNECT", "HEAD", "RESUME"):
        data = (f"{method} /resume HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Lanewarden: 1\r\n"
                "Content-Length: 0\r\n\r\n").encode()
        assert statuses(exchange(port, data)) == [501], method
    assert statuses(exchange(port, b"POST /resume HTTP/2.0\r\nContent-Length: 0\r\n\r\n")) == [505]
    assert statuses(exchange(port, b"GET / HTTP/1.1\r\nHost\r\n\r\n")) == [403], "no Host"
    assert statuses(exchange(port, b"POST /resume\r\n\r\n")) == [400], "HTTP/0.9"
    assert statuses(exchange(port, b"GET /status\r\n\r\n")) == [505], "HTTP/0.9"
    assert exchange(port, b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03" + bytes(range(256)))
    assert view.requests.calls == []


def test_bad_clients_print_no_traceback(view: View, capfd: pytest.CaptureFixture[str]) -> None:
    """Clients that hang up mid-header or mid-body, reset, send garbage or nothing: no traceback,
    no line on the terminal, and the next good request is served."""
    port = view.port
    partial = [b"GET /sta", f"POST /stop HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n".encode(),
               post("/stop", port, b"x" * 50)[:-50] + b"short", b"",
               b"\x00\xff" * 100 + b"\r\n\r\n", b"GET / HTTP/1.1\r\nHost: 127.0.0.1"]
    for data in partial:
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(data)
    for data in partial[:3]:  # the same, then a reset (RST) instead of a close
        s = socket.create_connection(("127.0.0.1", port), timeout=10)
        s.sendall(data)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        s.close()
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:  # leaves unread
        s.sendall(f"GET /status HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
    assert wait_until(lambda: view.server.open_connections == 0
                      and view.server.counts["closed"] >= len(partial) + 4, 20.0)
    assert fetch(port, "GET", "/status")[0] == 200
    out, err = capfd.readouterr()
    assert "Traceback" not in out + err and err == "", err
    assert view.requests.calls == [] and view.lines == []


def test_an_error_of_our_own_is_one_line(capfd: pytest.CaptureFixture[str]) -> None:
    """A bug on our side while serving (here: the operator's requests raising) is said in one
    line naming the error and where; no traceback; the server goes on."""
    v = View()

    def broken(source: str) -> None:
        raise RuntimeError("the panel is broken")

    v.requests.stop = broken  # type: ignore[method-assign]
    try:
        with pytest.raises((http.client.HTTPException, OSError)):
            fetch(v.port, "POST", "/stop", {"X-Lanewarden": "1"})
        assert wait_until(lambda: len(v.lines) == 1, 10.0)
        assert re.fullmatch(r"live view: internal error answering a request: RuntimeError: the "
                            r"panel is broken at test_live_view\.py:\d+ \(the run goes on; "
                            r"please report it\)", v.lines[0]), v.lines
        assert fetch(v.port, "GET", "/status")[0] == 200
        assert "Traceback" not in "".join(capfd.readouterr())
    finally:
        v.server.close()


def test_annotated_frame_shows_the_state_band() -> None:
    image = np.zeros((240, 320), np.uint8)
    picture = annotate(ViewFrame(image, None, None, "none", "HALT", "LANE_LOST: gone"))
    assert picture.shape == (240, 320, 3)
    assert tuple(picture[-2, -2]) == (40, 40, 230), "HALT's colour along the bottom"
    wide = annotate(ViewFrame(np.zeros((720, 1280, 3), np.uint8), None, None, "none",
                              "FOLLOW", None))
    assert wide.shape == (360, 640, 3)
