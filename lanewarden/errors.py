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


class QualityGateError(Exception):
    """A result that was computed but fails a quality gate (exit code 2), e.g. a bad calibration."""


#: Every error a user can cause; the CLI prints these as one line and exits non-zero.
USER_ERRORS: tuple[type[Exception], ...] = (
    ActuationError,
    ConfigError,
    PerceptionError,
    QualityGateError,
    ScenarioError,
    SupervisorError,
    UsageError,
)
