"""A campaign spec (what to draw from) and the cases drawn from it (what one run is, exactly).

A spec names scenarios, cameras, floor seeds and fault kinds with parameter RANGES; `draw_case`
turns (spec, campaign seed, run index) into one `Case`: a complete, self-contained run (the
scenario with its drawn faults, the controller, the seed, the config overrides). A case file
(`DIR/cases/<id>.yaml`) is all `lanewarden sim --case` needs to reproduce that run exactly.

A case depends only on (spec, seed, index), never on how many runs were asked for, so a campaign
can be extended or resumed. A parameter range in a spec is one of: a fixed value, `[low, high]`
(uniform; integers when both are integers), or `{one_of: [a, b, ...]}`.

Pure data and seeded draws: never runs a simulation, never reads a clock.
"""

from __future__ import annotations

import difflib
import hashlib
import itertools
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar, get_args

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from lanewarden.documents import (
    DocumentModel,
    read_yaml_document,
    shown_value,
    validation_error_lines,
)
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.library import (
    library_names,
    resolve_scenario,
    unknown_scenario,
    written_as_path,
)
from lanewarden.scenarios.spec import (
    FLOOR_FAULT_KINDS,
    FaultKind,
    FaultSpec,
    ScenarioSpec,
    merge_overrides,
    parse_scenario,
)
from lanewarden.scenarios.world import build_world

ModelT = TypeVar("ModelT", bound=BaseModel)

DEFAULT_SPEC = "default"
#: Floor faults are placed at least this far along the lane (the robot has engaged by then).
FLOOR_FAULT_MIN_M = 0.8
#: ... and where the robot can get to: this fraction of the distance it could drive.
REACH_FRACTION = 0.7
#: Seconds of a run before the robot is moving at speed (start, engage, ramp).
START_UP_S = 2.0


class _Model(DocumentModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


#: A drawn choice's name (in the results and the report) and its relative frequency.
ChoiceName = Annotated[str, Field(min_length=1, max_length=40, pattern=r"^[A-Za-z0-9_.-]+$")]
Weight = Annotated[float, Field(gt=0.0, le=1000.0)]


class CameraChoice(_Model):
    """One camera a campaign draws from: its name in the results, its relative frequency, the
    render size, any other `simulation:` settings that go with it (e.g. a coarser floor texture
    for a small image), the scenario `camera:` block (pose, field of view, distortion) and
    `config:` overrides a user of this camera sets (e.g. the look-ahead its start-up check
    names: perception refuses a camera that cannot tell tape from seam at the look-ahead)."""

    name: ChoiceName
    weight: Weight = 1.0
    width_px: Annotated[int, Field(ge=64, le=1920)] = 320
    height_px: Annotated[int, Field(ge=48, le=1440)] = 240
    simulation: dict[str, Any] = {}
    #: the scenario's `camera:` block for this camera (its pose, field of view, distortion)
    camera: dict[str, Any] = {}
    #: config overrides that go with this camera (config file shape), over the spec's `config:`
    config: dict[str, Any] = {}
    #: scenarios this camera is never drawn with (a course it cannot see: the scenario's fault,
    #: not the supervisor's; say why in the spec)
    exclude_scenarios: list[str] = []


class FloorChoice(_Model):
    """One floor a campaign draws: its name in the results, its relative frequency, the
    scenario `floor:` block it lays (replacing the scenario's; empty: the scenario's own floor)
    and `config:` overrides that go with it."""

    name: ChoiceName
    weight: Weight = 1.0
    floor: dict[str, Any] = {}
    config: dict[str, Any] = {}
    #: scenarios this floor is never drawn with
    exclude_scenarios: list[str] = []


class TapeChoice(_Model):
    """One tape a campaign draws: the scenario `tape:` block (replacing the scenario's; empty:
    the scenario's own tape), `lane:` keys merged over the scenario's (dashes, single line),
    `config:` overrides that go with it (the tape widths perception is told), and the `floors`
    (names) it is laid on (empty: any; white tape on a light floor is a course nobody tapes)."""

    name: ChoiceName
    weight: Weight = 1.0
    tape: dict[str, Any] = {}
    lane: dict[str, Any] = {}
    config: dict[str, Any] = {}
    floors: list[str] = []
    exclude_scenarios: list[str] = []


class EffectChoice(_Model):
    """One set of camera effects and light a campaign draws: `camera:` keys merged over the
    scenario's camera block (exposure, noise, compression, ...), `lighting:` keys merged over
    its lighting (brightness, changes, ceiling lights), `config:` overrides."""

    name: ChoiceName
    weight: Weight = 1.0
    camera: dict[str, Any] = {}
    lighting: dict[str, Any] = {}
    config: dict[str, Any] = {}
    exclude_scenarios: list[str] = []


class FaultRange(_Model):
    """One fault kind a campaign draws, with `weight` (relative frequency) and its parameters
    as ranges (any FaultSpec field but `kind`)."""

    kind: FaultKind
    weight: Weight = 1.0
    params: dict[str, Any] = {}


#: The most scenarios, and the most fault kinds, a spec lists.
MAX_LISTED = 200


class CampaignSpec(_Model):
    """What a campaign draws its runs from."""

    name: Annotated[str, Field(min_length=1, max_length=60, pattern=r"^[A-Za-z0-9_.-]+$")]
    description: str = ""
    controller: Literal["supervised", "lecture"] = "supervised"
    scenarios: Annotated[list[str], Field(min_length=1, max_length=MAX_LISTED)]
    cameras: Annotated[list[CameraChoice], Field(min_length=1, max_length=50)] = [
        CameraChoice(name="320x240")]
    #: floor seeds are drawn from range(floor_seeds); few seeds let workers reuse the floor
    floor_seeds: Annotated[int, Field(ge=1, le=1000)] = 3
    max_time_s: Annotated[float, Field(gt=2.0, le=600.0)] = 20.0
    faults_per_run: tuple[Annotated[int, Field(ge=0, le=8)], Annotated[int, Field(ge=0, le=8)]] = (
        1, 2)
    #: when a timed fault starts, unless its params say (s)
    fault_start_s: tuple[Annotated[float, Field(ge=0.0, le=600.0)],
                         Annotated[float, Field(ge=0.0, le=600.0)]] = (2.5, 12.0)
    faults: Annotated[list[FaultRange], Field(min_length=1, max_length=MAX_LISTED)]
    #: floors, tapes and camera effects drawn per run (none: each scenario's own)
    floors: Annotated[list[FloorChoice], Field(max_length=50)] = []
    tapes: Annotated[list[TapeChoice], Field(max_length=50)] = []
    effects: Annotated[list[EffectChoice], Field(max_length=50)] = []
    #: config overrides for every run (the same shape as a config file)
    config: dict[str, Any] = {}

    @model_validator(mode="after")
    def _ordered(self) -> CampaignSpec:
        if self.faults_per_run[0] > self.faults_per_run[1]:
            raise ValueError(f"faults_per_run = {list(self.faults_per_run)}: expected [min, max]")
        if self.fault_start_s[0] > self.fault_start_s[1]:
            raise ValueError(f"fault_start_s = {list(self.fault_start_s)}: expected [from, to]")
        if self.fault_start_s[0] >= self.max_time_s:
            # every run would end before its faults start: all errors, nothing tested
            raise ValueError(
                f"fault_start_s = {list(self.fault_start_s)}: the runs end at max_time_s "
                f"{self.max_time_s:g} s, before any fault starts: expected a start below it")
        for what, choices in (("cameras", self.cameras), ("floors", self.floors),
                              ("tapes", self.tapes), ("effects", self.effects)):
            names = [c.name for c in choices]
            if len(set(names)) != len(names):
                raise ValueError(f"{what}: names must be unique, got {names}")
        floors = {f.name for f in self.floors}
        for i, tape in enumerate(self.tapes):
            unknown = [f for f in tape.floors if f not in floors]
            if unknown:
                raise ValueError(f"tapes.{i}.floors: {unknown} are not among the floors "
                                 f"{sorted(floors)}")
        return self


#: The largest seed a command takes (`--seed`), and a case file with it.
MAX_SEED = 2**32 - 1


class Case(_Model):
    """One run, completely: `lanewarden sim --case FILE` reproduces it."""

    id: str
    campaign: str
    # (as --seed bounds them: a case file's seed of 10**39 had been taken)
    campaign_seed: Annotated[int, Field(ge=0, le=MAX_SEED)]
    index: Annotated[int, Field(ge=0)]
    controller: Literal["supervised", "lecture"]
    seed: Annotated[int, Field(ge=0, le=MAX_SEED)]
    camera: str
    fault_kinds: list[str]
    #: the drawn floor, tape and camera effects (names from the spec; `scenario`/`default`:
    #: the scenario's own)
    floor: str = "scenario"
    tape: str = "scenario"
    effect: str = "default"
    scenario: dict[str, Any]
    #: the whole run's config overrides (config file shape); each piece was checked when the
    #: spec was read (`_config_problems`), the whole when the case runs
    config: dict[str, Any]

    def scenario_spec(self, source: str = "case") -> ScenarioSpec:
        return parse_scenario(self.scenario, f"{source}: scenario")


# ---- reading ----------------------------------------------------------------------------------
def default_spec_path() -> Path:
    return Path(__file__).with_name("default.yaml")


def load_campaign_spec(name_or_file: str) -> tuple[CampaignSpec, Path]:
    """The spec (`default` or a file) and the file it came from; ScenarioError (one line per
    problem, naming the file and key) for a bad one."""
    path = default_spec_path() if name_or_file == DEFAULT_SPEC else Path(name_or_file)
    if not path.exists() and not written_as_path(name_or_file):
        # a misspelt built-in name ('defualt'), not a file
        close = difflib.get_close_matches(name_or_file, [DEFAULT_SPEC], n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise ScenarioError(f"--spec {name_or_file}: no such spec file; {hint}expected "
                            f"'{DEFAULT_SPEC}' (the built-in spec) or a YAML file")
    data = _read_mapping(path, "campaign spec")
    try:
        spec = _validated(data, path, "campaign spec", CampaignSpec)
    except ScenarioError as exc:
        if more := _problems_beside(data, path):
            raise ScenarioError("\n".join([str(exc), *more])) from None
        raise
    _check_draws(spec, path)
    return spec, path


def _read_mapping(path: Path, what: str) -> dict[str, Any]:
    data = read_yaml_document(path, what, ScenarioError)
    if not isinstance(data, dict):
        raise ScenarioError(f"{path}: expected a YAML mapping at the top level, got "
                            f"{type(data).__name__}")
    return data


def _validated(data: dict[str, Any], path: Path, read_as: str, model: type[ModelT]) -> ModelT:
    """`data` read from `path` as a `read_as` (a campaign spec, a campaign case): `model`, or
    ScenarioError (one line for another lanewarden file, else one per problem)."""
    from lanewarden.config import misplaced_document  # lanewarden.config imports campaign/

    if other := misplaced_document(data, read_as, model.model_fields):
        raise ScenarioError(f"{path}: {other}")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(validation_error_lines(str(path), exc, model)) from None


def _check_draws(spec: CampaignSpec, path: Path) -> None:
    """Every scenario resolves and every fault's parameter ranges give valid faults."""
    problems = []
    unread = False  # a scenario that does not resolve: the dressing below reads the first one
    bases: dict[str, dict[str, Any]] = {}  # each scenario's data, what a choice is laid over
    for i, name in enumerate(spec.scenarios):
        base, problem = _scenario_base(i, name, path)
        if base is not None:
            bases[name] = base
        if problem is not None:
            problems.append(problem)
            unread = True
        if all(name in c.exclude_scenarios for c in spec.cameras):
            problems.append(f"{path}: scenarios.{i} = {name!r}: every camera excludes it "
                            "(cameras.*.exclude_scenarios)")
    for i, camera in enumerate(spec.cameras):
        for name in camera.exclude_scenarios:
            if name not in spec.scenarios:
                problems.append(f"{path}: cameras.{i}.exclude_scenarios: {name!r} is not one of "
                                f"the spec's scenarios {spec.scenarios}")
    groups: list[tuple[str, Sequence[Choice]]] = [
        ("floors", spec.floors), ("tapes", spec.tapes), ("effects", spec.effects)]
    for what, choices in groups:
        for i, choice in enumerate(choices):
            for name in choice.exclude_scenarios:
                if name not in spec.scenarios:
                    problems.append(f"{path}: {what}.{i}.exclude_scenarios: {name!r} is not one "
                                    f"of the spec's scenarios {spec.scenarios}")
            if unread:
                continue  # (one line per misspelt scenario, not one per floor, tape, effect)
            # over every scenario a run may lay it on: a tape checked against the first alone
            # had let a lane too wide for the lecture's 0.5 m bends through, and every run that
            # drew the two was an error
            for name in (n for n in bases if n not in choice.exclude_scenarios):
                try:
                    dressed = parse_scenario(_dress(bases[name], choice),
                                             f"{what}.{i} ({choice.name})")
                    if isinstance(choice, TapeChoice):  # the lane's width against its bends
                        build_world(dressed)
                except ScenarioError as exc:
                    problems.append(f"{path}: {what}.{i} ({choice.name}) on scenario "
                                    f"{name!r}: {_one_line(exc)}")
                    break  # (one line per choice)
    problems += _config_problems(spec, path)
    for i, fault in enumerate(spec.faults):
        if problem := _fault_problem(i, fault.kind, fault.params, spec.max_time_s, path):
            problems.append(problem)
    if problems:
        raise ScenarioError("\n".join(problems))


def _scenario_base(i: int, name: str, path: Path) -> tuple[dict[str, Any] | None, str | None]:
    """Scenario `name` (the spec's `scenarios.{i}`) as data a choice is laid over, or the line
    saying why it does not resolve."""
    try:
        return _resolve(name, path).model_dump(mode="json", exclude_defaults=True), None
    except ScenarioError as exc:
        return None, f"{path}: scenarios.{i} = {name!r}: {exc}"


def _fault_problem(i: int, kind: str, params: dict[str, Any], max_time_s: float,
                   path: Path) -> str | None:
    """Why fault `faults.{i}` (`kind` with its parameter ranges) can draw a fault that is not
    valid, in one line or a few (None: every draw is valid). Every value a draw can give at its
    extremes is tried (each one_of option, each end of a range; every combination while they
    are few): three random draws had let {one_of: [99, 2]} through, and run 0 then failed."""
    try:
        options = {key: _extremes(value, f"faults.{i}.params.{key}")
                   for key, value in params.items()}
    except ValueError as exc:  # (the line names the key: faults.{i}.params.{key})
        return f"{path}: {_one_line(exc)}"
    late = [at for at in options.get("at_s", []) if isinstance(at, int | float)
            and not isinstance(at, bool) and at >= max_time_s]
    if late:
        # as for fault_start_s: a fault set to start after the runs end never takes effect,
        # and every run that drew it was an error
        return (f"{path}: faults.{i} ({kind}): params.at_s = {max(late):g}: the runs end at "
                f"max_time_s {max_time_s:g} s: expected a start below it")
    for drawn in _combinations(options):
        try:
            FaultSpec.model_validate({"kind": kind, **_placement(kind, drawn), **drawn})
        except ValidationError as exc:  # worded as a scenario file's problems are
            return validation_error_lines(str(path), exc, FaultSpec,
                                          prefix=("faults", i, "params"))
        except ValueError as exc:
            return f"{path}: faults.{i} ({kind}): {_one_line(exc)}"
    return None


def _problems_beside(data: dict[str, Any], path: Path) -> list[str]:
    """A spec that fails its own checks: the scenario names and fault parameters that can still
    be checked in its data, so that one run shows every problem (a safety reviewer's spec with
    six typos took two rounds: these checks had waited for a spec that passes)."""
    problems = []

    def listed(key: str) -> list[Any]:  # (a list longer than a spec may be: its own line says
        value = data.get(key)           # so; each entry would cost a check)
        return value if isinstance(value, list) and len(value) <= MAX_LISTED else []

    for i, name in enumerate(listed("scenarios")):
        if isinstance(name, str) and (problem := _scenario_base(i, name, path)[1]):
            problems.append(problem)
    max_time_s = data.get("max_time_s", CampaignSpec.model_fields["max_time_s"].default)
    if not isinstance(max_time_s, int | float) or isinstance(max_time_s, bool):
        max_time_s = CampaignSpec.model_fields["max_time_s"].default
    for i, fault in enumerate(listed("faults")):
        if not isinstance(fault, dict) or fault.get("kind") not in get_args(FaultKind):
            continue  # (its own line says what is wrong with it)
        params = fault.get("params", {})
        if isinstance(params, dict) and all(isinstance(key, str) for key in params) and (
                problem := _fault_problem(i, fault["kind"], params, float(max_time_s), path)):
            problems.append(problem)
    return problems


def _config_problems(spec: CampaignSpec, path: Path) -> list[str]:
    """The spec's config overrides checked now, not when a run draws them (a bad key would
    otherwise turn every run with it into an error): the top-level `config:`, and each camera's
    `config:` and `simulation:`, each floor's, tape's and effect's `config:` over it."""
    from lanewarden.config import config_from_mapping  # lanewarden.config imports campaign/
    from lanewarden.errors import ConfigError

    pieces: list[tuple[str, dict[str, Any]]] = [("config", {})]
    pieces_by_choice: dict[int, dict[str, Any]] = {}
    for i, camera in enumerate(spec.cameras):
        pieces_by_choice[id(camera)] = merge_overrides(camera.config, {
            "simulation": {"width_px": camera.width_px, "height_px": camera.height_px,
                           **camera.simulation}})
        pieces.append((f"cameras.{i} ({camera.name})", pieces_by_choice[id(camera)]))
    groups: list[tuple[str, Sequence[Choice]]] = [
        ("floors", spec.floors), ("tapes", spec.tapes), ("effects", spec.effects)]
    for what, choices in groups:
        pieces += [(f"{what}.{i} ({c.name})", c.config) for i, c in enumerate(choices) if c.config]
        pieces_by_choice.update((id(c), c.config) for c in choices)
    problems = []
    for where, overrides in pieces:
        try:
            config_from_mapping(merge_overrides(spec.config, overrides), f"{path}: {where}")
        except ConfigError as exc:
            problems.append(str(exc))
            if where == "config":  # every other piece goes over it: one report is enough
                break
    if problems:
        return problems
    # Then the pieces a run may draw together, each fine alone: a camera's speed limit and an
    # effect's slower base had made every run that drew both an error.
    for drawn in _drawn_together(spec, pieces_by_choice):
        named = [f"{what}.{i} ({c.name})" for what, i, c in drawn]
        merged = dict(spec.config)
        for _, _, choice in drawn:
            merged = merge_overrides(merged, pieces_by_choice[id(choice)])
        try:
            config_from_mapping(merged, f"{path}: {' with '.join(named)}")
        except ConfigError as exc:
            problems.append(" ".join(str(exc).split("\n")[:1]))
            break  # (one line: the first such draw)
    return problems


def _drawn_together(spec: CampaignSpec, pieces: Mapping[int, dict[str, Any]],
                    ) -> Iterator[list[tuple[str, int, Any]]]:
    """The choices a run may draw together (a camera, and a floor, tape and effect where the
    spec has them: some scenario none of them excludes, the tape laid on that floor) that bring
    config overrides (`pieces`, by the choice's id), at least two; each such set once."""
    groups: list[list[tuple[str, int, Any]]] = [
        [("cameras", i, c) for i, c in enumerate(spec.cameras)]]
    for what, choices in (("floors", spec.floors), ("tapes", spec.tapes),
                          ("effects", spec.effects)):
        if choices:
            groups.append([(what, i, c) for i, c in enumerate(choices)])
    seen: set[tuple[int, ...]] = set()
    for drawn in itertools.product(*groups):
        bringing = tuple(id(c) for _, _, c in drawn if pieces[id(c)])
        if len(bringing) < 2 or bringing in seen:
            continue  # (each piece alone was checked)
        if not any(all(name not in c.exclude_scenarios for _, _, c in drawn)
                   for name in spec.scenarios):
            continue
        floor = next((c for what, _, c in drawn if what == "floors"), None)
        tape = next((c for what, _, c in drawn if what == "tapes"), None)
        if floor is not None and tape is not None and tape.floors and floor.name not in tape.floors:
            continue
        seen.add(bringing)
        yield [(what, i, c) for what, i, c in drawn if pieces[id(c)]]


def _placement(kind: str, params: Mapping[str, Any]) -> dict[str, Any]:
    if kind in FLOOR_FAULT_KINDS:
        return {} if "at_m" in params else {"at_m": 1.0}
    return {}


def _one_line(exc: Exception) -> str:
    if isinstance(exc, ValidationError):  # each key with the value it was given
        return "; ".join(f"{'.'.join(str(p) for p in e['loc'])} = {shown_value(e.get('input'))}"
                         f": {e['msg']}" for e in exc.errors())
    return " ".join(str(exc).split())


def _resolve(name: str, spec_path: Path) -> ScenarioSpec:
    if name in library_names():
        return resolve_scenario(name)
    candidate = Path(name)
    if not candidate.is_absolute():
        candidate = spec_path.parent / candidate
    if not written_as_path(name) and not candidate.exists():  # a misspelt library name
        raise ScenarioError(unknown_scenario(name))
    return resolve_scenario(str(candidate))


def spec_fingerprint(spec: CampaignSpec, config_overrides: Mapping[str, Any]) -> str:
    """Identifies what a campaign directory holds (spec + config overrides)."""
    # Defaults left out: a field added later with a default does not orphan existing results.
    text = json.dumps({"spec": spec.model_dump(mode="json", exclude_defaults=True),
                       "config": config_overrides}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# ---- drawing ----------------------------------------------------------------------------------
#: Above this many combinations of extremes, each parameter's are checked with the others' first.
MAX_CHECKED_COMBINATIONS = 256


def _extremes(value: Any, where: str) -> list[Any]:
    """The values a parameter's draws can take at their extremes (ValueError for a bad form)."""
    rng = np.random.default_rng(0)
    _draw(rng, value, where)  # the form is checked as a draw checks it
    if isinstance(value, Mapping):
        return list(value["one_of"])
    if isinstance(value, list):
        return list(value)
    return [value]


def _combinations(options: Mapping[str, list[Any]]) -> Iterator[dict[str, Any]]:
    keys = list(options)
    if math.prod(len(options[k]) for k in keys) <= MAX_CHECKED_COMBINATIONS:
        for values in itertools.product(*(options[k] for k in keys)):
            yield dict(zip(keys, values, strict=True))
        return
    first = {k: options[k][0] for k in keys}
    for key in keys:
        for value in options[key]:
            yield {**first, key: value}


def _draw(rng: np.random.Generator, value: Any, where: str) -> Any:
    if isinstance(value, Mapping):
        if set(value) != {"one_of"} or not isinstance(value["one_of"], list) or not value[
                "one_of"]:
            raise ValueError(f"{where}: expected a value, [low, high] or {{one_of: [...]}}")
        choices = value["one_of"]
        return choices[int(rng.integers(0, len(choices)))]
    if isinstance(value, list):
        if len(value) != 2 or not all(isinstance(v, int | float) and not isinstance(v, bool)
                                      for v in value) or value[0] > value[1]:
            raise ValueError(f"{where} = {value}: expected [low, high] (numbers, low <= high)")
        low, high = value
        if isinstance(low, int) and isinstance(high, int):
            return int(rng.integers(low, high + 1))
        return round(float(rng.uniform(low, high)), 4)
    return value


def _lane_length_m(scenario: ScenarioSpec) -> float:
    ends = [e for e in (scenario.lane.ends.left_m, scenario.lane.ends.right_m) if e is not None]
    return min([scenario.lane.length_m, *ends])


#: A fault that would start inside a loop stall starts this long after the stall ends instead.
AFTER_STALL_S = 0.05


def _not_inside_a_stall(faults: list[dict[str, Any]]) -> None:
    """While the loop is stalled nothing is read or written, so a fault starting inside the
    stall could end unseen (a 0.05 s blocked write inside a 0.3 s stall never blocks anything:
    the run would be an `error`, the case's fault, not the supervisor's). Such a fault starts
    just after the stall instead (a stall without a duration lasts to the end: left alone)."""
    stalls = [(f["at_s"], f["at_s"] + f["duration_s"]) for f in faults
              if f["kind"] == "loop_stall" and f.get("duration_s") is not None]
    for fault in faults:
        if fault["kind"] == "loop_stall" or "at_s" not in fault:
            continue
        for start, end in stalls:
            if start <= fault["at_s"] < end:
                fault["at_s"] = round(end + AFTER_STALL_S, 3)


#: Faults that act through the camera's frames, and through the base's serial link.
CAMERA_STREAM_KINDS = frozenset({
    "camera_freeze", "camera_ring", "camera_drop", "camera_error", "late_frames",
    "frame_from_future",
    "perception_exception", "frame_rate_collapse", "timestamp_jump", "exposure_jump",
    "glare_sweep", "occlusion", "lens_smudge"})
LINK_STREAM_KINDS = frozenset({
    "base_link_loss", "link_garbage", "checksum_storm", "write_blocks", "bumper", "cliff",
    "wheel_drop", "low_battery"})
#: Without a duration these end their stream for good (no new frames, or a frozen image; no
#: link): a fault on the same stream starting later could never take effect.
STREAM_KILLERS = {"camera_freeze": CAMERA_STREAM_KINDS, "camera_ring": CAMERA_STREAM_KINDS,
                  "camera_drop": CAMERA_STREAM_KINDS,
                  "camera_error": CAMERA_STREAM_KINDS, "base_link_loss": LINK_STREAM_KINDS}
#: ... so such a fault starts at least this long after the other faults on its stream.
AFTER_OTHERS_S = 0.5
#: When two permanent losses of one stream are drawn, the earlier one lasts this long instead.
SHORTENED_LOSS_S = 1.0


def _stream_loss_last(faults: list[dict[str, Any]]) -> None:
    """A permanent loss of a stream (camera or link) starts after every other fault on that
    stream has started (run 210 of the default campaign drew late frames 0.76 s after a
    permanent camera error: they could never take effect, an `error` of the case's making).
    Two permanent losses of one stream cannot both act (run 665: a camera error, then a freeze):
    all but the last-starting one last SHORTENED_LOSS_S."""
    permanent = [f for f in faults if f["kind"] in STREAM_KILLERS
                 and f.get("duration_s") is None and "at_s" in f]
    for lost in {STREAM_KILLERS[f["kind"]] for f in permanent}:
        losses = sorted((f for f in permanent if STREAM_KILLERS[f["kind"]] is lost),
                        key=lambda f: f["at_s"])
        for earlier in losses[:-1]:
            earlier["duration_s"] = SHORTENED_LOSS_S
    for killer in faults:
        stream = STREAM_KILLERS.get(killer["kind"])
        if stream is None or killer.get("duration_s") is not None or "at_s" not in killer:
            continue
        # after the others start, and after a (shortened) loss of the same stream ends
        others = [f["at_s"] + ((f.get("duration_s") or 0.0) if f["kind"] in STREAM_KILLERS
                               else 0.0)
                  for f in faults if f is not killer and f["kind"] in stream and "at_s" in f]
        if others and killer["at_s"] < max(others) + AFTER_OTHERS_S:
            killer["at_s"] = round(max(others) + AFTER_OTHERS_S, 3)


Choice = FloorChoice | TapeChoice | EffectChoice


def _dress(scenario: dict[str, Any], choice: Choice) -> dict[str, Any]:
    """The scenario (its JSON data) with a drawn floor, tape or effect laid over it."""
    data = dict(scenario)
    if isinstance(choice, FloorChoice) and choice.floor:
        data["floor"] = dict(choice.floor)
    elif isinstance(choice, TapeChoice):
        if choice.tape:
            data["tape"] = dict(choice.tape)
        if choice.lane:
            data["lane"] = merge_overrides(data.get("lane", {}), choice.lane)
    elif isinstance(choice, EffectChoice):
        if choice.camera:
            data["camera"] = merge_overrides(data.get("camera", {}), choice.camera)
        if choice.lighting:
            data["lighting"] = merge_overrides(data.get("lighting", {}), choice.lighting)
    return data


def _pick(rng: np.random.Generator, choices: list[Any], scenario: str,
          allowed: Any = None) -> Any:
    """One of `choices` by weight, never one that excludes `scenario` (None: none to draw)."""
    weights = np.array([0.0 if scenario in c.exclude_scenarios or (
        allowed is not None and not allowed(c)) else c.weight for c in choices])
    if not len(choices) or weights.sum() <= 0:
        return None
    return choices[int(rng.choice(len(choices), p=weights / weights.sum()))]


def draw_case(spec: CampaignSpec, spec_path: Path, campaign_seed: int, index: int,
              config_overrides: Mapping[str, Any], follow_speed_m_s: float) -> Case:
    """Run `index` of the campaign: a pure function of its arguments."""
    rng = np.random.default_rng([campaign_seed, index, 0xCA5E])
    scenario_name = spec.scenarios[int(rng.integers(0, len(spec.scenarios)))]
    scenario = _resolve(scenario_name, spec_path)
    camera_weights = np.array([0.0 if scenario_name in c.exclude_scenarios else c.weight
                               for c in spec.cameras], dtype=np.float64)
    camera = spec.cameras[int(rng.choice(len(spec.cameras),
                                         p=camera_weights / camera_weights.sum()))]
    seed = int(rng.integers(0, spec.floor_seeds))
    max_time = min(scenario.run.max_time_s, spec.max_time_s)
    count = int(rng.integers(spec.faults_per_run[0], spec.faults_per_run[1] + 1))
    weights = np.array([f.weight for f in spec.faults], dtype=np.float64)
    chosen: list[int] = [int(c) for c in rng.choice(
        len(spec.faults), size=min(count, len(spec.faults)), replace=False,
        p=weights / weights.sum())] if count else []
    on_floor = [c for c in chosen if spec.faults[c].kind in FLOOR_FAULT_KINDS]
    if on_floor:
        # A floor fault needs the robot to drive up to it: no other fault may stop it first.
        chosen = on_floor[:1]
    reach = min(_lane_length_m(scenario) - 0.3,
                REACH_FRACTION * follow_speed_m_s * max(0.0, max_time - START_UP_S))
    faults = [dict(f) for f in (fs.model_dump(mode="json", exclude_defaults=True)
                                for fs in scenario.faults)]
    kinds: list[str] = []
    for choice in chosen:
        fault = spec.faults[int(choice)]
        params = {key: _draw(rng, value, key) for key, value in fault.params.items()}
        if fault.kind in FLOOR_FAULT_KINDS:
            if "at_m" not in params:
                params["at_m"] = round(float(rng.uniform(FLOOR_FAULT_MIN_M,
                                                         max(FLOOR_FAULT_MIN_M, reach))), 3)
        elif "at_s" not in params:
            latest = min(spec.fault_start_s[1], max_time - 3.0)
            params["at_s"] = round(float(rng.uniform(spec.fault_start_s[0],
                                                     max(spec.fault_start_s[0], latest))), 3)
        faults.append({"kind": fault.kind, **params})
        kinds.append(fault.kind)
    _not_inside_a_stall(faults)
    _stream_loss_last(faults)
    data = scenario.model_dump(mode="json", exclude_defaults=True)
    data.pop("expect", None)  # the scenario's expected outcome is without these faults
    # Floor, tape and effects come from a stream of their own, so a spec without them draws
    # exactly the cases it drew before they existed.
    look = np.random.default_rng([campaign_seed, index, 0xF1002])
    floor = _pick(look, spec.floors, scenario_name)
    tape = _pick(look, spec.tapes, scenario_name,
                 lambda t: not t.floors or (floor is not None and floor.name in t.floors))
    effect = _pick(look, spec.effects, scenario_name)
    drawn = [c for c in (floor, tape, effect) if c is not None]
    for choice in drawn:
        data = _dress(data, choice)
    if camera.camera:
        data["camera"] = merge_overrides(data.get("camera", {}), camera.camera)
    data["faults"] = faults
    data["run"] = merge_overrides(data.get("run", {}), {"max_time_s": max_time})
    config = merge_overrides(merge_overrides(dict(config_overrides), spec.config), camera.config)
    for choice in drawn:
        config = merge_overrides(config, choice.config)
    config = merge_overrides(config, {"simulation": {"width_px": camera.width_px,
                                            "height_px": camera.height_px,
                                            **camera.simulation,
                                            "progress": False}})
    case = Case(id=case_id(index), campaign=spec.name, campaign_seed=campaign_seed,
                index=index, controller=spec.controller, seed=seed, camera=camera.name,
                fault_kinds=kinds, floor="scenario" if floor is None else floor.name,
                tape="scenario" if tape is None else tape.name,
                effect="default" if effect is None else effect.name, scenario=data,
                config=config)
    case.scenario_spec(f"campaign {spec.name} run {index}")  # every drawn case is valid
    return case


def case_id(index: int) -> str:
    """Run `index`'s id: r00042."""
    return f"r{index:05d}"


# ---- case files -------------------------------------------------------------------------------
def case_yaml(case: Case) -> str:
    return yaml.safe_dump(case.model_dump(mode="json"), sort_keys=False)


def load_case(path: str | Path) -> Case:
    """A case file (as written by a campaign); ScenarioError (one line per problem, or one
    saying it is no case file at all: a scenario or some other YAML gave a dozen lines)."""
    data = _read_mapping(Path(path), "case")  # (read once: it had been read twice)
    if not {"id", "scenario"} <= set(data):
        from lanewarden.config import misplaced_document  # lanewarden.config imports campaign/

        raise ScenarioError(f"{path}: " + (
            misplaced_document(data, "campaign case", Case.model_fields)
            or "not a campaign case: a case file is DIR/cases/<id>.yaml as a campaign writes "
               "it (with id: and scenario:)"))
    case = _validated(data, Path(path), "campaign case", Case)
    case.scenario_spec(str(path))
    return case
