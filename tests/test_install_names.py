"""The installed import names collide with nothing: one top-level package, `lanewarden`.

perception/, supervisor/, actuation/ and scenarios/ install as `lanewarden.perception`, ... (PyPI's
`supervisor` is supervisord's package). The wheel test builds the real wheel; the coexistence test
installs it next to supervisord and uses both (it needs the package index and skips without it).
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

from tests.conftest import PROJECT_ROOT

LAYERS = ("perception", "supervisor", "actuation", "scenarios")


def _python_files() -> list[Path]:
    roots = [PROJECT_ROOT / name for name in (*LAYERS, "lanewarden", "tests", "benchmarks")]
    return [path for root in roots for path in root.rglob("*.py")]


def test_the_tree_has_no_symlinks() -> None:
    """A clone must work where git checks symlinks out as plain files (Windows without developer
    mode): the layers are mapped by setuptools' package-dir, not linked."""
    listed = subprocess.run(["git", "ls-files", "-s"], cwd=PROJECT_ROOT, capture_output=True,
                            text=True)
    if listed.returncode != 0:
        pytest.skip(f"not a git checkout: {listed.stderr.strip()[:80]}")
    links = [line.split("\t", 1)[1] for line in listed.stdout.splitlines()
             if line.startswith("120000 ")]
    assert links == []


def test_every_package_folder_is_listed_for_setuptools() -> None:
    """pyproject lists the packages by hand (package-dir mapping); a new folder with an
    __init__.py must be listed there or it is missing from the wheel."""
    config = tomllib.loads((PROJECT_ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    mapping = {"lanewarden": "lanewarden", **config["package-dir"]}
    expected = set()
    for name, folder in mapping.items():
        for init in (PROJECT_ROOT / folder).rglob("__init__.py"):
            relative = init.parent.relative_to(PROJECT_ROOT / folder).parts
            expected.add(".".join((name, *relative)))
    assert set(config["packages"]) == expected
    assert set(config["package-dir"]) == {f"lanewarden.{layer}" for layer in LAYERS}


def test_no_code_imports_a_layer_by_its_bare_top_level_name() -> None:
    offenders = []
    for path in _python_files():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            offenders += [f"{path.relative_to(PROJECT_ROOT)}:{node.lineno} imports {name}"
                          for name in names if name.split(".")[0] in LAYERS]
    assert offenders == []


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    result = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", str(PROJECT_ROOT), "-w",
         str(out)], capture_output=True, text=True)
    if result.returncode != 0:
        pytest.skip(f"cannot build the wheel here (pip needs setuptools from the index): "
                    f"{result.stderr.strip().splitlines()[-1:]}")
    return next(out.glob("lanewarden-*.whl"))


def test_the_wheel_installs_one_top_level_package(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    top_level = {name.split("/")[0] for name in names}
    assert top_level == {"lanewarden", f"{wheel.name.split('-py3')[0]}.dist-info"}
    for layer in LAYERS:
        assert f"lanewarden/{layer}/__init__.py" in names
    assert "lanewarden/actuation/deadman.py" in names
    assert "lanewarden/scenarios/library/lecture.yaml" in names


def test_installs_and_works_next_to_supervisord(wheel: Path, tmp_path: Path) -> None:
    target = tmp_path / "site"
    install = subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(target),
         str(wheel), "supervisor"], capture_output=True, text=True)
    if install.returncode != 0:
        pytest.skip(f"cannot install supervisord from the package index here: "
                    f"{install.stderr.strip().splitlines()[-1:]}")
    script = (
        "import supervisor.supervisord, supervisor.options\n"
        "from lanewarden.supervisor.controller import SupervisedController\n"
        "from lanewarden.supervisor.config import SupervisorConfig\n"
        "from lanewarden.cli import main\n"
        "import lanewarden\n"
        f"assert supervisor.supervisord.__file__.startswith({str(target)!r})\n"
        f"assert lanewarden.__file__.startswith({str(target)!r})\n"
        "SupervisedController(SupervisorConfig())\n"
        "print(supervisor.options.ServerOptions().__class__.__name__)\n"
        "raise SystemExit(main(['config', 'show']))\n"
    )
    # the wheel's dependencies come from this environment; the wheel and supervisord from `target`
    env = {**os.environ, "PYTHONPATH": str(target)}
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            env=env, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("ServerOptions\n")
    assert "supervisor:" in result.stdout  # lanewarden's config show printed its sections


def test_a_clone_imported_from_its_root_is_the_clone_whole() -> None:
    """`python benchmarks/...` or `python -m lanewarden.config_reference` from a clone's root with
    a plain `pip install .`: the clone's lanewarden/ comes first on sys.path and hides the
    installed copy, so its layers must come from the clone too (they were 'No module named
    lanewarden.actuation'). `-S`: no site-packages, so no installed or editable copy answers."""
    probe = ("import importlib.util as u, lanewarden; "
             "print(*(u.find_spec('lanewarden.' + n).origin for n in "
             f"{LAYERS!r}), sep='\\n')")
    found = subprocess.run([sys.executable, "-S", "-c", probe], cwd=PROJECT_ROOT,
                           capture_output=True, text=True, check=True)
    assert found.stdout.split() == [str(PROJECT_ROOT / name / "__init__.py") for name in LAYERS]
