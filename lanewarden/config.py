"""The one validated config: every tunable of every layer, loaded from one YAML file.

Each layer owns its section's model (with every default and units in the names); this module only
assembles them, loads YAML and turns validation errors into one line per bad key.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

from pydantic import BaseModel, ConfigDict, ValidationError, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from lanewarden.actuation.config import ActuationConfig
from lanewarden.documents import (
    CONFIG_SECTIONS,
    DocumentModel,
    allowed_range,
    config_given_as,
    read_yaml_document,
    validation_error_lines,
    wrong_document,
)
from lanewarden.errors import ConfigError
from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.config import PerceptionConfig
from lanewarden.scenarios.campaign.config import CampaignConfig
from lanewarden.scenarios.config import SimulationConfig
from lanewarden.supervisor.config import SupervisorConfig


class LanewardenConfig(DocumentModel):
    """The whole configuration. `lanewarden config show` prints it as YAML."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    perception: PerceptionConfig = PerceptionConfig()
    calibration: CalibrationConfig = CalibrationConfig()
    supervisor: SupervisorConfig = SupervisorConfig()
    actuation: ActuationConfig = ActuationConfig()
    simulation: SimulationConfig = SimulationConfig()
    campaign: CampaignConfig = CampaignConfig()

    @model_validator(mode="after")
    def _sections_agree(self) -> Self:
        """A quantity that two sections both need lives in one of them, or is checked here: each
        conflict is one error, located at one key and naming the other."""
        sup, act = self.supervisor, self.actuation
        conflicts: list[tuple[tuple[str, ...], object, str]] = []
        for sup_key, act_key, unit, what in (
            ("limiter_max_linear_m_s", "max_linear_m_s", "m/s", "the base's own limit"),
            ("limiter_max_angular_rad_s", "max_angular_rad_s", "rad/s", "the base's own limit"),
            ("max_linear_accel_m_s2", "max_linear_accel_m_s2", "m/s^2", "the dead-man's envelope"),
            ("max_angular_accel_rad_s2", "max_angular_accel_rad_s2", "rad/s^2",
             "the dead-man's envelope"),
        ):
            value, limit = getattr(sup, sup_key), getattr(act, act_key)
            if value > limit:
                conflicts.append((("supervisor", sup_key), value,
                                  f"must not exceed actuation.{act_key} ({limit:g} {unit}), "
                                  f"{what}"))  # fmt: skip
        rate_hz = self.simulation.camera_rate_hz
        if not math.isclose(sup.camera_period_s * rate_hz, 1.0, rel_tol=1e-3):
            conflicts.append((("supervisor", "camera_period_s"), sup.camera_period_s,
                              f"must be 1 / simulation.camera_rate_hz ({rate_hz:g} Hz, "
                              f"{1.0 / rate_hz:.6g} s): the simulated camera is the "
                              "robot's"))  # fmt: skip
        free, clearance = self.perception.free_width_m, sup.lane_departure_clearance_m
        if free < 2.0 * clearance:
            conflicts.append((("perception", "lane", "width_m"), self.perception.lane.width_m,
                              f"leaves {free:.3g} m between the tapes' inner edges, less than "
                              f"twice supervisor.lane_departure_clearance_m ({clearance:g} m: "
                              "the robot's half-width and a margin): centred in this lane the "
                              "robot would already be leaving it, and every frame would halt "
                              "it; expected the lane's true width (a Kobuki needs its tapes' "
                              "inner edges 0.39 m apart or more), or a smaller clearance for a "
                              "narrower robot"))  # fmt: skip
        clamp = self.perception.edges.max_abs_slope
        if 2.0 * clamp <= sup.turn_enter_slope_sum:
            conflicts.append((("supervisor", "turn_enter_slope_sum"), sup.turn_enter_slope_sum,
                              f"must be below twice perception.edges.max_abs_slope ({clamp:g}): "
                              "two clamped slopes could never reach it"))  # fmt: skip
        if conflicts:
            raise ValidationError.from_exception_data(type(self).__name__, [
                InitErrorDetails(type=PydanticCustomError("sections_disagree", message),
                                 loc=loc, input=value)
                for loc, value, message in conflicts
            ])  # fmt: skip
        return self


_UNKNOWN_KEY_HINT = " (check the spelling; `lanewarden config show` lists every key)"


def lane_margin_m(config: LanewardenConfig) -> float:
    """How far the robot, centred in the lane, may drift before the lane-departure rule halts
    it: half the floor between the tapes' inner edges less `lane_departure_clearance_m`."""
    return (0.5 * config.perception.free_width_m
            - config.supervisor.lane_departure_clearance_m)


def narrow_lane_warning(config: LanewardenConfig) -> str | None:
    """A lane the robot fits in (narrower is refused) but with less room to drift than the
    defaults' lane leaves (81 mm: a 0.6 m lane of 48 mm tapes, what the scenarios and the
    campaigns drive): said where the robot is about to drive (`run`, `sim`), since in bends it
    halts on LANE_DEPARTURE while on course (a new user's 0.5 m lane of 19 mm tape, the README's
    own example then, halted in a 2 m-radius bend 23 mm off the lane's centre). None otherwise."""
    margin = lane_margin_m(config)
    usual = lane_margin_m(LanewardenConfig())
    if margin >= usual - 1e-9:
        return None
    return (f"perception.lane.width_m {config.perception.lane.width_m:g} leaves the robot "
            f"{1000 * margin:.0f} mm to drift either way before the lane-departure rule halts "
            f"it (half the {config.perception.free_width_m:.3g} m between the tapes' inner "
            f"edges, less supervisor.lane_departure_clearance_m "
            f"{config.supervisor.lane_departure_clearance_m:g}); in bends, where the robot runs "
            "a few centimetres off the lane's centre and an edge read ahead of it errs by a few "
            f"more, expect LANE_DEPARTURE halts on course: the defaults leave "
            f"{1000 * usual:.0f} mm (a 0.6 m lane of 48 mm tape)")


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
        raise ConfigError(
            validation_error_lines(source, exc, LanewardenConfig, _UNKNOWN_KEY_HINT)
        ) from None


def load_config(path: str | Path | None) -> LanewardenConfig:
    """Load and validate a YAML config file; None gives the defaults."""
    if path is None:
        return LanewardenConfig()
    data = read_yaml_document(path, "config", ConfigError)
    if other := another_document(data):
        raise ConfigError(f"{path}: {other}")
    return config_from_mapping(data, str(path))


def misplaced_document(data: Any, read_as: str, own_keys: Iterable[str]) -> str:
    """Is a document read as a `read_as` (a scenario, a campaign spec, a campaign case; the keys
    it may have: `own_keys`) another lanewarden file: a config (`documents.config_given_as`) or
    one of the others (`another_document`)? The one line saying which and where it goes, or
    ''."""
    return config_given_as(data, own_keys, read_as) or another_document(data, read_as)


def another_document(data: Any, read_as: str = "config") -> str:
    """Is a document read as a `read_as` (a config, a scenario, a campaign spec or a campaign
    case) one of the others but a config? Yes when it has every key such a file must have and no
    config section of its own: `wrong_document`'s line, without the file's name (the config's
    validation had said 'unknown key' of each of its keys, a campaign spec's ten and more; a
    spec read as a scenario gave eleven lines). '' otherwise. (A config read as one of the
    others: `documents.config_given_as`.)"""
    if not isinstance(data, dict) or (
            read_as == "config" and all(key in CONFIG_SECTIONS for key in data)):
        return ""  # a config (or not a mapping, as config_from_mapping says)
    # imported here: the campaign's modules import this one where they validate a config
    from lanewarden.scenarios.campaign.cases import CampaignSpec, Case
    from lanewarden.scenarios.spec import ScenarioSpec

    for what, flag, model in (("scenario", "sim --scenario", ScenarioSpec),
                              ("campaign spec", "campaign --spec", CampaignSpec),
                              ("campaign case", "sim --case", Case)):
        if what == read_as:
            continue
        fields = model.model_fields
        required = [name for name, field in fields.items() if field.is_required()]
        sections = {key for key in data if key in CONFIG_SECTIONS} - set(fields)
        if all(name in data for name in required) and not sections:
            signs = [name for name in required if name not in CONFIG_SECTIONS][:2]
            return wrong_document(f"a {what}", signs, read_as, flag)
    return ""


@dataclass(frozen=True)
class ConfigNode:
    """One node of the config tree: a section (`is_section`) or a key with its JSON-ready value.
    `description` is the key's Field description, or a section's one-paragraph summary;
    `allowed` a numeric key's allowed range (e.g. '0 < value <= 5'), else ''."""

    path: tuple[str, ...]
    value: object
    description: str
    is_section: bool
    allowed: str = ""


def _summary(model: BaseModel) -> str:
    first_paragraph = (type(model).__doc__ or "").strip().split("\n\n")[0]
    return " ".join(first_paragraph.split())


def walk_config(model: BaseModel, path: tuple[str, ...] = ()) -> Iterator[ConfigNode]:
    """Every section and key in declaration order, each section before its keys. The one walk
    behind `config show` and the generated reference (docs/configuration.md)."""
    for name, field in type(model).model_fields.items():
        value = getattr(model, name)
        here = (*path, name)
        if isinstance(value, BaseModel):
            yield ConfigNode(here, None, _summary(value), True)
            yield from walk_config(value, here)
        else:
            dumped = model.model_dump(mode="json", include={name})[name]
            yield ConfigNode(here, dumped, (field.description or "").strip(), False,
                             allowed_range(field))


def config_as_yaml(config: LanewardenConfig) -> str:
    """The effective config as block-style YAML with each key's description as a comment, so the
    output of `lanewarden config show` is a self-documenting file to edit. Loadable again with
    `load_config` (values are written as JSON, which is valid YAML)."""
    lines: list[str] = []
    for node in walk_config(config):
        indent = "  " * (len(node.path) - 1)
        name = node.path[-1]
        if node.is_section:
            top_level_summary = node.description and len(node.path) == 1
            lines.append(f"{indent}{name}:" + (f"  # {node.description}" if top_level_summary
                                                else ""))
        else:
            comment = f"  # {node.description}" if node.description else ""
            lines.append(f"{indent}{name}: {json.dumps(node.value)}{comment}")
    return "\n".join(lines) + "\n"
