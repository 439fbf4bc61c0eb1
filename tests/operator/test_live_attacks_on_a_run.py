"""Issue 18's attacks on the live view of a real `lanewarden run --base sim --view`, at socket
level: the operator engages the robot, stops it from the page, and then every attack is thrown at
the page's port. The recorded run shows the robot never left HALT (no start or resume reached the
loop, every command after the stop is zero), nothing printed a traceback, and the refusals were
reported in one line each now and then. The clip shows the lane all along, so a resume that got
through would have engaged again (as the first start did)."""

from __future__ import annotations

import http.client
import json
import os
import signal
import socket
from pathlib import Path
from typing import Any

import pytest

from tests.operator.runs import free_port, run_beside, steps, wait_until
from tests.operator.test_live_page_browser import PATIENT_CONFIG, lasting_lane_images
from tests.operator.test_live_view import SMUGGLED_RESUME, exchange, post, statuses


def _status(port: int) -> dict[str, Any] | None:
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    try:
        connection.request("GET", "/status")
        return dict(json.loads(connection.getresponse().read()))
    except (OSError, ValueError):
        return None
    finally:
        connection.close()


def _attacks(port: int) -> dict[str, list[int]]:
    """Every attack once; what each got back (the status codes on its connection)."""
    smuggled = SMUGGLED_RESUME % port
    head = f"Host: 127.0.0.1:{port}\r\n"
    got: dict[str, list[int]] = {}
    got["smuggled in a 4096-byte body"] = statuses(exchange(port, (
        f"POST /stop HTTP/1.1\r\n{head}Content-Type: text/plain\r\n"
        f"Content-Length: {4096 + len(smuggled)}\r\n\r\n").encode() + b"a" * 4096 + smuggled))
    got["pipelined after a stop"] = statuses(exchange(port, post("/stop", port) + smuggled))
    got["DNS rebinding"] = statuses(exchange(port, (
        f"POST /resume HTTP/1.1\r\nHost: evil.example:{port}\r\nX-Lanewarden: 1\r\n"
        "Content-Length: 0\r\n\r\n").encode()))
    got["foreign Origin"] = statuses(exchange(port, (
        f"POST /start HTTP/1.1\r\n{head}X-Lanewarden: 1\r\nOrigin: http://evil.example\r\n"
        "Content-Length: 0\r\n\r\n").encode()))
    got["no header"] = statuses(exchange(port, (
        f"POST /resume HTTP/1.1\r\n{head}Content-Length: 0\r\n\r\n").encode()))
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(f"POST /resume HTTP/1.1\r\n{head}X-Lanewarden: 1\r\n"
                  "Content-Length: -1\r\n\r\n".encode())
        try:
            for _ in range(32):
                s.sendall(b"x" * 65536)
        except OSError:
            pass  # closed by the server
        try:
            got["Content-Length -1 and 2 MiB"] = statuses(s.recv(4096))
        except OSError:
            got["Content-Length -1 and 2 MiB"] = []
    got["huge headers"] = statuses(exchange(port, (
        f"POST /resume HTTP/1.1\r\n{head}X-Lanewarden: 1\r\n"
        + "".join(f"X-Big-{i}: {'z' * 500}\r\n" for i in range(40)) + "\r\n").encode()))
    got["unknown method"] = statuses(exchange(port, (
        f"RESUME /resume HTTP/1.1\r\n{head}X-Lanewarden: 1\r\n\r\n").encode()))
    idle = [socket.create_connection(("127.0.0.1", port), timeout=10) for _ in range(40)]
    for s in idle[:5]:
        s.sendall(b"POST /resume HTTP/1.1\r\n")  # and then nothing more
    for s in idle:
        s.close()
    return got


def test_the_robot_never_leaves_halt_under_attack(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    clip = lasting_lane_images(tmp_path)
    record = tmp_path / "run"
    config = tmp_path / "patient.yaml"
    config.write_text(PATIENT_CONFIG, encoding="utf-8")
    port = free_port()
    seen: dict[str, Any] = {}

    def operator() -> None:
        try:
            if not wait_until(lambda: (_status(port) or {}).get("state") == "FOLLOW", 40.0):
                return
            seen["engaged"] = True
            stop = exchange(port, post("/stop", port))
            seen["stop"] = statuses(stop)
            if not wait_until(lambda: (_status(port) or {}).get("state") == "HALT", 10.0):
                return
            seen["attacks"] = _attacks(port)
            # The page is served again once the attackers' connections are gone.
            status: dict[str, Any] = {}
            if not wait_until(lambda: bool(status.update(_status(port) or {}) or status), 20.0):
                return
            # Long enough for a resume that got through to engage (confident frames) again.
            seen["after"] = wait_until(
                lambda: (_status(port) or {}).get("step", 0) >= status["step"] + 90, 30.0)
        finally:
            os.kill(os.getpid(), signal.SIGINT)

    code = run_beside(operator, ["--camera", str(clip), "--base", "sim", "--view", str(port),
                                 "--record", str(record), "--config", str(config)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert seen.get("engaged") and seen.get("stop") == [200], seen
    assert seen.get("after"), seen
    attacks = seen["attacks"]
    # The answer to the flood may be lost to the reset of the unread data it left behind.
    assert attacks.pop("Content-Length -1 and 2 MiB") in ([400], []), attacks
    assert attacks == {
        "smuggled in a 4096-byte body": [413], "pipelined after a stop": [200],
        "DNS rebinding": [403], "foreign Origin": [403], "no header": [403],
        "huge headers": [431], "unknown method": [501]}
    records = steps(record)
    stopped = next(k for k, r in enumerate(records) if "stop" in r["input"].get("requests", []))
    after = records[stopped:]
    assert len(after) > 90
    assert all(r["state"] == "HALT" for r in after), "the robot left HALT"
    assert all(r["command"]["linear_m_s"] == 0.0 and r["command"]["angular_rad_s"] == 0.0
               for r in after)
    assert not any({"start", "resume"} & set(r["input"].get("requests", [])) for r in after)
    assert "Traceback" not in out + err
    assert out.count("stop requested (page)") == 2, "the page's two stops, announced"
    assert "resume requested" not in out and out.count("start requested") == 1
    assert "live view: refused POST /stop from 127.0.0.1: body over 1024 bytes" in out
    last_frame = records[-1]["frame_index"]
    assert last_frame is not None and last_frame < len(list(clip.iterdir())) - 1, \
        "the clip (its lane all along) had not run out: a resume that got through would engage"
