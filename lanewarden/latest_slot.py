"""A latest-only slot between the control thread and a slower consumer (live page, terminal).

`put` never blocks and never queues: it replaces what is there (counting what was replaced unseen
as dropped), so a consumer that falls behind costs dropped view updates, never loop time.
"""

from __future__ import annotations

import threading
from typing import Generic, TypeVar

T = TypeVar("T")


class LatestSlot(Generic[T]):
    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._item: T | None = None
        self._version = 0
        self._taken_version = 0
        self._closed = False
        self.dropped = 0

    def put(self, item: T) -> None:
        with self._cond:
            if self._version != self._taken_version:
                self.dropped += 1
            self._item = item
            self._version += 1
            self._cond.notify_all()

    def take(self, timeout_s: float | None = None) -> T | None:
        """The newest item not taken yet, waiting up to `timeout_s` for one; None when there is
        none (or the slot was closed)."""
        with self._cond:
            self._cond.wait_for(lambda: self._closed or self._version != self._taken_version,
                                timeout_s)
            if self._version == self._taken_version:
                return None
            self._taken_version = self._version
            return self._item

    def peek(self) -> T | None:
        """The newest item, taken or not (does not mark it taken)."""
        with self._cond:
            return self._item

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        with self._cond:
            return self._closed
