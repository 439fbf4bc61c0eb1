"""README's "Try it without a robot", run as written in an empty folder, as a new user would from a
fresh clone: every `lanewarden` line of its block, in order, with no file from anywhere else.

Only two things differ from a user's terminal: the live camera line (`--camera 0`) is not run
(on a developer's machine it may be a real webcam; tests/test_docs_examples.py parses it), and
`--view 8080` serves on a free port instead (8080 may be taken on a test machine; the page itself
is tested in test_live_page_browser.py). The run is real time on a loaded machine, so what it
must show is the documented outcome class (engaged, then a safety stop when the tape ends: exit
3), not one halt reason."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from lanewarden.cli import main
from tests.conftest import PROJECT_ROOT
from tests.operator.runs import free_port
from tests.test_docs_examples import argv_of

SECTION = "## Try it without a robot"
#: README's exit code for each line (by its subcommand).
EXPECTED_EXIT = {"sim": 0, "run": 3, "replay": 0}


def readme_block() -> list[str]:
    """The `lanewarden` lines of the section's bash block (continuations joined, comments
    dropped)."""
    text = (PROJECT_ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index(SECTION):]
    block = re.search(r"```bash\n(.*?)```", section, re.S)
    assert block is not None
    lines = block.group(1).replace("\\\n", " ").splitlines()
    return [" ".join(line.split(" #")[0].split()) for line in lines
            if line.strip().startswith("lanewarden ")]


def test_the_readme_block_works_as_written_from_an_empty_folder(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    commands = readme_block()
    assert [c.split()[1] for c in commands] == ["sim", "run", "replay", "run"]
    for command in commands:
        argv, _ = argv_of(command)
        if "--camera" in argv and argv[argv.index("--camera") + 1] == "0":
            continue  # the live camera
        if "--view" in argv:
            argv[argv.index("--view") + 1] = str(free_port())
        code = main(argv)
        out, err = capsys.readouterr()
        assert code == EXPECTED_EXIT[argv[0]], f"{command}: exit {code}\n{out[-3000:]}\n{err}"
        if argv[0] == "sim":
            assert "  camera clip: clip.mp4 (640x480, 30 fps, " in out
            assert Path("clip.mp4").stat().st_size > 0 and Path("clip.calibration.yaml").exists()
        elif argv[0] == "run":
            summary = json.loads(Path("runs/first/summary.json").read_text())
            assert summary["end"]["engaged"] and "FOLLOW" in summary["states_visited"]
            assert summary["end_reason"].startswith("safety stop: ")
            # what perception gave the supervisor before that stop, as replay and sim say it
            assert "\n  before the halt: last 2 s: " in out, out[-2000:]
            assert err == f"lanewarden: {summary['end_reason']}\n"
        else:
            metrics = json.loads(Path("lanewarden-out/replay-first/metrics.json").read_text())
            assert Path("lanewarden-out/replay-first/report.html").exists()
            if metrics["exact_input"]:
                assert metrics["reproduced"], out
                assert metrics["end_reason"] == summary["end_reason"]
            else:  # a loaded machine's recorder dropped frames: replay says it cannot be exact
                assert summary["frames_dropped"] > 0
                assert "the replay cannot be exact" in out
