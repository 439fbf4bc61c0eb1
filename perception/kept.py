"""Values derived from frozen config objects, kept per object.

A config's properties cost more than the arithmetic that uses them on every frame (a width
score per candidate pair, a chain rule per followed edge), and the configs are frozen: what is
derived from one never changes. `KeptPerObject` keeps such values by the object's identity (a
config need not be hashable, and hashing a whole config would cost what the cache saves), with
the object itself beside the value, so that a new object that happens to take over a dead
one's id is never answered with the dead one's value. At most KEPT_AT_MOST entries: a program
that builds configs in a loop (a campaign worker, the tests) does not grow it without end.

Pure: the value is a function of the object (and the extra key parts) alone.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

Owner = TypeVar("Owner")
V = TypeVar("V")

#: Entries kept before the cache starts again.
KEPT_AT_MOST = 64


class KeptPerObject(Generic[Owner, V]):
    """`make(owner, *key)`, computed once per `owner` object and extra `key` parts."""

    def __init__(self, make: Callable[..., V]) -> None:
        self._make = make
        self._kept: dict[tuple[Hashable, ...], tuple[Owner, V]] = {}

    def __call__(self, owner: Owner, *key: Hashable) -> V:
        full = (id(owner), *key)
        hit = self._kept.get(full)
        if hit is not None and hit[0] is owner:
            return hit[1]
        value = self._make(owner, *key)
        if len(self._kept) >= KEPT_AT_MOST:
            self._kept.clear()
        self._kept[full] = (owner, value)
        return value
