"""Choosing the base `lanewarden run` drives: `--base kobuki|sim|none`.

- `kobuki`: the real robot through its dead-man process (`KobukiBase.open`).
- `sim`: a `SimBase` driven in real time by the very commands that would go to the wheels (to
  bench-test a clip or the live camera through the whole loop; the distance is the simulated one).
- `none`: a `NullBase`: nothing is sent anywhere; the status shows what would have been sent.

The simulated bases are wrapped in `SerializedBase`: the runner's operator stop may call `send` from
another thread than the one that steps, and a `SimBase` refuses time going backwards, which two
threads reading the monotonic clock a moment apart could otherwise produce.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from lanewarden.actuation.base import Base, BaseFeedback, VelocityCommand
from lanewarden.actuation.config import ActuationConfig
from lanewarden.actuation.null_base import NullBase
from lanewarden.actuation.sim_base import SimBase, SimBaseParams

BASE_KINDS = ("kobuki", "sim", "none")
DEFAULT_BASE = "kobuki"


class SerializedBase:
    """A base behind a lock, with `now` never going backwards (the latest `now` seen is used when
    a call arrives with an earlier one from another thread)."""

    def __init__(self, inner: Base) -> None:
        self.inner = inner
        self._lock = threading.Lock()
        self._latest: float | None = None

    def _monotone(self, now: float) -> float:
        if self._latest is not None and now < self._latest:
            return self._latest
        self._latest = now
        return now

    def send(self, command: VelocityCommand, now: float) -> None:
        with self._lock:
            self.inner.send(command, self._monotone(now))

    def feedback(self, now: float) -> BaseFeedback:
        with self._lock:
            return self.inner.feedback(self._monotone(now))

    def close(self) -> None:
        with self._lock:
            self.inner.close()


@contextmanager
def open_base(kind: str, *, port: str | None, config: ActuationConfig,
              clock: Callable[[], float]) -> Iterator[Base]:
    """The chosen base, closed (stopped) on the way out whatever happens."""
    base: Base
    if kind == "kobuki":
        from lanewarden.actuation.kobuki_base import KobukiBase

        base = KobukiBase.open(port, clock=clock, config=config)
    elif kind == "sim":
        base = SerializedBase(SimBase(params=SimBaseParams.from_config(config)))
    elif kind == "none":
        base = SerializedBase(NullBase())
    else:  # click's Choice keeps other values out; this is for callers in code
        raise ValueError(f"--base: unknown base {kind!r}, expected one of: {', '.join(BASE_KINDS)}")
    try:
        yield base
    finally:
        base.close()
