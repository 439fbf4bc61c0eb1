"""The `--pattern COLSxROWS` option type shared by the calibrate subcommands."""

from __future__ import annotations

from typing import Any

import click

from lanewarden.perception.chessboard import ChessboardPattern, parse_pattern
from lanewarden.perception.errors import PerceptionError


class PatternType(click.ParamType):
    """COLSxROWS inner corners, e.g. 9x6."""

    name = "COLSxROWS"

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> ChessboardPattern:
        if isinstance(value, ChessboardPattern):
            return value
        try:
            return parse_pattern(str(value))
        except PerceptionError as exc:
            self.fail(str(exc), param, ctx)


PATTERN = PatternType()
