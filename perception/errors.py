"""Perception's exception hierarchy: library errors are translated into these at the boundary."""


class PerceptionError(Exception):
    """A frame, image file or calibration file perception cannot use. The message is one line."""


class PerceptionConfigError(PerceptionError):
    """A perception config this camera cannot work with (found when the detector is set up for
    an image size, before any frame is used): the floor region is out of view, or the camera
    cannot tell the tape from a seam at the look-ahead distance. `suggested_look_ahead_m` is the
    farthest look-ahead that would work, when there is one."""

    def __init__(self, message: str, suggested_look_ahead_m: float | None = None) -> None:
        super().__init__(message)
        self.suggested_look_ahead_m = suggested_look_ahead_m
