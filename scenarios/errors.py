"""Scenarios' exception hierarchy."""


class ScenarioError(Exception):
    """A scenario file or name that cannot be used. One-line message naming the file/key."""
