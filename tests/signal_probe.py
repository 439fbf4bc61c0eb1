"""A `Ticker` that raises a real signal in this process at the start of one of its waits and
records whether that wait's `interrupted` saw it at once: the commands' waits must end on a
stop or suspend signal, not at their next tick (a new user's Ctrl-C to `base drive` had let two
more motion packets out)."""

from __future__ import annotations

import os
import signal
from collections.abc import Callable

from lanewarden.ticker import Ticker


def signalling_ticker(sig: signal.Signals, at_wait: int,
                      seen: list[bool | None]) -> type[Ticker]:
    """A Ticker class whose wait number `at_wait` (0-based) first sends `sig` to this process
    (its handler runs before the next line), then appends to `seen` what that wait's
    `interrupted` says (None: the caller gave none)."""

    class SignallingTicker(Ticker):
        waits = 0

        def wait(self, until_s: float | None = None,
                 interrupted: Callable[[], bool] | None = None) -> bool:
            if SignallingTicker.waits == at_wait:
                os.kill(os.getpid(), sig)
                seen.append(None if interrupted is None else interrupted())
            SignallingTicker.waits += 1
            return super().wait(until_s, interrupted)

    return SignallingTicker
