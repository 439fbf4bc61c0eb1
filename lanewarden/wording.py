"""Small wording helpers shared by the tool's messages and reports."""

from __future__ import annotations


def counted(count: int, noun: str) -> str:
    """'1 frame', '3 frames', '1 unsafe run' (`noun` singular, its last word gets the s)."""
    return f"{count} {noun}{'' if count == 1 else 's'}"
