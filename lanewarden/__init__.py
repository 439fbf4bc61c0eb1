"""Lanewarden's composition root: the CLI, the one config, and the robot runner.

This is the only package that imports perception, supervisor, actuation and scenarios together.
"""

__version__ = "0.1.0"
