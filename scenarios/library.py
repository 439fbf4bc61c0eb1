"""The scenario library shipped with the package (`scenarios/library/*.yaml`), found by name.

`resolve_scenario("lecture")` loads a library scenario; anything that looks like a path (has a
suffix or a separator, or exists) is loaded as a file. An unknown name is a ScenarioError naming
the closest name ("did you mean") and listing all of them. Reads package data only; never renders
or runs anything.
"""

from __future__ import annotations

import difflib
from importlib import resources
from pathlib import Path

from lanewarden.documents import parse_yaml_text
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.spec import ScenarioSpec, load_scenario_file, parse_scenario


def _library_dir() -> Path:
    return Path(str(resources.files("lanewarden.scenarios") / "library"))


def library_names() -> list[str]:
    """Names of the scenarios shipped with the package, sorted."""
    return sorted(p.stem for p in _library_dir().glob("*.yaml"))


def library_path(name: str) -> Path:
    return _library_dir() / f"{name}.yaml"


def written_as_path(text: str) -> bool:
    """A scenario named by a path (a separator or a YAML suffix), not by a library name."""
    return "/" in text or "\\" in text or text.endswith((".yaml", ".yml"))


def _looks_like_path(text: str) -> bool:
    return written_as_path(text) or Path(text).exists()


def unknown_scenario(name: str) -> str:
    """"unknown scenario 'x'; did you mean 'y'? (expected a YAML file or one of: ...)"."""
    names = library_names()
    close = difflib.get_close_matches(name, names, n=1)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    return (f"unknown scenario '{name}'{hint} (expected a YAML file or one of: "
            f"{', '.join(names)})")


def resolve_scenario(name_or_file: str) -> ScenarioSpec:
    """A library scenario by name, or a scenario file by path."""
    if _looks_like_path(name_or_file):
        return load_scenario_file(name_or_file)
    if name_or_file not in library_names():
        raise ScenarioError(f"--scenario: {unknown_scenario(name_or_file)}")
    path = library_path(name_or_file)
    spec = load_scenario_file(path)
    if spec.name != name_or_file:
        raise ScenarioError(f"{path}: name = {spec.name!r}: expected {name_or_file!r}")
    return spec


def parse_scenario_text(text: str, source: str = "<scenario>") -> ScenarioSpec:
    """Validate scenario YAML given as text (used by tests and tools)."""
    return parse_scenario(parse_yaml_text(text, source, ScenarioError), source)
