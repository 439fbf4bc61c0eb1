"""Scenarios' exception hierarchy."""


class ScenarioError(Exception):
    """A scenario file or name that cannot be used. One-line message naming the file/key."""


class ScenarioOutputError(ScenarioError):
    """A runtime failure, not a bad scenario (exit code 1): a simulation or campaign output
    (folder, metrics, video, report) that cannot be written, a scheduler that cannot be
    reached."""
