"""The live view: `lanewarden run --view [HOST:]PORT` serves a page with the camera image and
perception's overlay, the supervisor's state and its reason, a rolling plot of the slope sum and the
confidence, and Start / Stop / Resume buttons.

Standard library only (http.server's ThreadingHTTPServer): one page with inline CSS and JS (works
offline, no account, nothing fetched from elsewhere) that polls `/status` (JSON: the newest status
and the plot's new samples) and `/frame.jpg` (the newest annotated frame, with the status of the
step it belongs to in its `X-Lanewarden-Status` header, so overlay and panel show one step), and
posts `/start`, `/stop`, `/resume`.

The control loop is never slowed or blocked:
- `publish()` (control thread) swaps a reference into a latest-only slot and appends one plot
  sample; nothing is copied, drawn or encoded there.
- A separate encoder thread draws the overlay and encodes JPEG at most `VIEW_FPS` times a second,
  and only while a page has asked for something in the last `VIEWER_IDLE_S` seconds.
- Each connection is served by its own thread, at most `MAX_CONNECTIONS` at once and
  `MAX_CONNECTIONS_PER_CLIENT` from one client address (more are closed at once, unserved; every
  slot taken, the oldest connection whose request has not come through gives way to a new one),
  each with a deadline for its headers (`HEADER_DEADLINE_S`), one for the whole connection and a
  byte budget.
- Closing, it gives a page that was watching up to `FINAL_STATUS_WAIT_S` to fetch the last status
  (why the run ended).

It must never let a request it did not mean to serve reach the robot (issue 18's attacks):
- One request per connection, always `Connection: close`: a body can never be served as a second
  request (request smuggling).
- The body is read exactly as `Content-Length` says; a missing, repeated, non-numeric or too large
  length, a chunked body, or a GET with a body is refused with a 4xx before anything is read.
- The `Host` header must name this server (`AccessRules`: DNS rebinding); a state-changing request
  must come from this server's own page (`Origin`, `Sec-Fetch-Site`) and carry `X-Lanewarden`;
  a GET must not come from another site's page (`Sec-Fetch-Site`), and every answer says
  `Cross-Origin-Resource-Policy: same-origin`, so another site cannot embed the camera picture;
  on any bind address but loopback every request but the page itself carries the run's token.
- A bad client never prints a traceback; an error in this module's own code prints one line.
Buttons go through `OperatorPanel`: Stop always works (the loop's own operator_stop, at once);
Start and Resume only arm, the supervisor still needs its confident frames.
"""

from __future__ import annotations

import hmac
import io
import ipaddress
import json
import math
import re
import secrets
import socket
import sys
import threading
import time
import traceback
from collections import Counter, deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from typing import Any, Protocol
from urllib.parse import parse_qs, urlsplit

import cv2
import numpy as np

from lanewarden.errors import UsageError
from lanewarden.latest_slot import LatestSlot
from lanewarden.perception.detector import DetectionDebug
from lanewarden.perception.observation import LaneObservation
from lanewarden.perception.overlay import draw_overlay
from lanewarden.recording import lower_priority
from lanewarden.scenarios.video import state_color

#: The encoder's ceiling, frames per second (the page asks at most this often, too).
VIEW_FPS = 10.0
#: No request from a page for this long: the encoder stops encoding.
VIEWER_IDLE_S = 2.0
JPEG_QUALITY = 75
#: Frames wider than this are scaled down for the page.
MAX_VIEW_WIDTH_PX = 640
#: Connections served at once; more are closed unserved (the page needs two or three).
MAX_CONNECTIONS = 16
#: Connections one client address may hold at once; more from it are closed unserved, so one
#: host cannot take every slot (idle connections from one attacker, no token needed, had kept the
#: page's Stop from being served for as long as it went on).
MAX_CONNECTIONS_PER_CLIENT = MAX_CONNECTIONS // 2
#: A connection's whole life (request in, response out); a slower client is cut off.
CONNECTION_DEADLINE_S = 5.0
#: ... and the request line and headers must have come within this (a browser sends them at
#: once): an idle connection holds its slot this long, not the whole deadline.
HEADER_DEADLINE_S = 1.0
#: Every slot taken, a new connection takes the slot of the oldest one whose request has not been
#: let through yet (idle, dribbling its headers or body, or still being checked): that one is
#: closed, and the new one waits this long at most for its slot.
EVICTION_WAIT_S = 0.5
#: Closing the view after the run's last status, it keeps answering until a page that was
#: watching has fetched that status (the reason the run ended), at most this long.
FINAL_STATUS_WAIT_S = 1.0
#: Bytes a connection may send: request line, headers and body together.
MAX_REQUEST_BYTES = 8192
#: The largest body a POST may carry (the page's carry none).
MAX_BODY_BYTES = 1024
#: The plot's window, seconds of run time, and the most samples kept for it.
PLOT_WINDOW_S = 10.0
PLOT_MAX_SAMPLES = 1024
#: How often the server's loop looks whether it is asked to stop (closing waits up to this).
SERVER_POLL_S = 0.05
#: Refused requests are reported on the terminal at most once per this many seconds.
REFUSAL_REPORT_EVERY_S = 5.0
#: The header the page's POSTs carry (a page from another site cannot send it without a CORS
#: preflight, which this server never grants).
REQUEST_HEADER = "X-Lanewarden"
#: The header carrying the token (non-loopback binds).
TOKEN_HEADER = "X-Lanewarden-Token"
#: The header of /frame.jpg carrying the status of the frame's step (JSON).
FRAME_STATUS_HEADER = "X-Lanewarden-Status"
#: Host names that are this machine's loopback (IPv6 as in a URL).
LOOPBACK_NAMES = frozenset({"127.0.0.1", "localhost", "[::1]"})
ACTIONS = ("start", "stop", "resume")
#: What a browser asks for on its own, answered without the token or a line on the terminal.
FAVICON_PATH = "/favicon.ico"
#: `Sec-Fetch-Site` of the requests served: the page's own, and for a GET also an address typed,
#: bookmarked or opened from the terminal ('none'); never another site's page (a browser sends
#: 'cross-site' or 'same-site' for those: an <img> of /frame.jpg, a form, a fetch).
STATE_CHANGING_FETCH_SITES = frozenset({"same-origin"})
GET_FETCH_SITES = frozenset({"same-origin", "none"})
_CONTENT_LENGTH = re.compile(r"[0-9]{1,9}")
_SECURITY_HEADERS = (
    ("Cache-Control", "no-store"),
    ("X-Content-Type-Options", "nosniff"),
    ("Referrer-Policy", "no-referrer"),
    ("X-Frame-Options", "DENY"),  # no clickjacking of the buttons from another site's frame
    # no other site's page may embed an answer (an <img> of /frame.jpg showed the camera there)
    ("Cross-Origin-Resource-Policy", "same-origin"),
    ("Content-Security-Policy", "default-src 'none'; script-src 'unsafe-inline'; "
     "style-src 'unsafe-inline'; img-src 'self' blob:; connect-src 'self'; "
     "frame-ancestors 'none'; base-uri 'none'; form-action 'none'"),
    ("Connection", "close"),
)


class Requests(Protocol):
    def start(self, source: str) -> None: ...
    def resume(self, source: str) -> None: ...
    def stop(self, source: str) -> None: ...


@dataclass(frozen=True)
class ViewFrame:
    """What the encoder needs for one picture (references only, nothing copied)."""

    image: np.ndarray
    observation: LaneObservation | None
    debug: DetectionDebug | None
    decision: str
    state: str
    reason: str | None


def parse_view_address(value: str) -> tuple[str, int]:
    """'8080' -> ('127.0.0.1', 8080); 'HOST:PORT' -> (HOST, PORT); UsageError naming --view."""
    host, _, port_text = value.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    try:
        port = int(port_text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise UsageError(f"--view {value!r}: expected [HOST:]PORT with a port 0-65535, "
                         "e.g. 8080 or 0.0.0.0:8080")
    return host, port


def annotate(frame: ViewFrame) -> np.ndarray:
    """The page's picture: the analysed image with perception's overlay and the state banner."""
    if frame.observation is not None and frame.debug is not None:
        canvas = draw_overlay(frame.debug.image, frame.observation, frame.debug, frame.decision)
    else:
        image = frame.image
        canvas = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else (
            image[:, :, :3].copy())
    height, width = canvas.shape[:2]
    if width > MAX_VIEW_WIDTH_PX:
        canvas = cv2.resize(canvas, (MAX_VIEW_WIDTH_PX, round(height * MAX_VIEW_WIDTH_PX / width)),
                            interpolation=cv2.INTER_AREA)
        height, width = canvas.shape[:2]
    band = max(14, height // 14)
    cv2.rectangle(canvas, (0, height - band), (width, height), state_color(frame.state), -1)
    label = frame.state if frame.state != "HALT" or not frame.reason else (
        f"HALT {frame.reason.split(':')[0]}")
    cv2.putText(canvas, label, (4, height - band // 4), cv2.FONT_HERSHEY_SIMPLEX,
                band / 30.0, (255, 255, 255), 1, cv2.LINE_AA)
    return canvas


# ---- who may ask what (pure) --------------------------------------------------------------------
def is_loopback(host: str) -> bool:
    """A bind address only this machine can reach ('localhost', 127.0.0.0/8, ::1)."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.split("%")[0]).is_loopback
    except ValueError:
        return False


def url_name(address: str) -> str:
    """An address as it appears in a URL's host: IPv6 in brackets, IPv4-mapped IPv6 as IPv4,
    names in lower case."""
    try:
        ip = ipaddress.ip_address(address.split("%")[0])
    except ValueError:
        return address.lower()
    if ip.version == 6:
        mapped = ip.ipv4_mapped  # type: ignore[union-attr]
        return str(mapped) if mapped is not None else f"[{ip}]"
    return str(ip)


def split_host(value: str) -> tuple[str, int | None]:
    """A Host header's (name, port): 'a:8080' -> ('a', 8080), '[::1]:80' -> ('[::1]', 80), 'a' ->
    ('a', 80); the port is None when it is not a number."""
    value = value.strip().lower()
    if value.startswith("["):
        end = value.find("]")
        name, rest = (value[:end + 1], value[end + 1:]) if end > 0 else (value, "")
        port_text = rest[1:] if rest.startswith(":") else ("80" if not rest else "")
    elif ":" in value:
        name, _, port_text = value.rpartition(":")
    else:
        name, port_text = value, "80"
    return name, int(port_text) if port_text.isdigit() and len(port_text) <= 5 else None


def machine_names() -> frozenset[str]:
    """This machine's own names: its hostname, its fully qualified name and `<hostname>.local`
    (mDNS, e.g. raspberrypi.local)."""
    hostname = socket.gethostname().lower()
    names = {hostname, f"{hostname}.local"}
    try:
        names.add(socket.getfqdn().lower())
    except OSError:
        pass
    return frozenset(n for n in names if n and n != ".local")


@dataclass(frozen=True)
class AccessRules:
    """Which requests the view serves (docs/operator.md, "Who may use the page").

    - Every request: exactly one `Host` header naming this server with its port: a loopback name
      on a loopback bind; on any other bind also the bound name, this machine's names and the
      address the connection arrived on. A DNS-rebinding page sends its own name: refused.
    - A state-changing request (POST): `X-Lanewarden` present; `Sec-Fetch-Site`, when sent, is
      `same-origin`; `Origin`, when sent, is `http://` + the Host header.
    - Any other request (GET): `Sec-Fetch-Site`, when sent, is `same-origin` or `none`;
      `Origin`, when sent, is `http://` + the Host header (a browser's WebSocket handshake
      carries Origin alone: another site's page had kept the picture encoder busy); no
      `Upgrade` (WebSocket) is served.
    - `token` (every bind but loopback): every request but the page itself carries it in
      `X-Lanewarden-Token` (compared in constant time).
    """

    port: int
    names: frozenset[str]
    token: str | None

    @classmethod
    def for_bind(cls, host: str, port: int, token: str | None = None) -> AccessRules:
        if is_loopback(host):
            return cls(port, LOOPBACK_NAMES | {url_name(host)}, None)
        names = LOOPBACK_NAMES | machine_names()
        if host not in ("0.0.0.0", "::", ""):
            names |= {url_name(host)}
        return cls(port, names, token or secrets.token_urlsafe(18))

    def host_problem(self, hosts: list[str], arrived_on: str) -> str | None:
        """Why the Host header(s) do not name this server (None: they do). `arrived_on`: the
        local address of the connection, as in a URL."""
        if len(hosts) != 1:
            return "no Host header" if not hosts else "more than one Host header"
        name, port = split_host(hosts[0])
        if port != self.port or (name not in self.names and name != arrived_on):
            return f"unexpected Host header {hosts[0][:80]!r}"
        return None

    @staticmethod
    def fetch_site_problem(fetch_site: str | None, state_changing: bool) -> str | None:
        """Why the browser says the request comes from another site's page (None: it does not,
        or it is no browser: no header)."""
        allowed = STATE_CHANGING_FETCH_SITES if state_changing else GET_FETCH_SITES
        if fetch_site is not None and fetch_site.strip().lower() not in allowed:
            return f"a {fetch_site[:40]!r} request (Sec-Fetch-Site)"
        return None

    def origin_problem(self, origin: str | None, fetch_site: str | None, host: str,
                       marked: bool) -> str | None:
        """Why a state-changing request is not from this server's own page (None: it is)."""
        if problem := self.fetch_site_problem(fetch_site, state_changing=True):
            return problem
        if problem := _foreign_origin(origin, host):
            return problem
        if not marked:
            return f"missing {REQUEST_HEADER} header"
        return None

    def get_problem(self, origin: str | None, fetch_site: str | None, host: str,
                    upgrade: str | None) -> str | None:
        """Why a GET is not one this server serves (None: it is)."""
        if upgrade is not None:
            return f"an Upgrade to {upgrade[:40]!r} (only plain HTTP is served)"
        return (self.fetch_site_problem(fetch_site, state_changing=False)
                or _foreign_origin(origin, host))

    def token_problem(self, given: str | None) -> str | None:
        if self.token is None:
            return None
        if given is None:
            return "no token"
        if not hmac.compare_digest(given.strip().encode("utf-8", "replace"),
                                   self.token.encode()):
            return "wrong token"
        return None


def _foreign_origin(origin: str | None, host: str) -> str | None:
    """Why `origin` (when sent) is not this server's page, served as `host`."""
    if origin is not None and origin.strip().lower() != f"http://{host.strip().lower()}":
        return f"unexpected Origin {origin[:80]!r}"
    return None


# ---- the server ---------------------------------------------------------------------------------
def json_text(value: Any) -> str:
    """JSON a browser can parse: a non-finite number (NaN, infinity) becomes null."""
    try:
        return json.dumps(value, allow_nan=False)
    except ValueError:
        return json.dumps(_finite(value), allow_nan=False)


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def printable(text: str, limit: int = 80) -> str:
    """A client's text made safe for the operator's terminal: no control characters (no escape
    sequences), ASCII only, at most `limit` characters."""
    return "".join(c if " " <= c < "\x7f" else "?" for c in text[:limit])


def _stderr_line(text: str) -> None:
    print(f"lanewarden: {text}", file=sys.stderr, flush=True)


def _where(exc: BaseException) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    if not frames:
        return ""
    last = frames[-1]
    return f" at {Path(last.filename).name}:{last.lineno}"


class LiveView:
    """The server, its encoder thread and the slots the control thread publishes into.

    `log`: where one-line messages go (refused requests, an internal error): the run's terminal.
    `plot`: constants the page's plot draws (`turn_enter_slope_sum`, `turn_exit_slope_sum`).
    `token`: the token a non-loopback bind requires (None: a fresh random one).
    """

    def __init__(self, host: str, port: int, requests: Requests, *,
                 log: Callable[[str], None] = _stderr_line,
                 plot: Mapping[str, float] | None = None, token: str | None = None,
                 connection_deadline_s: float = CONNECTION_DEADLINE_S,
                 header_deadline_s: float = HEADER_DEADLINE_S,
                 final_status_wait_s: float = FINAL_STATUS_WAIT_S) -> None:
        self._requests = requests
        self._log = log
        self._plot = dict(plot or {})
        self.connection_deadline_s = connection_deadline_s
        self.header_deadline_s = min(header_deadline_s, connection_deadline_s)
        self._final_status_wait_s = final_status_wait_s
        #: Set once a page has been served a status saying the run ended (`close` waits for it).
        self._end_served = threading.Event()
        self._frames: LatestSlot[tuple[ViewFrame, dict[str, Any]]] = LatestSlot()
        self._status_lock = threading.Lock()
        self._status: dict[str, Any] = {"state": "HALT", "step": 0}
        self._samples: deque[tuple[Any, ...]] = deque(maxlen=PLOT_MAX_SAMPLES)
        self._jpeg_lock = threading.Lock()
        self._jpeg: tuple[bytes, str] | None = None  # (JPEG, the JSON status of its step)
        self._jpeg_seq = 0
        self._last_viewer_s = -float("inf")
        self.frames_encoded = 0
        self._counts_lock = threading.Lock()
        #: What the server did, for the operator and the tests: connections served, refused
        #: (busy), cut off (deadline, byte budget, hang-up), refused requests by reason, the most
        #: connections open at once and the most bytes one connection sent.
        self.counts: dict[str, int] = {"served": 0, "closed": 0, "busy": 0, "evicted": 0,
                                       "cut_off": 0,
                                       "refused": 0, "peak_open": 0, "largest_request": 0}
        self._open = 0
        self._refusals = _Throttle()
        self._busy = _Throttle()
        self._page = resources.files("lanewarden").joinpath("static/live.html").read_bytes()
        self.rules = AccessRules.for_bind(host, port, token)
        try:
            self._server = _Server((host, port), _Handler, self)
        except OSError as exc:
            raise UsageError(f"--view {host}:{port}: cannot listen there "
                             f"({exc.strerror or exc})") from exc
        self.host, self.port = host, int(self._server.server_address[1])
        self.rules = AccessRules(self.port, self.rules.names, self.rules.token)
        self._threads = [
            threading.Thread(target=self._server.serve_forever,
                             kwargs={"poll_interval": SERVER_POLL_S}, name="live-view-http",
                             daemon=True),
            threading.Thread(target=self._encode_frames, name="live-view-encoder", daemon=True),
        ]
        for thread in self._threads:
            thread.start()

    @property
    def token(self) -> str | None:
        return self.rules.token

    @property
    def url(self) -> str:
        """The page's address to print (with the token in the fragment, which browsers never
        send to a server nor put in a Referer)."""
        host = socket.gethostname() if self.host in ("0.0.0.0", "::", "") else self.host
        base = f"http://{url_name(host)}:{self.port}/"
        return base if self.token is None else f"{base}#token={self.token}"

    # ---- the control thread's side (never blocks) ---------------------------------------------
    def publish(self, status: dict[str, Any], frame: ViewFrame | None) -> None:
        sample = (status.get("step"), status.get("time_s"), status.get("slope_sum"),
                  status.get("filtered_slope_sum"), status.get("confidence"))
        with self._status_lock:
            self._status = status
            self._samples.append(sample)
        if frame is not None:
            self._frames.put((frame, status))

    @property
    def frames_dropped(self) -> int:
        """Frames published that the page never got (replaced before they were encoded)."""
        return self._frames.dropped

    # ---- the encoder thread -------------------------------------------------------------------
    def _encode_frames(self) -> None:
        lower_priority()  # the control loop wins the CPU; the page gets fewer frames
        period = 1.0 / VIEW_FPS
        while True:
            taken = self._frames.take(timeout_s=0.5)
            if taken is None:
                if self._frames.closed:
                    return
                continue
            if time.monotonic() - self._last_viewer_s > VIEWER_IDLE_S:
                continue  # nobody is watching: don't spend the CPU
            frame, status = taken
            try:
                ok, data = cv2.imencode(".jpg", annotate(frame),
                                        [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
                status_json = json_text(status)
            except Exception as exc:  # noqa: BLE001 (our own bug: one line, the run goes on)
                self.report_error("drawing the page's frame", exc)
                continue
            if ok:
                with self._jpeg_lock:
                    self._jpeg = (data.tobytes(), status_json)
                    self._jpeg_seq += 1
                self.frames_encoded += 1
            time.sleep(period)  # this thread's own pace (at most VIEW_FPS encodes a second)

    # ---- what the handler asks ----------------------------------------------------------------
    def status_json(self, since_step: int = -1) -> bytes:
        """The newest status, the newest frame's number and step, and the plot's samples newer
        than `since_step` within the last PLOT_WINDOW_S seconds."""
        self._last_viewer_s = time.monotonic()  # an open page polls this: keep encoding
        with self._status_lock:
            status = dict(self._status)
            samples = list(self._samples)
        if status.get("end_reason"):
            self._end_served.set()
        with self._jpeg_lock:
            status["frame_seq"] = self._jpeg_seq
        newest = samples[-1][1] if samples and samples[-1][1] is not None else 0.0
        oldest = newest - PLOT_WINDOW_S
        status["plot"] = {**self._plot, "window_s": PLOT_WINDOW_S, "samples": [
            s for s in samples if isinstance(s[0], int) and s[0] > since_step
            and (s[1] or 0.0) >= oldest]}
        status["view_frames_dropped"] = self.frames_dropped
        return json_text(status).encode()

    def latest_jpeg(self) -> tuple[bytes, str] | None:
        """The newest annotated frame and the JSON status of the step it belongs to."""
        self._last_viewer_s = time.monotonic()
        with self._jpeg_lock:
            return self._jpeg

    def request(self, action: str) -> None:
        if action == "stop":
            self._requests.stop("page")
        elif action == "start":
            self._requests.start("page")
        else:
            self._requests.resume("page")

    def page(self) -> bytes:
        return self._page

    # ---- bookkeeping (any thread) -------------------------------------------------------------
    def count(self, key: str, amount: int = 1) -> None:
        with self._counts_lock:
            self.counts[key] += amount

    @property
    def open_connections(self) -> int:
        with self._counts_lock:
            return self._open

    def connection_opened(self) -> None:
        with self._counts_lock:
            self._open += 1
            self.counts["peak_open"] = max(self.counts["peak_open"], self._open)

    def connection_closed(self, bytes_read: int) -> None:
        with self._counts_lock:
            self._open -= 1
            self.counts["closed"] += 1
            self.counts["largest_request"] = max(self.counts["largest_request"], bytes_read)

    def busy(self, client: str, one_client: bool = False) -> None:
        """A connection closed unserved, every slot taken (`one_client`: every slot one client
        may hold): one line on the terminal, at most every REFUSAL_REPORT_EVERY_S (slow or idle
        clients holding every slot kept the page's Stop from being served for seconds, and
        nothing said so: an attacker's review)."""
        taken = (f"{MAX_CONNECTIONS_PER_CLIENT} connections from one client open" if one_client
                 else f"all {MAX_CONNECTIONS} connections busy")
        self._counted("busy", self._busy, lambda more: (
            f"live view: {taken}, one from {printable(client)} closed unserved"
            + (f" (and {more} more before)" if more else "")
            + ": the page's buttons may not get through (slow or idle clients?); stop from the "
            "keys, Ctrl-C or the base's B1"))

    def evicted(self, victim: str, newcomer: str) -> None:
        """Every slot taken, the oldest connection whose request had not come through was closed
        for a new one: one line on the terminal, at most every REFUSAL_REPORT_EVERY_S."""
        self._counted("evicted", self._busy, lambda more: (
            f"live view: all {MAX_CONNECTIONS} connections busy: closed the oldest whose request "
            f"had not come through, from {printable(victim)}, for one from {printable(newcomer)}"
            + (f" (and {more} more before)" if more else "") + " (slow or idle clients?)"))

    def refused(self, what: str, client: str, problem: str) -> None:
        """A refused request: one line on the terminal, at most every REFUSAL_REPORT_EVERY_S
        (with how many more were refused meanwhile)."""
        self._counted("refused", self._refusals, lambda more: (
            f"live view: refused {printable(what)} from {printable(client)}: "
            f"{printable(problem, 200)}" + (f" (and {more} more refused before)" if more else "")))

    def _counted(self, key: str, throttle: _Throttle, line: Callable[[int], str]) -> None:
        """Count `key`; say `line(how many were held back since)` when `throttle` lets it."""
        with self._counts_lock:
            self.counts[key] += 1
            more = throttle.due(time.monotonic())
        if more is not None:
            self._log(line(more))

    def report_error(self, doing: str, exc: BaseException) -> None:
        """An error in our own code while serving: one line, the run goes on."""
        self._log(f"live view: internal error {doing}: {type(exc).__name__}: "
                  f"{printable(str(exc), 200)}{_where(exc)} (the run goes on; please report it)")

    def close(self) -> None:
        """Stop serving. A page that was watching (a request within VIEWER_IDLE_S) is first given
        the time to fetch the last status published, when it says why the run ended, at most
        `final_status_wait_s`: the page had kept showing the last state, FOLLOW at 0.20 m/s, for
        a run that had ended (the server closed before its next poll)."""
        with self._status_lock:
            ended = bool(self._status.get("end_reason"))
        if ended and time.monotonic() - self._last_viewer_s <= VIEWER_IDLE_S:
            self._end_served.wait(self._final_status_wait_s)
        self._frames.close()
        self._server.shutdown()
        self._server.server_close()
        for thread in self._threads:
            thread.join(timeout=2.0)
        with self._counts_lock:  # refusals counted but not yet reported: said once, at the end
            more = self._refusals.take_held()
        if more:
            self._log(f"live view: {more} more request{'s' if more > 1 else ''} refused after the "
                      "last one reported")


class _Throttle:
    """One kind of terminal line, said at most every REFUSAL_REPORT_EVERY_S: `due(now)` is None
    while it is held back (counted), else how many were held back since it was last said.
    Called under the view's counts lock."""

    def __init__(self) -> None:
        self._last_s = -float("inf")
        self._held = 0

    def due(self, now: float) -> int | None:
        if now - self._last_s < REFUSAL_REPORT_EVERY_S:
            self._held += 1
            return None
        self._last_s = now
        return self.take_held()

    def take_held(self) -> int:
        """How many were held back, and none any more."""
        held, self._held = self._held, 0
        return held


class _RequestTooLarge(Exception):
    """The connection sent more than MAX_REQUEST_BYTES."""


class _DeadlineReader(io.RawIOBase):
    """A connection's reading side: every read waits at most until the connection's deadline
    (a client sending a byte now and then cannot hold it longer) and the connection may send at
    most `budget` bytes (headers and body together)."""

    def __init__(self, connection: socket.socket, deadline_s: float, budget: int) -> None:
        super().__init__()
        self._connection = connection
        self.deadline_s = deadline_s
        self._budget = budget
        self.bytes_read = 0

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        left = self._budget - self.bytes_read
        if left <= 0:
            raise _RequestTooLarge
        remaining_s = self.deadline_s - time.monotonic()
        if remaining_s <= 0:
            raise TimeoutError("the request was not complete in time")
        self._connection.settimeout(remaining_s)
        with memoryview(buffer) as view:
            count = self._connection.recv_into(view[:left])
        self.bytes_read += count
        return count


class _LineReader(io.BufferedReader):
    """Remembers the last line read: a header section must end with an empty line, not with the
    client hanging up (http.client takes either as the end)."""

    last_line = b""

    def readline(self, size: int | None = -1) -> bytes:
        self.last_line = super().readline(-1 if size is None else size)
        return self.last_line


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True
    request_queue_size = 4 * MAX_CONNECTIONS  # a burst waits in the kernel, not in threads

    def __init__(self, address: tuple[str, int], handler: type[BaseHTTPRequestHandler],
                 view: LiveView) -> None:
        if ":" in address[0]:
            self.address_family = socket.AF_INET6
        self.view = view
        self._slots = threading.BoundedSemaphore(MAX_CONNECTIONS)
        self._lock = threading.Lock()  # (the two below)
        self._per_client: Counter[str] = Counter()
        #: connections whose request has not been let through yet, and where each comes from, in
        #: the order they were accepted (the first is the oldest)
        self._pending: dict[socket.socket, str] = {}
        super().__init__(address, handler)

    def process_request(self, request: Any, client_address: Any) -> None:
        """A thread per connection, at most MAX_CONNECTIONS, and at most
        MAX_CONNECTIONS_PER_CLIENT from one client address: more are closed at once."""
        client = _address(client_address)
        with self._lock:
            one_client = self._per_client[client] >= MAX_CONNECTIONS_PER_CLIENT
            if not one_client:
                self._per_client[client] += 1
        shown = (f"{client_address[0]}:{client_address[1]}"
                 if isinstance(client_address, tuple) and len(client_address) >= 2
                 else str(client_address))
        if one_client or not (self._slots.acquire(blocking=False)
                              or self._evict_for_one(shown)):
            if not one_client:
                self._client_left(client)
            self.shutdown_request(request)
            self.view.busy(shown, one_client)
            return
        with self._lock:
            self._pending[request] = shown
        try:
            super().process_request(request, client_address)
        except BaseException:
            self.let_through(request)
            self._slots.release()
            self._client_left(client)
            raise

    def _evict_for_one(self, newcomer: str) -> bool:
        """Every slot taken: close the oldest connection whose request has not been let through
        (many hosts' idle or dribbling connections, each within its deadlines, had kept the
        page's Stop out), then wait up to EVICTION_WAIT_S for its slot. Whether a slot was
        taken."""
        with self._lock:
            if not self._pending:
                return False
            oldest = next(iter(self._pending))
            victim = self._pending.pop(oldest)
            try:
                oldest.shutdown(socket.SHUT_RDWR)  # its thread reads the end and leaves
            except OSError:
                pass
        self.view.evicted(victim, newcomer)
        return self._slots.acquire(timeout=EVICTION_WAIT_S)

    def let_through(self, request: socket.socket) -> None:
        """The request on this connection passed the checks (or the connection ended): it is
        served, never closed for a newcomer."""
        with self._lock:
            self._pending.pop(request, None)

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self.let_through(request)
            self._slots.release()
            self._client_left(_address(client_address))

    def _client_left(self, client: str) -> None:
        with self._lock:
            self._per_client[client] -= 1
            if self._per_client[client] <= 0:
                del self._per_client[client]

    def handle_error(self, request: Any, client_address: Any) -> None:
        """No traceback for a client's doing (it hung up, reset, stalled); one line for ours."""
        exc = sys.exc_info()[1]
        if exc is None or isinstance(exc, OSError):
            self.view.count("cut_off")
            return
        self.view.report_error("answering a request", exc)


def _address(client_address: Any) -> str:
    """The client's address without its port (what MAX_CONNECTIONS_PER_CLIENT counts by)."""
    if isinstance(client_address, tuple) and client_address:
        return str(client_address[0])
    return str(client_address)


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    protocol_version = "HTTP/1.1"
    _reader: _DeadlineReader | None = None
    _lines: _LineReader

    # ---- one request per connection, within a deadline and a byte budget ----------------------
    def setup(self) -> None:
        super().setup()
        self.rfile.close()  # replaced by a reader with a deadline and a budget
        view = self.server.view
        view.connection_opened()
        self._opened_s = time.monotonic()
        self._reader = _DeadlineReader(self.connection, self._opened_s + view.header_deadline_s,
                                       MAX_REQUEST_BYTES)
        self.rfile = self._lines = _LineReader(self._reader, 2048)

    def handle(self) -> None:
        self.close_connection = True
        try:
            self.handle_one_request()  # one request, never a second one from the same bytes
        except _RequestTooLarge:
            self._refuse_quietly(HTTPStatus.REQUEST_HEADER_FIELDS_TOO_LARGE,
                                 f"request larger than {MAX_REQUEST_BYTES} bytes")
        except OSError:  # hung up, reset, or too slow: nothing to answer
            self.server.view.count("cut_off")
        self.close_connection = True

    def finish(self) -> None:
        try:
            super().finish()
        finally:
            self.server.view.connection_closed(self._reader.bytes_read if self._reader else 0)

    def parse_request(self) -> bool:
        if not super().parse_request():
            return False
        if self.request_version not in ("HTTP/1.0", "HTTP/1.1"):
            self.send_error(HTTPStatus.HTTP_VERSION_NOT_SUPPORTED)
            return False
        if self._lines.last_line not in (b"\r\n", b"\n"):
            raise ConnectionAbortedError("the client hung up within the headers")
        if self._reader is not None:  # the headers came in time: the body and the answer may
            # take the rest of the connection's deadline
            self._reader.deadline_s = self._opened_s + self.server.view.connection_deadline_s
        return True

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 (the base's name)
        pass  # the terminal belongs to the status line; refusals are reported by LiveView

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """http.server's own refusals (bad request line, unknown method, ...): short, plain,
        closing."""
        try:
            phrase = HTTPStatus(code).phrase
        except ValueError:
            phrase = ""
        self.close_connection = True
        if self.request_version not in ("HTTP/1.0", "HTTP/1.1"):
            self.request_version = "HTTP/1.1"  # a status line even for HTTP/0.9 or 2
        self._send(code, f"{code} {phrase}\n".encode(), "text/plain")

    def _send(self, status: int, body: bytes, content_type: str,
              headers: tuple[tuple[str, str], ...] = ()) -> None:
        deadline_s = self._reader.deadline_s if self._reader else time.monotonic()
        self.connection.settimeout(max(0.05, deadline_s - time.monotonic()))
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        for name, value in (*_SECURITY_HEADERS, *headers):
            self.send_header(name, value)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _refuse_quietly(self, status: HTTPStatus, text: str) -> None:
        try:
            self._send(status, f"{text}\n".encode(), "text/plain")
        except OSError:
            pass

    # ---- the checks -----------------------------------------------------------------------------
    def _body_problem(self) -> tuple[HTTPStatus, str] | None:
        """Read the body exactly as Content-Length says, or say why not (nothing read then)."""
        if self.headers.get_all("Transfer-Encoding"):
            return HTTPStatus.BAD_REQUEST, "no Transfer-Encoding accepted (send Content-Length)"
        lengths = self.headers.get_all("Content-Length") or []
        if len(lengths) > 1:
            return HTTPStatus.BAD_REQUEST, "more than one Content-Length"
        text = lengths[0].strip() if lengths else None
        if self.command != "POST":
            return None if text in (None, "0") else (HTTPStatus.BAD_REQUEST,
                                                      f"a {self.command} carries no body")
        if text is None:
            return HTTPStatus.LENGTH_REQUIRED, "Content-Length required"
        if not _CONTENT_LENGTH.fullmatch(text):
            return HTTPStatus.BAD_REQUEST, f"bad Content-Length {text[:40]!r}"
        length = int(text)
        if length > MAX_BODY_BYTES:
            return HTTPStatus.REQUEST_ENTITY_TOO_LARGE, f"body over {MAX_BODY_BYTES} bytes"
        if len(self.rfile.read(length)) != length:
            raise ConnectionAbortedError("the client hung up within the body")
        return None

    def _client(self) -> str:
        return str(self.client_address[0]) if self.client_address else "?"

    def _arrived_on(self) -> str:
        try:
            return url_name(str(self.connection.getsockname()[0]))
        except OSError:
            return ""

    def _refuse(self, status: HTTPStatus, problem: str) -> None:
        self.server.view.refused(f"{self.command} {self.path[:60]}", self._client(), problem)
        self._send(status, f"{problem}\n".encode(), "text/plain")

    def _allowed(self, *, state_changing: bool, needs_token: bool) -> bool:
        """Run the checks in order; answer the first problem and say False."""
        framing = self._body_problem()
        if framing is not None:
            self._refuse(*framing)
            return False
        rules = self.server.view.rules
        hosts = self.headers.get_all("Host") or []
        problem = rules.host_problem(hosts, self._arrived_on())
        fetch_site = self.headers.get("Sec-Fetch-Site")
        if problem is None and state_changing:
            problem = rules.origin_problem(self.headers.get("Origin"), fetch_site, hosts[0],
                                           self.headers.get(REQUEST_HEADER) is not None)
        elif problem is None:  # another site's <img> of /frame.jpg had shown the camera there
            problem = rules.get_problem(self.headers.get("Origin"), fetch_site, hosts[0],
                                        self.headers.get("Upgrade"))
        if problem is not None:
            self._refuse(HTTPStatus.FORBIDDEN, problem)
            return False
        problem = rules.token_problem(self.headers.get(TOKEN_HEADER)) if needs_token else None
        if problem is not None:
            self._refuse(HTTPStatus.UNAUTHORIZED,
                         f"{problem}: this page needs the token printed on the robot's terminal")
            return False
        self.server.let_through(self.connection)
        return True

    # ---- the endpoints --------------------------------------------------------------------------
    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        view = self.server.view
        parts = urlsplit(self.path)
        path = parts.path
        if not self._allowed(state_changing=False,
                             needs_token=path not in ("/", "/index.html", FAVICON_PATH)):
            return
        view.count("served")
        if path == FAVICON_PATH:  # (a browser asks on its own: no token, no line refused)
            self._send(HTTPStatus.NOT_FOUND, b"no icon\n", "text/plain")
        elif path in ("/", "/index.html"):
            self._send(HTTPStatus.OK, view.page(), "text/html; charset=utf-8")
        elif path == "/status":
            since = parse_qs(parts.query).get("since", ["-1"])[0]
            self._send(HTTPStatus.OK, view.status_json(
                int(since) if re.fullmatch(r"-?[0-9]{1,12}", since) else -1), "application/json")
        elif path == "/frame.jpg":
            frame = view.latest_jpeg()
            if frame is None:
                self._send(HTTPStatus.SERVICE_UNAVAILABLE, b"no frame yet\n", "text/plain")
            else:
                self._send(HTTPStatus.OK, frame[0], "image/jpeg",
                           ((FRAME_STATUS_HEADER, frame[1]),))
        else:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")

    def do_POST(self) -> None:  # noqa: N802 (http.server's name)
        if not self._allowed(state_changing=True, needs_token=True):
            return
        action = self.path.split("?", 1)[0].removeprefix("/")
        if action not in ACTIONS:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")
            return
        self.server.view.count("served")
        self.server.view.request(action)
        self._send(HTTPStatus.OK, json.dumps({"ok": True, "request": action}).encode(),
                   "application/json")
