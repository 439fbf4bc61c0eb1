"""The one validated config: every tunable of every layer, loaded from one YAML file.

Each layer owns its section's model (with every default and units in the names); this module only
assembles them, loads YAML and turns validation errors into one line per bad key.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from actuation.config import ActuationConfig
from lanewarden.errors import ConfigError
from perception.calibration_config import CalibrationConfig
from perception.config import PerceptionConfig
from scenarios.config import SimulationConfig
from supervisor.config import SupervisorConfig


class LanewardenConfig(BaseModel):
    """The whole configuration. `lanewarden config show` prints it as YAML."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    perception: PerceptionConfig = PerceptionConfig()
    calibration: CalibrationConfig = CalibrationConfig()
    supervisor: SupervisorConfig = SupervisorConfig()
    actuation: ActuationConfig = ActuationConfig()
    simulation: SimulationConfig = SimulationConfig()


def _describe_error(source: str, err: Any) -> str:
    key = ".".join(str(part) for part in err["loc"]) or "(top level)"
    if err["type"] == "extra_forbidden":
        return (
            f"{source}: unknown key '{key}' "
            "(check the spelling; `lanewarden config show` lists every key)"
        )
    value = err.get("input")
    shown = repr(value) if not isinstance(value, dict) else "a mapping"
    return f"{source}: {key} = {shown}: {err['msg'].lower()}"


def config_from_mapping(data: Any, source: str = "config") -> LanewardenConfig:
    """Validate a parsed mapping; every problem becomes one line of the raised ConfigError."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(
            f"{source}: expected a YAML mapping of sections at the top level, "
            f"got {type(data).__name__}"
        )
    try:
        return LanewardenConfig.model_validate(data)
    except ValidationError as exc:
        lines = [_describe_error(source, err) for err in exc.errors()]
        raise ConfigError("\n".join(lines)) from None


def load_config(path: str | Path | None) -> LanewardenConfig:
    """Load and validate a YAML config file; None gives the defaults."""
    if path is None:
        return LanewardenConfig()
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: config file not found") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: is a directory, expected a YAML config file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read config file ({exc})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise ConfigError(f"{path}: not valid YAML{where}: {problem}") from None
    return config_from_mapping(data, str(path))


def config_as_yaml(config: LanewardenConfig) -> str:
    """The effective config as YAML, loadable again with `load_config`."""
    return yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False, default_flow_style=None)
