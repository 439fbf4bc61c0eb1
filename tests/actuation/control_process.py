"""A pretend control process for the dead-man end-to-end tests and benchmark (TEST code).

`python tests/actuation/control_process.py PORT [HEARTBEAT_LOG] [--heartbeat-timeout-s S]`:
opens KobukiBase on PORT, prints `deadman <pid>`, then sends 0.2 m/s every 20 ms (its control
tick) forever, appending to HEARTBEAT_LOG, if given, the monotonic time taken just before each
send. It keeps sending whatever happens (the dead-man must ignore that stream when it holds a
stop) and prints:
- `tripped STOPPED_S REASON` when send() says the dead-man tripped (STOPPED_S: when the dead-man
  wrote the stop; its reason names the stamp of the last heartbeat it accepted);
- `latched STOPPED_S REASON` when the dead-man latched a stop of its own (bumper, cliff, wheel
  drop, stale feedback).
Lines on stdin: `rearm` (KobukiBase.rearm, then `rearmed`, or `not rearmed MODE` when the
dead-man stays in MODE), `resume` (the operator's KobukiBase.resume, then `resumed`, or
`refused REASON`) and `hold` (KobukiBase.hold_stopped, as before a Ctrl-Z, then `held`).
"""

from __future__ import annotations

import argparse
import os
import select
import sys
import threading
import time

from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.config import ActuationConfig
from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.errors import DeadmanTrippedError
from lanewarden.actuation.kobuki_base import KobukiBase

CONTROL_PERIOD_S = 0.02


def _answer(base: KobukiBase, line: str) -> None:
    if line == "rearm":
        base.rearm(time.monotonic())
        if base.wait_for(lambda b: b.deadman_mode is DeadmanMode.ARMED, 1.0):
            print("rearmed", flush=True)
        else:
            print(f"not rearmed {base.deadman_mode.value}", flush=True)
    elif line == "hold":
        base.hold_stopped(time.monotonic())
        print("held", flush=True)
    elif line == "why":
        print(f"reason {base.deadman_reason}", flush=True)
    elif line == "resume":
        if base.resume(time.monotonic()):
            print("resumed", flush=True)
        else:
            print(f"refused {base.deadman_reason}", flush=True)


def main(port: str, heartbeat_log: str | None, config: ActuationConfig) -> None:
    base = KobukiBase.open(port, config=config, request_versions=False)
    print(f"deadman {base.deadman_pid}", flush=True)
    log_fd = os.open(heartbeat_log, os.O_WRONLY | os.O_CREAT | os.O_APPEND) \
        if heartbeat_log else None
    command = VelocityCommand(0.2, 0.0)
    tick = threading.Event()  # never set: its timed wait paces this pretend control loop
    held: DeadmanMode | None = None  # the dead-man's own stop, once reported
    while True:
        if log_fd is not None:
            os.write(log_fd, f"{time.monotonic()!r}\n".encode())
        try:
            base.send(command, time.monotonic())  # reaches the dead-man even when it holds stop
        except DeadmanTrippedError:
            pass  # tripped or held: reported below, or on purpose
        mode = base.deadman_mode
        if mode in (DeadmanMode.TRIPPED, DeadmanMode.LATCHED) and held is not mode:
            held = mode
            print(f"{mode.value} {base.motion_stopped_s!r} {base.deadman_reason}", flush=True)
        elif mode is DeadmanMode.ARMED:
            held = None
        if select.select([sys.stdin], [], [], 0.0)[0]:
            _answer(base, sys.stdin.readline().strip())
        tick.wait(CONTROL_PERIOD_S)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("port")
    parser.add_argument("heartbeat_log", nargs="?")
    parser.add_argument("--heartbeat-timeout-s", type=float,
                        default=ActuationConfig().heartbeat_timeout_s)
    args = parser.parse_args()
    main(args.port, args.heartbeat_log,
         ActuationConfig(heartbeat_timeout_s=args.heartbeat_timeout_s))
