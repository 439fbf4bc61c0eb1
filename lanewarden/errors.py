"""The errors the CLI turns into one line on stderr and a non-zero exit (no traceback)."""

from __future__ import annotations

from lanewarden.actuation.errors import ActuationError
from lanewarden.perception.errors import PerceptionError
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.supervisor.errors import SupervisorError


class ConfigError(Exception):
    """A config file that is missing, unparsable or invalid. One line per problem."""


class UsageError(Exception):
    """A command-line value that cannot be used (exit code 2)."""


class OutputError(Exception):
    """An output that cannot be written (a folder that cannot be created, a full disk): exit 1."""


class QualityGateError(Exception):
    """A result that was computed but fails a quality gate (exit code 2), e.g. a bad calibration."""


#: Every error a user can cause; the CLI prints these as one line and exits non-zero.
USER_ERRORS: tuple[type[Exception], ...] = (
    ActuationError,
    ConfigError,
    OutputError,
    PerceptionError,
    QualityGateError,
    ScenarioError,
    SupervisorError,
    UsageError,
)
