"""Reading a validated YAML document (a config file, a scenario file) with one-line errors.

Shared by the scenario library and the CLI's config loader: the file is read, parsed and its
pydantic validation errors turned into one line each, naming the file, the dotted key, the bad
value and what was expected. Raises the caller's own exception type, so each layer keeps its own
error hierarchy. Never prints.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError


def describe_validation_error(source: str, err: Any, unknown_key_hint: str = "") -> str:
    """One line for one pydantic error: `source: key = value: what was expected`."""
    key = ".".join(str(part) for part in err["loc"]) or "(top level)"
    if err["type"] == "extra_forbidden":
        return f"{source}: unknown key '{key}'{unknown_key_hint}"
    value = err.get("input")
    shown = "a mapping" if isinstance(value, dict) else repr(value)
    message = str(err["msg"])
    if message.startswith("Value error, "):
        message = message[len("Value error, "):]
    return f"{source}: {key} = {shown}: {message[:1].lower()}{message[1:]}"


def validation_error_lines(
    source: str, exc: ValidationError, unknown_key_hint: str = ""
) -> str:
    """Every problem of `exc`, one line each."""
    return "\n".join(
        describe_validation_error(source, err, unknown_key_hint) for err in exc.errors()
    )


def read_yaml_document(path: str | Path, what: str, error: type[Exception]) -> Any:
    """Read and parse one YAML file; `error(...)` (one line naming the file) when it can't be."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error(f"{path}: {what} file not found") from None
    except IsADirectoryError:
        raise error(f"{path}: is a directory, expected a {what} YAML file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{path}: cannot read {what} file ({exc})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise error(f"{path}: not valid YAML{where}: {problem}") from None
