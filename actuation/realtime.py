"""Raising a thread's scheduling priority where the OS permits, for the threads that must stop
the robot on time: the dead-man process, and the control process's watch on it.

Linux applies a scheduling policy or nice value to the calling thread only; threads it starts
later inherit it. Both threads that get it block in select/read almost all the time, so a
real-time priority costs the machine nothing, but a loaded machine can no longer delay them.
"""

from __future__ import annotations

import os

#: SCHED_FIFO priority (1..99): above every ordinary process, below the kernel's own real-time
#: threads.
REALTIME_PRIORITY = 10
#: The nice value tried when SCHED_FIFO is refused.
NICE_VALUE = -10


def raise_priority() -> tuple[bool, str]:
    """Raise the calling thread's priority: SCHED_FIFO where permitted (root or CAP_SYS_NICE),
    else nice -10. Returns (raised, one-line description, or why neither was allowed)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(REALTIME_PRIORITY))
        return True, f"SCHED_FIFO {REALTIME_PRIORITY}"
    except (OSError, AttributeError) as fifo_exc:
        try:
            os.setpriority(os.PRIO_PROCESS, 0, NICE_VALUE)
            return True, f"nice {NICE_VALUE} (SCHED_FIFO refused: {fifo_exc})"
        except (OSError, AttributeError) as nice_exc:
            return False, (f"normal priority: could not raise it (SCHED_FIFO: {fifo_exc}; "
                           f"nice {NICE_VALUE}: {nice_exc})")
