"""Dead-man latency: last heartbeat -> stop packet on the wire, against the 300 ms target.

Runs the pty stand-in Kobuki (tests/actuation/kobuki_standin.py) and the pretend control process
(tests/actuation/control_process.py, which logs the monotonic time of every completed send), then:
- SIGKILL: the dead-man sees end-of-stream and stops at once;
- SIGSTOP (a frozen control process): the dead-man's heartbeat timeout (0.2 s) trips.
Latency = arrival of the first stop packet at the stand-in - the last logged heartbeat
(CLOCK_MONOTONIC is system-wide, so the processes' stamps compare). Also reports the steady
base-control rate the stand-in receives and how long KobukiBase.open takes.

    python benchmarks/deadman_latency.py [--trials N]
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PROJECT_ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(PROJECT_ROOT))

from lanewarden.actuation.kobuki_base import KobukiBase  # noqa: E402
from tests.actuation.kobuki_standin import STOP_PACKET, KobukiStandIn  # noqa: E402

TARGET_S = 0.300
CONTROL_SCRIPT = PROJECT_ROOT / "tests" / "actuation" / "control_process.py"


def _motion(packets: list) -> bool:  # type: ignore[type-arg]
    return any(p.base_control not in (None, (0, 0)) for p in packets)


def one_trial(how: signal.Signals) -> tuple[float, float]:
    """(last heartbeat -> stop, signal -> stop) in seconds."""
    with KobukiStandIn() as standin, tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "heartbeats"
        control = subprocess.Popen([sys.executable, str(CONTROL_SCRIPT), standin.port, str(log)],
                                   cwd=PROJECT_ROOT, stdin=subprocess.PIPE,
                                   stdout=subprocess.DEVNULL)
        try:
            if not standin.wait_for(_motion, 15.0):
                raise RuntimeError("the control process never drove")
            signalled_at = time.monotonic()
            os.kill(control.pid, how)
            if not standin.wait_for(lambda pkts: any(
                    p.arrival_s >= signalled_at and p.packet == STOP_PACKET for p in pkts), 5.0):
                raise RuntimeError("no stop packet within 5 s")
            stop_at = next(p.arrival_s for p in standin.snapshot()
                           if p.arrival_s >= signalled_at and p.packet == STOP_PACKET)
            heartbeats = [float(line) for line in log.read_text().split()]
            last = max(t for t in heartbeats if t <= stop_at)
            return stop_at - last, stop_at - signalled_at
        finally:
            if how is signal.SIGSTOP:
                os.kill(control.pid, signal.SIGCONT)
            control.kill()
            control.wait()


def steady_rate() -> tuple[float, float]:
    """(base-control packets/s received while driving unchanged, KobukiBase.open seconds)."""
    from lanewarden.actuation.base import VelocityCommand

    with KobukiStandIn() as standin:
        started = time.monotonic()
        with KobukiBase.open(standin.port) as base:
            opened_s = time.monotonic() - started
            command = VelocityCommand(0.2, 0.0)
            begin = time.monotonic()
            while time.monotonic() - begin < 2.0:
                base.send(command, time.monotonic())
                base.wait_for(lambda b: False, 0.1)  # heartbeat every 100 ms
            base.send(VelocityCommand(), time.monotonic())
        moving = [t for t, c in standin.base_controls() if c != (0, 0)]
        return (len(moving) - 1) / (moving[-1] - moving[0]), opened_s


def _summary(name: str, values: list[float]) -> str:
    ms = sorted(v * 1000 for v in values)
    verdict = "PASS" if max(ms) <= TARGET_S * 1000 else "FAIL"
    return (f"{name:34} min {ms[0]:6.1f}  median {statistics.median(ms):6.1f}  "
            f"max {ms[-1]:6.1f} ms  (target {TARGET_S * 1000:.0f} ms: {verdict})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=10)
    trials = parser.parse_args().trials
    rate_hz, open_s = steady_rate()
    print(f"steady base-control rate while the command is unchanged: {rate_hz:.1f} Hz "
          f"(configured 50 Hz)")
    print(f"KobukiBase.open (spawn dead-man, open port, first feedback): {open_s * 1000:.0f} ms")
    for how, label in ((signal.SIGKILL, "SIGKILL control process"),
                       (signal.SIGSTOP, "SIGSTOP (frozen) control process")):
        results = [one_trial(how) for _ in range(trials)]
        print(_summary(f"{label}: last heartbeat->stop", [r[0] for r in results]))
        print(_summary(f"{label}: signal->stop", [r[1] for r in results]))


if __name__ == "__main__":
    main()
