"""Scenarios' exception hierarchy."""


class ScenarioError(Exception):
    """A scenario file or name that cannot be used. One-line message naming the file/key."""


class ScenarioOutputError(ScenarioError):
    """A simulation output (folder, metrics, video) that cannot be written: a runtime failure,
    not a bad scenario."""
