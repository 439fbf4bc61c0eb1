"""Actuation: the Kobuki serial protocol, the real base driver and a simulated base.

Knows bytes and wheels, never images: nothing here imports `perception` or `scenarios`.
Every base stops on close, and the default command is stop.
"""

from lanewarden.actuation.base import Base, BaseFeedback, Pose2D, VelocityCommand
from lanewarden.actuation.errors import ActuationError

__all__ = ["ActuationError", "Base", "BaseFeedback", "Pose2D", "VelocityCommand"]
