"""Choosing a controller by name (`--controller supervised|lecture` wherever one can be chosen)."""

from __future__ import annotations

from collections.abc import Callable
from types import MappingProxyType

from supervisor.config import SupervisorConfig
from supervisor.control_io import Controller
from supervisor.controller import SupervisedController
from supervisor.errors import SupervisorError
from supervisor.lecture import LectureController

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
