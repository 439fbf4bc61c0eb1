"""A command's --out folder that holds another command's outputs is refused before any work (a
safety reviewer's review: `sim --out` into a campaign's folder replaced the campaign's
report.html without a word, and `campaign --out` into a run's folder the run's report)."""

from __future__ import annotations

from pathlib import Path

import pytest

from lanewarden.cli import main
from tests.conftest import PROJECT_ROOT

#: The file that tells each command's outputs, as written out in the error.
HELD = {
    "campaign": ("results.sqlite", "a campaign's results"),
    "run": ("metrics.json", "a simulated or replayed run's outputs"),
    "demo": ("supervised/metrics.json", "the demo's outputs"),
    "survey": ("survey.json", "a survey's outputs"),
}


def _argv(command: str, out: Path) -> list[str]:
    return {
        "sim": ["sim", "--scenario", "fault-bumper", "--no-video", "--quiet", "--out", str(out)],
        "demo": ["demo", "--no-video", "--quiet", "--out", str(out)],
        "campaign": ["campaign", "--spec", "default", "--runs", "1", "--quiet", "--out",
                     str(out)],
        "replay": ["replay", "nothing-to-replay", "--out", str(out)],
        "survey": ["survey", str(PROJECT_ROOT / "data" / "survey" / "rendered"), "--out", str(out)],
    }[command]


@pytest.mark.parametrize(("command", "held"), [
    ("sim", "campaign"), ("sim", "demo"), ("sim", "survey"),
    ("replay", "campaign"), ("replay", "survey"),
    ("campaign", "run"), ("campaign", "demo"),
    ("demo", "run"), ("demo", "campaign"),
    ("survey", "run"), ("survey", "campaign"),
])
def test_another_commands_outputs_are_refused(command: str, held: str, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    marker, what = HELD[held]
    (out / marker).parent.mkdir(parents=True)
    (out / marker).write_text("kept\n")
    assert main(_argv(command, out)) == 2
    err = capsys.readouterr().err
    assert err == (f"lanewarden: error: --out '{out}': holds {what} ({marker}), which these "
                   "outputs would mix with or replace; expected a new folder, or one this "
                   "command wrote before\n")
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()) == [
        marker]  # nothing written, nothing replaced
    assert (out / marker).read_text() == "kept\n"
