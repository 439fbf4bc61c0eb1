"""Small wording helpers shared by the tool's messages and reports."""

from __future__ import annotations


def counted(count: int, noun: str) -> str:
    """'1 frame', '3 frames', '1 unsafe run' (`noun` singular, its last word gets the s)."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def first_few(names: list[str], shown: int = 3) -> str:
    """'a, b, c' or 'a, b, c, ...': the first `shown` names, and whether there are more."""
    return ", ".join(names[:shown]) + (", ..." if len(names) > shown else "")
