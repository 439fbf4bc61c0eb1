"""`lanewarden detect` (placeholder: owned by the work item that builds it)."""

from __future__ import annotations

import click


def commands() -> list[click.Command]:
    return []
