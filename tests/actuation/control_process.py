"""A pretend control process for the dead-man end-to-end tests and benchmark (TEST code).

`python tests/actuation/control_process.py PORT [HEARTBEAT_LOG]`: opens KobukiBase on PORT,
prints `deadman <pid>`, then sends 0.2 m/s every 20 ms (its control tick) forever, appending to
HEARTBEAT_LOG, if given, the monotonic time taken just before each send. Prints `tripped
STOPPED_S REASON` (when the dead-man wrote the stop, and its reason, with the stamp of the last
heartbeat it accepted) when send() says the dead-man tripped (it keeps sending: the dead-man
must ignore that stream), and re-arms (printing `rearmed`) when a `rearm` line arrives on stdin.
"""

from __future__ import annotations

import os
import select
import sys
import threading
import time

from lanewarden.actuation.base import VelocityCommand
from lanewarden.actuation.deadman_logic import DeadmanMode
from lanewarden.actuation.errors import DeadmanTrippedError
from lanewarden.actuation.kobuki_base import KobukiBase

CONTROL_PERIOD_S = 0.02


def main(port: str, heartbeat_log: str | None) -> None:
    base = KobukiBase.open(port, request_versions=False)
    print(f"deadman {base.deadman_pid}", flush=True)
    log_fd = os.open(heartbeat_log, os.O_WRONLY | os.O_CREAT | os.O_APPEND) \
        if heartbeat_log else None
    command = VelocityCommand(0.2, 0.0)
    tick = threading.Event()  # never set: its timed wait paces this pretend control loop
    tripped = False
    while True:
        if log_fd is not None:
            os.write(log_fd, f"{time.monotonic()!r}\n".encode())
        try:
            base.send(command, time.monotonic())  # reaches the dead-man even when tripped
        except DeadmanTrippedError:
            if not tripped:
                tripped = True
                print(f"tripped {base.motion_stopped_s!r} {base.deadman_reason}", flush=True)
        if tripped and select.select([sys.stdin], [], [], 0.0)[0]:
            if sys.stdin.readline().strip() == "rearm":
                base.rearm(time.monotonic())
                base.wait_for(lambda b: b.deadman_mode is DeadmanMode.ARMED, 5.0)
                tripped = False
                print("rearmed", flush=True)
        tick.wait(CONTROL_PERIOD_S)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else None)
