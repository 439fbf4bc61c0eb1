"""Small wording helpers shared by the tool's messages and reports."""

from __future__ import annotations


def counted(count: int, noun: str) -> str:
    """'1 frame', '3 frames', '1 unsafe run' (`noun` singular, its last word gets the s)."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def first_few(names: list[str], shown: int = 3) -> str:
    """'a, b, c' or 'a, b, c, ...': the first `shown` names, and whether there are more."""
    return ", ".join(names[:shown]) + (", ..." if len(names) > shown else "")


def shown_name(name: str) -> str:
    """`name` with each character a terminal acts on (a newline, ESC, a tab) written as its
    escape ('\\n', '\\x1b'): a file, or a labels file's text, is named in one line of text,
    whatever it holds (a file name with a newline had split the NOT SAFE line in two; a labels
    file's OSC sequence had set the terminal's title)."""
    if name.isprintable():
        return name
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii")
                   for c in name)
