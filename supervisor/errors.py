"""Supervisor's exception hierarchy."""


class SupervisorError(Exception):
    """The supervisor refuses to run (for example a bad calibration). One-line message."""
