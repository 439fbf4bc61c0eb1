"""Choosing a controller by name (`--controller supervised|lecture` wherever one can be chosen)."""

from __future__ import annotations

from collections.abc import Callable
from types import MappingProxyType

from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.control_io import Controller
from lanewarden.supervisor.controller import SupervisedController
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.lecture import LectureController

CONTROLLERS: MappingProxyType[str, Callable[[SupervisorConfig], Controller]] = MappingProxyType(
    {"supervised": SupervisedController, "lecture": LectureController}
)
DEFAULT_CONTROLLER = "supervised"


def make_controller(name: str, config: SupervisorConfig) -> Controller:
    """A fresh controller for one run; SupervisorError (one line) for an unknown name."""
    try:
        factory = CONTROLLERS[name]
    except KeyError:
        choices = ", ".join(CONTROLLERS)
        raise SupervisorError(
            f"--controller: unknown controller {name!r}, expected one of: {choices}"
        ) from None
    return factory(config)
