"""Helpers for tests that signal a `lanewarden` process and read the stand-in's packet log (TEST
code): start the CLI in a process group of its own, or the pretend control process
(control_process.py), see whether it is stopped, find its dead-man, and check what reached the
wire after a moment."""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
from pathlib import Path

from tests.actuation.kobuki_standin import STOP_PACKET, KobukiStandIn, ReceivedPacket

PROJECT_ROOT = Path(__file__).resolve().parents[2]
CONTROL_SCRIPT = Path(__file__).with_name("control_process.py")
DEADLINE_S = 5.0


def start_lanewarden(*args: str) -> subprocess.Popen[str]:
    """`python -m lanewarden ARGS` as the leader of a new session and process group (as a shell
    runs a job), so `os.killpg(process.pid, ...)` reaches exactly what the terminal would."""
    return subprocess.Popen([sys.executable, "-m", "lanewarden", *args], cwd=PROJECT_ROOT,
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def process_state(pid: int) -> str:
    """The kernel's one-letter state of `pid` (R, S, T for stopped, Z, ...; "" when gone)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return ""
    return stat.rsplit(")", 1)[1].split()[0]


def child_pids(pid: int) -> list[int]:
    children: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            children += [int(c) for c in (task / "children").read_text().split()]
        except OSError:
            pass
    return children


def deadman_of(pid: int, standin: KobukiStandIn) -> int:
    """The dead-man process started by `pid` (waits, re-checking at every packet on the wire)."""
    found: list[int] = []

    def started(_: list[ReceivedPacket]) -> bool:
        for child in child_pids(pid):
            try:
                cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
            except OSError:
                continue
            if b"lanewarden.actuation.deadman" in cmdline:
                found.append(child)
                return True
        return False

    assert standin.wait_for(started, 3 * DEADLINE_S), "no dead-man process started"
    return found[0]


def is_motion(packet: ReceivedPacket) -> bool:
    control = packet.base_control
    return control is not None and control != (0, 0)


def wait_for_stop_after(standin: KobukiStandIn, since_s: float) -> None:
    assert standin.wait_for(lambda pkts: any(
        p.arrival_s >= since_s and p.packet == STOP_PACKET for p in pkts), DEADLINE_S), \
        "no stop on the wire"


def motion_after_the_stop(standin: KobukiStandIn, since_s: float) -> list[ReceivedPacket]:
    """Motion packets that reached the wire after the first stop that arrived at or after
    `since_s` (there must be none when the stop held)."""
    after = [p for p in standin.snapshot() if p.arrival_s >= since_s]
    first_stop = next(i for i, p in enumerate(after) if p.packet == STOP_PACKET)
    return [p for p in after[first_stop:] if is_motion(p)]


def wait_for_more_packets(standin: KobukiStandIn, count: int) -> None:
    mark = len(standin.snapshot())
    assert standin.wait_for(lambda pkts: len(pkts) >= mark + count, DEADLINE_S), \
        "nothing reaches the wire any more"


def assert_stop_held_since(standin: KobukiStandIn, since_s: float) -> None:
    """A stop reached the wire at or after `since_s`, it is the last packet there once the
    sender is done, and nothing non-zero came after it."""
    wait_for_stop_after(standin, since_s)
    assert standin.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
    assert motion_after_the_stop(standin, since_s) == []


def stderr_lines(err: str) -> list[str]:
    """The lines of stderr, without start-up warnings (`lanewarden: warning: ...`, e.g. a
    dead-man that could not raise its priority on a machine where that is not permitted)."""
    return [line for line in err.strip().splitlines()
            if not line.startswith("lanewarden: warning: ")]


class ControlProcess:
    """tests/actuation/control_process.py on `port` (extra `args` passed on) as a subprocess, its
    stdout lines on a queue."""

    def __init__(self, port: str, *args: str) -> None:
        self.process = subprocess.Popen(
            [sys.executable, str(CONTROL_SCRIPT), port, *args], cwd=PROJECT_ROOT,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._pump, daemon=True).start()
        self.deadman_pid = int(self.expect("deadman "))

    def _pump(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.put(line.strip())

    def expect(self, prefix: str) -> str:
        """The next line, which must start with `prefix`, without it."""
        line = self.lines.get(timeout=3 * DEADLINE_S)
        assert line.startswith(prefix), line
        return line[len(prefix):]

    def say(self, line: str) -> None:
        assert self.process.stdin is not None
        self.process.stdin.write(line + "\n")
        self.process.stdin.flush()

    def close(self) -> None:
        os.kill(self.process.pid, signal.SIGCONT)  # a frozen process cannot die of SIGKILL late
        self.process.kill()
        self.process.wait(timeout=DEADLINE_S)
