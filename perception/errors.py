"""Perception's exception hierarchy: library errors are translated into these at the boundary."""


class PerceptionError(Exception):
    """A frame, image file or calibration file perception cannot use. The message is one line."""
