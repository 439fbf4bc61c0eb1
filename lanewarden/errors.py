"""The errors the CLI turns into one line on stderr and an exit code (no traceback), and the one
exit-code rule every `lanewarden` command follows (README, "Exit codes"):

- 0: the command did its job (`run`: a normal end: operator stop, `--duration`, end of a clip);
- 1: a runtime failure outside the user's input: robot/port or camera missing or lost, dead-man
  failure, an output that cannot be written;
- 2: bad input: a flag value, a config/scenario/calibration file or an input file that cannot be
  used as given (missing, unreadable, not an image, too large); a failed quality gate or check;
- 3: `run` (and `replay`) ended by a safety stop; `survey`: NOT SAFE (a decision on a no-lane
  frame); `compare --fail-if-worse`: a run became unsafe or a false halt;
- 130: interrupted by Ctrl-C (commands other than `run`).

Errors are classified by type (`EXIT_CODE_BY_ERROR`, first match wins), so a layer's own error
means the same exit code in every command.
"""

from __future__ import annotations

from lanewarden.actuation.errors import ActuationError
from lanewarden.perception.errors import PerceptionError
from lanewarden.scenarios.errors import ScenarioError, ScenarioOutputError
from lanewarden.supervisor.errors import SupervisorError

EXIT_OK = 0
EXIT_RUNTIME_FAILURE = 1
EXIT_BAD_INPUT = 2
EXIT_SAFETY_STOP = 3
EXIT_INTERRUPTED = 130


class ConfigError(Exception):
    """A config file that is missing, unparsable or invalid. One line per problem."""


class UsageError(Exception):
    """A command-line value that cannot be used (exit code 2)."""


class InputFileError(Exception):
    """An input file (image, calibration) that is missing, unreadable, not what was expected or
    too large (exit code 2)."""


class QualityGateError(Exception):
    """A result that was computed but fails a quality gate (exit code 2), e.g. a bad calibration."""


class OutputError(Exception):
    """An output file that cannot be written (exit code 1: the input was fine)."""


class Interrupted(Exception):
    """Ctrl-C during a command that has something to say about it, e.g. which outputs are
    partial (exit code 130). The message follows "interrupted: "."""


class DeviceError(Exception):
    """A device (camera) that cannot be opened or delivers nothing (exit code 1)."""


#: The exit code of every error a user can meet; the first row whose type matches decides.
EXIT_CODE_BY_ERROR: tuple[tuple[type[Exception], int], ...] = (
    (Interrupted, EXIT_INTERRUPTED),
    (ConfigError, EXIT_BAD_INPUT),
    (UsageError, EXIT_BAD_INPUT),
    (InputFileError, EXIT_BAD_INPUT),
    (QualityGateError, EXIT_BAD_INPUT),
    (ScenarioOutputError, EXIT_RUNTIME_FAILURE),  # before ScenarioError: it is one
    (ScenarioError, EXIT_BAD_INPUT),  # a scenario file, name or world that cannot be used
    (PerceptionError, EXIT_BAD_INPUT),  # an image, frame or calibration perception cannot use
    (OutputError, EXIT_RUNTIME_FAILURE),
    (DeviceError, EXIT_RUNTIME_FAILURE),
    (ActuationError, EXIT_RUNTIME_FAILURE),  # the base or its port missing, silent or lost
    (SupervisorError, EXIT_RUNTIME_FAILURE),  # the run cannot go on (no frames, log not writable)
)

#: Every error a user can cause; the CLI prints these as one line and exits non-zero.
USER_ERRORS: tuple[type[Exception], ...] = tuple(kind for kind, _ in EXIT_CODE_BY_ERROR)


def exit_code_for(error: Exception) -> int:
    """The exit code of a user-facing error (`EXIT_CODE_BY_ERROR`); 1 for anything else."""
    for kind, code in EXIT_CODE_BY_ERROR:
        if isinstance(error, kind):
            return code
    return EXIT_RUNTIME_FAILURE
