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
    """The effective config as YAML, loadable again with `load_config`."""
    return yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False, default_flow_style=None)
