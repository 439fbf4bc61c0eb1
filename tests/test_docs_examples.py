"""Every example in README.md and docs/*.md is run by a test, so the docs cannot drift.

Each `lanewarden ...` line in a ```bash block is accounted for in one literal table below: run
here, in order, in a folder prepared with what it reads (chessboard shots, lane frames, the
scenario file of docs/scenarios.md); run by another test (the demo); or, for those that need a
robot or a camera, parsed by the real CLI down to their subcommand and options (so a renamed flag
fails) but not run: on a developer's machine `--camera 0` may be a real webcam, `base drive` a
real robot. The `from ... import ...` lines of the ```python sketches are imported, and the
examples in every command's --help are parsed. An example added to the docs without a row here
fails `test_every_example_is_accounted_for`.
"""

from __future__ import annotations

import glob
import re
from pathlib import Path

import click
import cv2
import numpy as np
import pytest

from lanewarden.cli import cli, main
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.chessboard import (
    ChessboardRenderer,
    calibration_poses,
    floor_board_pose,
)
from tests.conftest import PROJECT_ROOT
from tests.perception import synthetic as syn

DOCS = [PROJECT_ROOT / "README.md", *sorted((PROJECT_ROOT / "docs").glob("*.md"))]

#: Run here, in this order, with the exit code they must give.
RUN_HERE: tuple[tuple[str, int], ...] = (
    ("lanewarden config show > lanewarden.yaml", 0),
    ("lanewarden calibrate --images 'shots/*.jpg' --pattern 9x6 --square 0.025 --out camera.yaml",
     0),
    ("lanewarden calibrate --images 'shots/*.jpg' --pattern 9x6 --square 0.025 --out camera.yaml "
     "--ros", 0),
    ("lanewarden undistort shots/view_000.jpg --calibration camera.yaml --out undistorted/", 0),
    ("lanewarden calibrate ground --calibration camera.yaml --height-m 0.26 --pitch-deg 40 "
     "--forward-m 0.12 --out camera.yaml", 0),
    ("lanewarden calibrate ground --calibration camera.yaml --image floor.jpg --pattern 9x6 "
     "--square 0.03 --board-center-m 0.55,0 --out camera.yaml", 0),
    ("lanewarden detect frames/*.png --json > detections.jsonl", 0),
    ("lanewarden detect shot.jpg --calibration camera.yaml --out annotated/", 0),
    ("lanewarden sim --scenario my-track.yaml --no-video --check", 0),
    ("lanewarden sim --scenario lane-ends --controller lecture --seed 3 --out out/lane-ends", 0),
)
#: Run by another test.
RUN_ELSEWHERE = {
    "lanewarden demo": "tests/scenarios/test_demo.py (the same command, into a temporary --out)",
    "lanewarden sim --scenario lane-ends --camera-out clip.mp4":
        "tests/operator/test_try_without_a_robot.py (README's block, run as written)",
    ("lanewarden run --camera clip.mp4 --calibration clip.calibration.yaml --base sim --record "
     "runs/first --view 8080"):
        "tests/operator/test_try_without_a_robot.py (README's block, run as written)",
    "lanewarden replay runs/first":
        "tests/operator/test_try_without_a_robot.py (README's block, run as written)",
    "lanewarden replay runs/2026-11-05T14-03-12Z --check":
        "tests/operator/test_run_end_to_end.py (a run recorded by run --record, replay --check)",
    "lanewarden replay clip.mp4 --out out/clip":
        "tests/operator/test_replay_sources.py (a rendered clip)",
    "lanewarden replay 'shots/*.png'": "tests/operator/test_replay_sources.py (a folder of images)",
    "lanewarden replay my_bag/ --topic /camera/image_raw/compressed":
        "tests/operator/test_replay_bags.py (rosbag2 folders written by rosbags, --topic)",
    ("lanewarden replay ../shared/data/donkeycar-tub --config "
     "tests/perception/donkeycar_camera.yaml --calibration "
     "tests/perception/donkeycar_calibration.yaml"):
        "tests/operator/test_replay_sources.py (the same tub, config and calibration)",
    ("lanewarden survey data/real/jetbot-tape-lane --calibration "
     "data/real/jetbot-tape-lane/calibration.yaml --config data/real/jetbot-tape-lane/camera.yaml"):
        "tests/survey/test_survey_real.py (the same folder, calibration and config, into a "
        "temporary --out)",
    "lanewarden survey data/survey/rendered":
        "tests/survey/test_survey_cli.py (the same command, into a temporary --out)",
    "lanewarden survey floor/ --calibration camera.yaml --config robot.yaml":
        "tests/survey/test_survey_cli.py (a floor/ of rendered photos, the simulated camera's "
        "calibration, a robot.yaml with their tape and lane)",
    ("lanewarden survey ../shared/data/donkeycar-tub --labels data/survey/donkeycar-tub.csv "
     "--config tests/perception/donkeycar_camera.yaml --calibration "
     "tests/perception/donkeycar_calibration.yaml"):
        "tests/survey/test_survey_real.py (the same tub, labels, config and calibration)",
    "lanewarden campaign --spec default --out campaign-out --runs 1000":
        "tests/campaign/test_campaign_cli.py and test_dask.py (small specs; 1000 runs take hours)",
    "lanewarden sim --case campaign-out/cases/r00042.yaml":
        "tests/campaign/test_campaign_cli.py (a case of a campaign it runs first)",
}
#: Need hardware: parsed, not run.
NEEDS_HARDWARE = {
    "lanewarden base info --port /dev/kobuki": "a Kobuki on /dev/kobuki",
    "lanewarden base drive --linear 0.1 --duration 2": "a Kobuki (the wheels turn)",
    "lanewarden calibrate capture --camera 0 --pattern 9x6 --out shots/": "camera 0",
    "lanewarden calibrate capture --camera 0 --pattern 9x6 --out shots/ --count 25": "camera 0",
    "lanewarden calibrate capture --camera 0 --pattern 9x6 --count 1 --out floor/": "camera 0",
    "lanewarden run --camera 0 --calibration camera.yaml --view 8080": "camera 0 and a Kobuki",
    "lanewarden run --camera 0 --base none": "camera 0",
}

_FENCE = re.compile(r"```(\w*)\n(.*?)```", re.S)
_TOKEN = re.compile(r"'[^']*'|\"[^\"]*\"|\S+")


def _blocks(language: str) -> list[str]:
    return [m.group(2) for doc in DOCS for m in _FENCE.finditer(doc.read_text(encoding="utf-8"))
            if m.group(1) == language]


def _joined_lines(text: str) -> list[str]:
    """Lines with shell continuations (a trailing backslash) joined to the next line."""
    return text.replace("\\\n", " ").splitlines()


def doc_examples() -> list[str]:
    """Every `lanewarden ...` command in a bash block (comments dropped, `&&` chains split)."""
    found = []
    for block in _blocks("bash"):
        for line in _joined_lines(block):
            for part in line.split("&&"):
                command = part.split(" #")[0].strip()
                if command.startswith("lanewarden "):
                    found.append(" ".join(command.split()))
    return list(dict.fromkeys(found))


def argv_of(command: str) -> tuple[list[str], str | None]:
    """Shell words after `lanewarden` (quotes removed, unquoted globs expanded) and the `>`
    redirect target, if any."""
    words = _TOKEN.findall(command)[1:]
    target = None
    if ">" in words:
        target = words[words.index(">") + 1]
        words = words[: words.index(">")]
    argv: list[str] = []
    for word in words:
        if word[0] in "'\"":
            argv.append(word[1:-1])
        elif "*" in word:
            argv.extend(sorted(glob.glob(word)) or [word])
        else:
            argv.append(word)
    return argv, target


#: Flags click refuses at parsing unless they name an existing file.
EXISTING_FILE_FLAGS = ("--calibration", "--config")


def with_named_files(argv: list[str], folder: Path) -> list[str]:
    """`argv` with each file an example names after EXISTING_FILE_FLAGS that is not here (a
    user's own camera.yaml) made, empty, under `folder` and named there: parsing is checked,
    not the files."""
    made = list(argv)
    for i, (flag, value) in enumerate(zip(argv, argv[1:], strict=False)):
        if flag in EXISTING_FILE_FLAGS and not Path(value).exists():
            stand_in = folder / Path(value).relative_to(Path(value).anchor)
            stand_in.parent.mkdir(parents=True, exist_ok=True)
            stand_in.touch()
            made[i + 1] = str(stand_in)
    return made


def parse_only(argv: list[str]) -> click.Context:
    """The real CLI's parsing down to the leaf command, without invoking anything."""
    ctx = cli.make_context("lanewarden", list(argv))
    command: click.Command = cli
    while isinstance(command, click.Group):
        rest = [*getattr(ctx, "_protected_args", []), *ctx.args]
        if not rest:
            break
        name, sub, rest = command.resolve_command(ctx, rest)
        assert sub is not None and name is not None
        ctx = sub.make_context(name, rest, parent=ctx)
        command = sub
    return ctx


def test_every_example_is_accounted_for() -> None:
    listed = [c for c, _ in RUN_HERE] + list(RUN_ELSEWHERE) + list(NEEDS_HARDWARE)
    assert sorted(doc_examples()) == sorted(listed)


def test_ros2_bag_play_of_a_recording_is_never_shown_sending_cmd_vel() -> None:
    """`ros2 bag play` of a whole run.mcap republishes the recorded /cmd_vel, which a live base
    driver obeys: a doc that names it warns of that, and each `ros2 bag play` example plays
    the recorded frames' topic only or moves /cmd_vel away (the topics as run_mcap names
    them, so a renamed topic fails here)."""
    from lanewarden.run_mcap import CMD_VEL_TOPIC, IMAGE_TOPIC, PERCEPTION_TOPIC

    naming = [doc for doc in DOCS if "ros2 bag play" in doc.read_text(encoding="utf-8")]
    assert naming
    for doc in naming:
        text = " ".join(doc.read_text(encoding="utf-8").split())
        assert "`ros2 bag play run.mcap` on its own drives the robot" in text, doc
        assert f"`{CMD_VEL_TOPIC}` included" in text, doc
    plays = [line for block in _blocks("bash") for line in _joined_lines(block)
             if line.strip().startswith("ros2 bag play")]
    assert plays
    for line in plays:
        words = line.split("#")[0].split()
        topics = words[words.index("--topics") + 1:] if "--topics" in words else []
        safe = (topics and set(topics) <= {PERCEPTION_TOPIC, IMAGE_TOPIC}) or any(
            w.startswith(f"{CMD_VEL_TOPIC}:=") for w in words)
        assert safe, line


@pytest.mark.parametrize("command", sorted(NEEDS_HARDWARE))
def test_hardware_examples_parse(command: str, tmp_path: Path) -> None:
    argv, _ = argv_of(command)
    ctx = parse_only(with_named_files(argv, tmp_path))
    assert not isinstance(ctx.command, click.Group) and ctx.params


def test_python_sketches_import_what_they_name() -> None:
    imports = [line for block in _blocks("python") for line in block.splitlines()
               if line.startswith("from lanewarden")]
    assert len(imports) >= 8
    for line in imports:
        exec(line.split("#")[0], {})  # noqa: S102 - a documented import line, nothing else


@pytest.fixture
def sandbox(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A folder with what the examples read: 15 chessboard shots seen by the simulated camera,
    lane frames, a lane photo, and docs/scenarios.md's scenario file as my-track.yaml."""
    monkeypatch.chdir(tmp_path)
    camera = CameraModel()
    board = ChessboardRenderer(camera, columns=9, rows=6, square_m=0.025)
    rng = np.random.default_rng(20240501)
    (tmp_path / "shots").mkdir()
    for i, pose in enumerate(calibration_poses(board, 15, rng)):
        assert cv2.imwrite(f"shots/view_{i:03d}.jpg", board.render(pose, noise_sigma=2.0,
                                                                   rng=rng))
    (tmp_path / "frames").mkdir()
    for name, scene in (("straight", syn.STRAIGHT), ("bend", syn.BEND_LEFT)):
        assert cv2.imwrite(f"frames/{name}.png", syn.frame(scene))
    assert cv2.imwrite("shot.jpg", syn.frame(syn.STRAIGHT, distorted=True))
    floor_board = ChessboardRenderer(camera, columns=9, rows=6, square_m=0.03)
    assert cv2.imwrite("floor.jpg", floor_board.render(floor_board_pose(floor_board, (0.55, 0.0)),
                                                       noise_sigma=2.0, rng=rng))
    scenario = next(b for b in _blocks("yaml") if b.startswith("name: my-track"))
    (tmp_path / "my-track.yaml").write_text(scenario, encoding="utf-8")
    return tmp_path


def test_the_examples_run(sandbox: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Heavy (two closed-loop runs): about 20 s on the development machine."""
    for command, expected in RUN_HERE:
        argv, target = argv_of(command)
        code = main(argv)
        captured = capsys.readouterr()
        assert code == expected, f"{command}: exit {code}\n{captured.err}"
        if target is not None:
            (sandbox / target).write_text(captured.out, encoding="utf-8")
    assert main(["config", "show", "--config", "lanewarden.yaml"]) == 0
    assert len((sandbox / "detections.jsonl").read_text().splitlines()) == 2
    assert (sandbox / "camera.ros.yaml").exists()
    assert "ground_height_m" in (sandbox / "camera.yaml").read_text()
    assert (sandbox / "undistorted" / "view_000_compare.png").exists()
    assert (sandbox / "annotated" / "shot_detect.png").exists()
    assert (sandbox / "out" / "lane-ends" / "video.mp4").exists()


def test_the_scenario_example_meets_its_expectation_with_either_controller(
        sandbox: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "--scenario", "my-track.yaml", "--no-video", "--check", "--quiet",
                 "--controller", "lecture"]) == 0, capsys.readouterr().err


def _help_examples() -> list[str]:
    """The `lanewarden ...` example lines of every command's --help."""
    found = []
    pending: list[tuple[list[str], click.Command]] = [([], cli)]
    while pending:
        path, command = pending.pop()
        ctx = click.Context(command, info_name=" ".join(["lanewarden", *path]))
        for line in _joined_lines(command.get_help(ctx)):
            text = line.strip().removeprefix("Example: ")
            if text.startswith("lanewarden "):
                found.append(text.split("&&")[0].strip())
        if isinstance(command, click.Group):
            pending += [([*path, name], command.commands[name]) for name in command.commands]
    return sorted(found)


def test_every_help_example_parses(tmp_path: Path) -> None:
    examples = _help_examples()
    assert len(examples) == 31
    for example in examples:
        argv, _ = argv_of(example)
        # parsed down to the command that runs
        assert parse_only(with_named_files(argv, tmp_path)).params, example
