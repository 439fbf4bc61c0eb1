"""The live view: `lanewarden run --view [HOST:]PORT` serves a page with the camera image and
perception's overlay, the supervisor's state and its reason, and Start / Stop / Resume buttons.

Standard library only (http.server's ThreadingHTTPServer): one page with inline CSS and JS (works
offline, no account, nothing fetched from elsewhere) that polls two endpoints, `/status` (JSON) and
`/frame.jpg` (the newest annotated frame), and posts `/start`, `/stop`, `/resume`. Polling suits a
page one operator watches at 5-10 Hz and needs nothing but the standard library; each request is
served by its own short-lived thread, never by the control thread.

The control loop is never slowed or blocked:
- `publish()` (control thread) swaps a reference into a latest-only slot; nothing is copied,
  drawn or encoded there. Frames the page never fetched are dropped (and counted).
- A separate encoder thread draws the overlay and encodes JPEG at most `VIEW_FPS` times a second,
  and only while a page has asked for a frame in the last `VIEWER_IDLE_S` seconds.
- Buttons go through `OperatorPanel`: Stop always works (the loop's own operator_stop, at once);
  Start and Resume only arm, the supervisor still needs its confident frames.

Binds 127.0.0.1 unless a host is given. POSTs need the `X-Lanewarden` header (a page from another
site cannot send it without a CORS preflight, which this server never grants), and the Host header
must name this server when it is bound to loopback (no DNS rebinding).
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any, Protocol

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
REQUEST_HEADER = "X-Lanewarden"
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1", "[::1]")


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


class LiveView:
    """The server, its encoder thread and the slots the control thread publishes into."""

    def __init__(self, host: str, port: int, requests: Requests) -> None:
        self._requests = requests
        self._frames: LatestSlot[ViewFrame] = LatestSlot()
        self._status_lock = threading.Lock()
        self._status: dict[str, Any] = {"state": "HALT", "step": 0}
        self._jpeg_lock = threading.Lock()
        self._jpeg: bytes | None = None
        self._jpeg_seq = 0
        self._last_viewer_s = -float("inf")
        self.frames_encoded = 0
        self._page = resources.files("lanewarden").joinpath("static/live.html").read_bytes()
        try:
            self._server = _Server((host, port), _Handler, self)
        except OSError as exc:
            raise UsageError(f"--view {host}:{port}: cannot listen there "
                             f"({exc.strerror or exc})") from exc
        self.host, self.port = host, int(self._server.server_address[1])
        self._allowed_hosts = (None if host not in LOOPBACK_HOSTS else
                               {f"{h}:{self.port}" for h in LOOPBACK_HOSTS})
        self._threads = [
            threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.2},
                             name="live-view-http", daemon=True),
            threading.Thread(target=self._encode_frames, name="live-view-encoder", daemon=True),
        ]
        for thread in self._threads:
            thread.start()

    @property
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("0.0.0.0", "") else self.host
        return f"http://{host}:{self.port}/"

    # ---- the control thread's side (never blocks) ---------------------------------------------
    def publish(self, status: dict[str, Any], frame: ViewFrame | None) -> None:
        with self._status_lock:
            self._status = status
        if frame is not None:
            self._frames.put(frame)

    @property
    def frames_dropped(self) -> int:
        """Frames published that the page never got (replaced before they were encoded)."""
        return self._frames.dropped

    # ---- the encoder thread -------------------------------------------------------------------
    def _encode_frames(self) -> None:
        lower_priority()  # the control loop wins the CPU; the page gets fewer frames
        period = 1.0 / VIEW_FPS
        while True:
            frame = self._frames.take(timeout_s=0.5)
            if frame is None:
                if self._frames.closed:
                    return
                continue
            if time.monotonic() - self._last_viewer_s > VIEWER_IDLE_S:
                continue  # nobody is watching: don't spend the CPU
            ok, data = cv2.imencode(".jpg", annotate(frame),
                                    [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            if ok:
                with self._jpeg_lock:
                    self._jpeg = data.tobytes()
                    self._jpeg_seq += 1
                self.frames_encoded += 1
            time.sleep(period)  # this thread's own pace (at most VIEW_FPS encodes a second)

    # ---- the HTTP side ------------------------------------------------------------------------
    def status_json(self) -> bytes:
        self._last_viewer_s = time.monotonic()  # an open page polls this: keep encoding
        with self._status_lock:
            status = dict(self._status)
        with self._jpeg_lock:
            status["frame_seq"] = self._jpeg_seq
        status["view_frames_dropped"] = self.frames_dropped
        return json.dumps(status).encode()

    def latest_jpeg(self) -> bytes | None:
        self._last_viewer_s = time.monotonic()
        with self._jpeg_lock:
            return self._jpeg

    def host_allowed(self, host_header: str | None) -> bool:
        return self._allowed_hosts is None or (host_header or "") in self._allowed_hosts

    def request(self, action: str) -> bool:
        if action == "stop":
            self._requests.stop("page")
        elif action == "start":
            self._requests.start("page")
        elif action == "resume":
            self._requests.resume("page")
        else:
            return False
        return True

    def page(self) -> bytes:
        return self._page

    def close(self) -> None:
        self._frames.close()
        self._server.shutdown()
        self._server.server_close()
        for thread in self._threads:
            thread.join(timeout=2.0)


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address: tuple[str, int], handler: type[BaseHTTPRequestHandler],
                 view: LiveView) -> None:
        if ":" in address[0]:
            import socket

            self.address_family = socket.AF_INET6
        self.view = view
        super().__init__(address, handler)


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 (the base's name)
        pass  # the terminal belongs to the status line

    def _send(self, status: HTTPStatus, body: bytes, content_type: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _refuse_host(self) -> bool:
        if self.server.view.host_allowed(self.headers.get("Host")):
            return False
        self._send(HTTPStatus.FORBIDDEN, b"unexpected Host header\n", "text/plain")
        return True

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        if self._refuse_host():
            return
        view = self.server.view
        path = self.path.split("?", 1)[0]
        if path in ("/", "/index.html"):
            self._send(HTTPStatus.OK, view.page(), "text/html; charset=utf-8")
        elif path == "/status":
            self._send(HTTPStatus.OK, view.status_json(), "application/json")
        elif path == "/frame.jpg":
            jpeg = view.latest_jpeg()
            if jpeg is None:
                self._send(HTTPStatus.SERVICE_UNAVAILABLE, b"no frame yet\n", "text/plain")
            else:
                self._send(HTTPStatus.OK, jpeg, "image/jpeg")
        else:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")

    def do_POST(self) -> None:  # noqa: N802 (http.server's name)
        if self._refuse_host():
            return
        length = int(self.headers.get("Content-Length") or 0)
        if length:
            self.rfile.read(min(length, 4096))
        if self.headers.get(REQUEST_HEADER) is None:
            self._send(HTTPStatus.FORBIDDEN, f"missing {REQUEST_HEADER} header\n".encode(),
                       "text/plain")
            return
        action = self.path.split("?", 1)[0].strip("/")
        if self.server.view.request(action):
            self._send(HTTPStatus.OK, json.dumps({"ok": True, "request": action}).encode(),
                       "application/json")
        else:
            self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")
