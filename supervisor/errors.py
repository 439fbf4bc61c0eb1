"""Supervisor's exception hierarchy, and how a caught exception is told in one line."""


class SupervisorError(Exception):
    """The supervisor refuses to run (for example a bad calibration). One-line message."""


def exception_line(exc: BaseException) -> str:
    """`TypeName: message` on one line (whitespace collapsed), for an event's detail."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
