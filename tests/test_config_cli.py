"""The one config and the CLI's error contract: one line, naming the key/file, non-zero exit."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from lanewarden.cli import main
from lanewarden.config import LanewardenConfig, config_as_yaml, load_config
from tests.conftest import PROJECT_ROOT


def test_config_show_round_trips(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["config", "show"]) == 0
    out = capsys.readouterr().out
    path = tmp_path / "effective.yaml"
    path.write_text(out)
    assert load_config(path) == LanewardenConfig()
    assert yaml.safe_load(config_as_yaml(LanewardenConfig())) == yaml.safe_load(out)
    leaf_lines = [line for line in out.splitlines() if not line.rstrip().endswith(":")]
    leaf_lines = [line for line in leaf_lines if ":  #" not in line]  # section headers
    assert leaf_lines and all("  # " in line for line in leaf_lines), "a key without its meaning"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("perceptoin: {}\n", "unknown key 'perceptoin'"),
        ("- 1\n- 2\n", "expected a YAML mapping"),
        ("perception: [\n", "not valid YAML"),
        # a camera calibration given as --config (a new user did): named as such
        ("%YAML 1.2\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n",
         "it holds OpenCV's !!opencv-matrix, as a camera calibration does (give that file as "
         "--calibration)"),
        # ...even where PyYAML stops first at an escape OpenCV writes and YAML has not (\')
        ("%YAML 1.2\n---\nground_method: \"the mount\\'s\"\ncamera_matrix: !!opencv-matrix\n",
         "it holds OpenCV's !!opencv-matrix, as a camera calibration does (give that file as "
         "--calibration)"),
    ],
)
def test_bad_config_is_one_line_naming_the_problem(
    text: str, expected: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    assert main(["config", "show", "--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert expected in err
    assert str(path) in err
    assert "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


#: A campaign's case file (DIR/cases/<id>.yaml) with every key a case must have.
CASE = ("id: r00001\ncampaign: default\ncampaign_seed: 0\nindex: 1\ncontroller: supervised\n"
        "seed: 5\ncamera: 320x240\nfault_kinds: []\nscenario: {name: s}\nconfig: {}\n")


@pytest.mark.parametrize(("file", "expected"), [
    ("scenarios/library/straight.yaml",
     "a scenario (it has 'name:' and 'lane:'), not a config (give this file to sim --scenario)"),
    ("scenarios/campaign/default.yaml",
     "a campaign spec (it has 'name:' and 'scenarios:'), not a config (give this file to "
     "campaign --spec)"),
    # a case holds 'campaign: default', a name, where a config has its campaign section
    ("r00001.yaml", "a campaign case (it has 'id:' and 'campaign_seed:'), not a config (give "
                    "this file to sim --case)"),
])
def test_another_lanewarden_file_given_as_the_config_is_one_line_saying_so(
    file: str, expected: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A scenario given to --config had said 'unknown key' of each of its keys (six lines for
    the library's straight.yaml), a campaign spec of ten and then '... and 3 more problems'."""
    path = PROJECT_ROOT / file
    if file == "r00001.yaml":
        path = tmp_path / file
        path.write_text(CASE, encoding="utf-8")
    assert main(["config", "show", "--config", str(path)]) == 2
    assert capsys.readouterr().err.splitlines() == [f"lanewarden: error: {path}: {expected}"]


def test_a_config_with_a_stray_top_level_key_is_still_read_as_a_config(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Only a file with no config section of its own is taken for another kind: a config
    with a misplaced 'name:' is told about that key."""
    path = tmp_path / "lw.yaml"
    path.write_text("name: mine\nlane: {}\nperception: {}\n", encoding="utf-8")
    assert main(["config", "show", "--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: unknown key 'name'" in err and "not a config" not in err


def test_missing_config_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nope.yaml"
    assert main(["config", "show", "--config", str(missing)]) == 2
    err = capsys.readouterr().err
    # the flag, the value and what was expected, before anything is read
    assert (f"Invalid value for '--config': Path '{missing}' does not exist; expected a config "
            "file") in err


def test_unknown_command_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["no-such-command"]) == 2
    assert "No such command" in capsys.readouterr().err


def test_the_simulators_calibration_file_is_yaml(tmp_path: Path) -> None:
    """What `sim --camera-out` writes beside its clip (the simulated camera's calibration) reads
    as YAML too: OpenCV writes an apostrophe as \\' in a quoted string, which YAML refuses
    (a new user gave that file as --config and got 'unknown escape character')."""
    from lanewarden.perception.calibration import save_calibration
    from lanewarden.scenarios.camera import CameraModel

    path = tmp_path / "clip.calibration.yaml"
    save_calibration(CameraModel().calibration(), path)
    text = path.read_text()
    document = yaml.safe_load(text.replace("!!opencv-matrix", ""))
    assert document["ground_method"] == "the simulated camera, at its true pose"
