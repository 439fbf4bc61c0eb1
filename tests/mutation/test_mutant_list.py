"""The mutation list stays true to the code: every listed original snippet is found exactly once in
its file and every mutated file compiles (the full mutation run, which applies them, is
`python -m tests.mutation.run`: see DEVELOPERS.md). A change to a safety rule's code fails here
first, in the ordinary test run, naming the mutant to update."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.mutation.run import load, stale

SAFETY_FILES = {
    "supervisor/gate.py", "supervisor/limiter.py", "actuation/kobuki_geometry.py",
    "supervisor/hazards.py", "supervisor/watchdog.py", "supervisor/controller.py",
    "supervisor/events.py", "supervisor/state_machine.py", "actuation/deadman_logic.py",
    "perception/tape_rules.py", "lanewarden/live_view.py", "lanewarden/operator.py",
    "supervisor/lane_evidence.py", "supervisor/commands.py", "supervisor/loop.py",
    "perception/confidence.py", "perception/lines.py", "perception/line_kernel.py",
    "perception/one_side.py",
    "perception/edge_choice.py", "lanewarden/survey.py", "supervisor/center_offset.py",
    "perception/detector.py", "lanewarden/runner.py", "lanewarden/survey_run.py",
    "lanewarden/commands/base.py", "supervisor/slope_filter.py", "actuation/kobuki_port.py",
    "actuation/kobuki_base.py",
}  # fmt: skip


def test_every_listed_mutant_still_matches_the_code() -> None:
    assert stale(load()) == []


def test_the_list_covers_every_safety_file_with_fast_tests() -> None:
    mutants = load()
    assert {m.file for m in mutants} == SAFETY_FILES
    assert 30 <= len(mutants) <= 160  # (the CI run: about 3 s a mutant on 2 cores)
    for m in mutants:
        for test in m.tests:
            assert Path(test.split("::")[0]).parts[0] == "tests", (m.id, test)


def test_a_stale_or_broken_mutant_is_named(tmp_path: Path) -> None:
    (tmp_path / "rule.py").write_text("def allowed(x):\n    return x < 3\n", encoding="utf-8")
    listed = tmp_path / "mutants.toml"
    listed.write_text(
        '[[mutant]]\nid = "gone"\nfile = "rule.py"\nrule = "r"\noriginal = "x <= 3"\n'
        'replacement = "True"\ntests = ["tests/x.py"]\n'
        '[[mutant]]\nid = "broken"\nfile = "rule.py"\nrule = "r"\noriginal = "x < 3"\n'
        'replacement = "x <"\ntests = ["tests/x.py"]\n', encoding="utf-8")
    problems = stale(load(listed), root=tmp_path)
    assert problems == [
        "gone: the original snippet is not found in rule.py (the code changed: update "
        "tests/mutation/mutants.toml): x <= 3",
        "broken: the mutated rule.py does not compile (invalid syntax, line 2)",
    ]
    listed.write_text('[[mutant]]\nid = "a"\nfile = "rule.py"\noriginal = "x"\n', encoding="utf-8")
    with pytest.raises(ValueError, match=r"mutant #1 \(a\): fields"):
        load(listed)
