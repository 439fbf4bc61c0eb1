"""The one validated config: every tunable of every layer, loaded from one YAML file.

Each layer owns its section's model (with every default and units in the names); this module only
assembles them, loads YAML and turns validation errors into one line per bad key.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, ValidationError

from actuation.config import ActuationConfig
from lanewarden.errors import ConfigError
from perception.calibration_config import CalibrationConfig
from perception.config import PerceptionConfig
from scenarios.config import SimulationConfig
from scenarios.yaml_documents import read_yaml_document, validation_error_lines
from supervisor.config import SupervisorConfig


class LanewardenConfig(BaseModel):
    """The whole configuration. `lanewarden config show` prints it as YAML."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    perception: PerceptionConfig = PerceptionConfig()
    calibration: CalibrationConfig = CalibrationConfig()
    supervisor: SupervisorConfig = SupervisorConfig()
    actuation: ActuationConfig = ActuationConfig()
    simulation: SimulationConfig = SimulationConfig()


_UNKNOWN_KEY_HINT = " (check the spelling; `lanewarden config show` lists every key)"


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
        raise ConfigError(validation_error_lines(source, exc, _UNKNOWN_KEY_HINT)) from None


def load_config(path: str | Path | None) -> LanewardenConfig:
    """Load and validate a YAML config file; None gives the defaults."""
    if path is None:
        return LanewardenConfig()
    data = read_yaml_document(path, "config", ConfigError)
    return config_from_mapping(data, str(path))


def config_as_yaml(config: LanewardenConfig) -> str:
    """The effective config as block-style YAML with each key's description as a comment, so the
    output of `lanewarden config show` is a self-documenting file to edit. Loadable again with
    `load_config` (values are written as JSON, which is valid YAML)."""
    lines: list[str] = []

    def emit(model: BaseModel, indent: str) -> None:
        for name, field in type(model).model_fields.items():
            value = getattr(model, name)
            if isinstance(value, BaseModel):
                summary = (type(value).__doc__ or "").strip().split("\n\n")[0]
                comment = f"  # {' '.join(summary.split())}" if summary and indent == "" else ""
                lines.append(f"{indent}{name}:{comment}")
                emit(value, indent + "  ")
                continue
            dumped = json.dumps(model.model_dump(mode="json", include={name})[name])
            comment = f"  # {field.description}" if field.description else ""
            lines.append(f"{indent}{name}: {dumped}{comment}")

    emit(config, "")
    return "\n".join(lines) + "\n"
