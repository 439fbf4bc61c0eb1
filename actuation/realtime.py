"""Raising a thread's scheduling priority where the OS permits, for the threads that must stop
the robot on time: the dead-man process, and the control process's watch on it; and sparing the
dead-man from the kernel's out-of-memory killer where the OS permits (`spare_from_oom`).

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


#: /proc/self/oom_score_adj's lowest value: the out-of-memory killer never picks the process.
OOM_NEVER = -1000


def spare_from_oom(path: str = "/proc/self/oom_score_adj") -> tuple[bool, str]:
    """Ask the kernel's out-of-memory killer never to pick this process (`OOM_NEVER`): the
    dead-man, so that running out of memory kills the control process, whose death it answers
    with a stop, rather than itself or both (an attacker's review: both killed at once, the
    base drives its last command). Permitted to root (CAP_SYS_RESOURCE) only; elsewhere the
    kernel picks by size, and the control process, far the larger, goes first. A cgroup killed
    whole (`memory.oom.group`, `docker kill`) takes both whatever this says (docs/actuation.md).
    Returns (spared, one-line description)."""
    try:
        with open(path, "w", encoding="ascii") as adjust:
            adjust.write(str(OOM_NEVER))
        return True, f"oom_score_adj {OOM_NEVER}"
    except OSError as exc:
        return False, f"oom_score_adj unchanged ({exc.strerror or exc})"
