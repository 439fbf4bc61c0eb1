"""Command-line types shared by the commands.

click's FloatRange lets `nan` through (every comparison with it is false) and, without a maximum,
`inf` too; `FiniteRange` refuses both with one line naming the flag and the allowed range.
`WholeRange` is click's IntRange in the same words ("--jitter: abc: expected an integer with
0 <= value <= 64", as the config says it of an integer key), where click said "'abc' is not a
valid integer range".

`PathFlag` is every path a command takes (a flag or an argument): an empty one is refused with one
line naming it. `Path("")` is `.`, the current folder, and `value or default` takes `""` for no
value: `--out ""` had written into the current folder (detect, undistort, demo), fallen back to
the default folder (sim, replay, survey; `--check-image` to its default name, replay's
`--calibration` to the recording's), been taken for `.` (`run --record`: "already exists") or
been a traceback (`sim --camera-out`).
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


class WholeRange(click.IntRange):
    """click.IntRange (its help shows the range), refusing a value that is no integer or lies
    outside `low`..`high` in one line: "Invalid value for '--jitter': abc: expected an integer
    with 0 <= value <= 64"."""

    def __init__(self, low: int, high: int) -> None:
        super().__init__(low, high)

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> Any:
        try:
            return super().convert(value, param, ctx)
        except click.BadParameter:
            shown = str(value)[:60] if str(value).strip() else repr(str(value))  # ('' said)
            self.fail(f"{shown}: expected an integer with {self.min} <= value <= "
                      f"{self.max}", param, ctx)


#: What a `--camera` is, for its empty value.
CAMERA_EXPECTED = "a camera index, device, video file, image sequence or stream URL"


class PathFlag(click.Path):
    """click.Path, and an empty value refused: "Invalid value for '--out': '' is empty; expected
    a folder" (`expected`: what the flag names); click's own refusals say it too ("Directory
    'afile' is a file; expected a folder"). `readable=False` for a value that is not always
    a file (a camera index or URL, a glob): then it is checked for nothing else, as a string."""

    def __init__(self, expected: str, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.expected = expected

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> Any:
        if isinstance(value, str) and not value:
            self.fail(f"'' is empty; expected {self.expected}", param, ctx)
        try:
            return super().convert(value, param, ctx)
        except click.BadParameter as exc:  # click's own ("Directory 'x' is a file."): + expected
            self.fail(f"{exc.message.rstrip('.')}; expected {self.expected}", param, ctx)
