"""The `lanewarden` command: the composition root.

Each command group lives in its own module under `lanewarden.commands`; this module only wires
them together and turns every user-caused error into one line on stderr and the exit code of the
one rule in `lanewarden.errors` (0 ok, 1 runtime failure, 2 bad input or failed gate/check, 3 a
safety stop of `run`, 130 Ctrl-C), with no traceback.
"""

from __future__ import annotations

import contextlib
import errno
import os
import sys
from collections.abc import Sequence

import click
import cv2

from lanewarden import __version__
from lanewarden.commands import register_commands
from lanewarden.commands.command_group import CommandGroup
from lanewarden.errors import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_RUNTIME_FAILURE,
    USER_ERRORS,
    Interrupted,
    exit_code_for,
)


@click.group(cls=CommandGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="lanewarden")
def cli() -> None:
    """Lanewarden: follow a taped lane with a Kobuki and a camera, and stop when unsure."""


register_commands(cli)


def _error(message: str) -> None:
    for line in str(message).splitlines() or [""]:
        click.echo(f"lanewarden: error: {line}", err=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point. Returns the exit code of the one rule (`lanewarden.errors`)."""
    # OpenCV's own warnings (a truncated PNG: "[ WARN:0@2.07] ... PNG input buffer is
    # incomplete") would come before the command's one error line; the command says it itself.
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    try:
        result = cli.main(args=list(argv) if argv is not None else None,
                          prog_name="lanewarden", standalone_mode=False)
    except click.exceptions.Abort:
        _error("interrupted")
        return EXIT_INTERRUPTED
    except click.exceptions.NoArgsIsHelpError as exc:  # bare group: show its help, like --help
        click.echo(exc.ctx.get_help() if exc.ctx else "", err=True)
        return EXIT_BAD_INPUT
    except click.UsageError as exc:
        # "lanewarden sim: ..." names the command; the bare group's own path is the prefix's.
        path = exc.ctx.command_path if exc.ctx is not None else ""
        where = f"{path}: " if path and path != "lanewarden" else ""
        _error(f"{where}{exc.format_message()}")
        return EXIT_BAD_INPUT
    except click.ClickException as exc:
        _error(exc.format_message())
        return exc.exit_code
    except Interrupted as exc:
        _error(f"interrupted: {exc}")
        return EXIT_INTERRUPTED
    except USER_ERRORS as exc:
        _error(str(exc))
        return exit_code_for(exc)
    except KeyboardInterrupt:
        _error("interrupted")
        return EXIT_INTERRUPTED
    except OSError as exc:
        if exc.errno not in _OUTPUT_GONE:
            raise
        return _output_gone(exc)
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        except OSError as exc:  # the last of the output could not be written either
            if exc.errno not in _OUTPUT_GONE:
                raise
            _output_gone(exc)
    return result if isinstance(result, int) else EXIT_OK


#: A write that failed because the output itself is gone or full (`> /dev/full`, a closed pipe,
#: a full or read-only disk, a file-size limit): one line and exit 1, not a traceback.
_OUTPUT_GONE = {errno.ENOSPC, errno.EPIPE, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EFBIG}


def _output_gone(exc: OSError) -> int:
    # stdout cannot take more: point it at /dev/null so the interpreter's own last flush at exit
    # does not print "Exception ignored ..." after the one line
    with contextlib.suppress(OSError, ValueError):
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    with contextlib.suppress(OSError):
        where = f"{exc.filename}: " if exc.filename else ""  # which file, when the error knows
        _error(f"{where}cannot write the output ({exc.strerror or exc})")
    return EXIT_RUNTIME_FAILURE


if __name__ == "__main__":
    raise SystemExit(main())
