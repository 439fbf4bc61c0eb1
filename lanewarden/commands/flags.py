"""Command-line number types shared by the commands: finite and bounded, like every config key.

click's FloatRange lets `nan` through (every comparison with it is false) and, without a maximum,
`inf` too; `FiniteRange` refuses both with one line naming the flag and the allowed range.
"""

from __future__ import annotations

import math
from typing import Any

import click


class FiniteRange(click.ParamType):
    """A finite float with low < value <= high (`low_open=False`: low <= value); `unit` is shown
    in the error: "--duration: nan s: expected a finite number with 0 < value <= 86400 s"."""

    name = "float"

    def __init__(self, low: float, high: float, unit: str, *, low_open: bool = False) -> None:
        self.low, self.high, self.unit, self.low_open = low, high, unit, low_open

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> float:
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = math.nan
        above_low = number > self.low if self.low_open else number >= self.low
        if not (math.isfinite(number) and above_low and number <= self.high):
            low = f"{self.low:g} {'<' if self.low_open else '<='} "
            self.fail(f"{str(value)[:60]} {self.unit}: expected a finite number with "
                      f"{low}value <= {self.high:g} {self.unit}", param, ctx)
        return number
