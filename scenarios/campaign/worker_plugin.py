"""The campaign's plugin for its local Dask workers (its own module: it subclasses Dask's
WorkerPlugin, and the runner imports Dask only when a campaign starts a cluster)."""

from __future__ import annotations

import threading

from distributed import WorkerPlugin

from lanewarden.stop_signals import leave_interrupts_to_the_parent


class LeaveInterruptsToTheParent(WorkerPlugin):
    """A local worker ignores SIGINT: the campaign, in the same process group, gets the same
    Ctrl-C and shuts the cluster down (without this, each worker printed a traceback)."""

    def setup(self, worker: object) -> None:
        # Signal handlers can only be set from a process's main thread, where a worker process
        # runs its event loop; anywhere else (a worker in threads) there is nothing to set.
        if threading.current_thread() is threading.main_thread():
            leave_interrupts_to_the_parent()
