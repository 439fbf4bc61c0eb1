"""A campaign draws floors, tapes and camera effects besides faults: each case carries them (and
runs them), a tape is only laid on the floors it lists, a spec without them draws exactly the
cases it drew before they existed, the results store and the report name them."""

from __future__ import annotations

import sqlite3
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
import yaml

from lanewarden.scenarios.campaign.cases import MAX_LISTED, draw_case, load_campaign_spec
from lanewarden.scenarios.campaign.report import summarize, write_report
from lanewarden.scenarios.campaign.store import ResultStore
from lanewarden.scenarios.errors import ScenarioError
from tests.campaign.conftest import TINY_SPEC

LOOKS = """\
floors:
  - {name: scenario, weight: 1}
  - {name: foam-mats, weight: 2, floor: {kind: foam}}
  - {name: terrazzo, weight: 2, floor: {kind: terrazzo, tile_m: 0.5}}
tapes:
  - {name: scenario, floors: [scenario]}
  - name: white-dashed
    tape: {color: "#eeeeea"}
    lane: {dashes: {tape: left, on_m: 0.3, off_m: 0.2}}
    floors: [foam-mats]
  - name: black
    tape: {color: "#151515", sheen: 0.5}
    floors: [foam-mats, terrazzo]
    config: {perception: {tape: {width_m: 0.048}}}
effects:
  - {name: default}
  - {name: dim, lighting: {brightness: 0.2}}
  - {name: mjpeg, camera: {compression: {format: jpeg, quality: 40}}}
"""


def spec_file(tmp_path: Path, extra: str = LOOKS) -> Path:
    (tmp_path / "short-straight.yaml").write_text(
        "name: short-straight\nlane:\n  segments:\n    - straight_m: 4.0\nrun:\n"
        "  max_time_s: 3.5\n", encoding="utf-8")
    path = tmp_path / "spec.yaml"
    path.write_text(TINY_SPEC + extra, encoding="utf-8")
    return path


def cases(path: Path, n: int = 60) -> list[Any]:
    spec, where = load_campaign_spec(str(path))
    return [draw_case(spec, where, 7, i, {}, 0.15) for i in range(n)]


def test_each_case_carries_its_floor_tape_and_effect(tmp_path: Path) -> None:
    drawn = cases(spec_file(tmp_path))
    pairs = Counter((c.floor, c.tape) for c in drawn)
    # a tape only on the floors it lists
    assert set(pairs) <= {("scenario", "scenario"), ("foam-mats", "white-dashed"),
                          ("foam-mats", "black"), ("terrazzo", "black")}
    assert len(pairs) == 4 and {c.effect for c in drawn} == {"default", "dim", "mjpeg"}
    for case in drawn:
        scenario = case.scenario
        if case.floor == "terrazzo":
            assert scenario["floor"] == {"kind": "terrazzo", "tile_m": 0.5}
        if case.floor == "scenario":
            assert "floor" not in scenario and "tape" not in scenario
        if case.tape == "white-dashed":
            assert scenario["lane"]["dashes"]["tape"] == "left"
            assert scenario["lane"]["segments"] == [{"straight_m": 4.0}]
        if case.tape == "black":
            assert case.config["perception"] == {"tape": {"width_m": 0.048}}
        if case.effect == "dim":
            assert scenario["lighting"]["brightness"] == 0.2
        if case.effect == "mjpeg":
            assert scenario["camera"]["compression"] == {"format": "jpeg", "quality": 40}
        spec = case.scenario_spec()
        assert spec.floor.kind == {"scenario": "tiles", "foam-mats": "foam",
                                   "terrazzo": "terrazzo"}[case.floor]


def test_looks_do_not_change_what_else_a_case_draws(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    plain = cases(spec_file(tmp_path / "a", ""), 30)
    dressed = cases(spec_file(tmp_path / "b"), 30)
    for a, b in zip(plain, dressed, strict=True):
        assert (a.seed, a.camera, a.fault_kinds) == (b.seed, b.camera, b.fault_kinds)
        assert a.scenario["faults"] == b.scenario["faults"]
        assert (a.floor, a.tape, a.effect) == ("scenario", "scenario", "default")


def test_a_bad_look_is_refused_at_load_with_its_key(tmp_path: Path) -> None:
    bad = LOOKS.replace("kind: terrazzo, tile_m: 0.5", "kind: marble")
    with pytest.raises(ScenarioError, match=r"floors\.2 \(terrazzo\).*floor\.kind"):
        load_campaign_spec(str(spec_file(tmp_path, bad)))
    unknown = LOOKS.replace("floors: [foam-mats, terrazzo]", "floors: [foam-mats, lino]")
    with pytest.raises(ScenarioError, match=r"tapes\.2\.floors: \['lino'\]"):
        load_campaign_spec(str(spec_file(tmp_path, unknown)))


def test_a_bad_config_override_is_refused_at_load_not_in_every_run(tmp_path: Path) -> None:
    # Each was a run-time ConfigError in every run that drew it: a campaign of errors, exit 0.
    bad = LOOKS.replace("{perception: {tape: {width_m: 0.048}}}",
                        "{perception: {tape: {width_mm: 48}}}")
    with pytest.raises(ScenarioError, match=r"spec\.yaml: tapes\.2 \(black\).*unknown key "
                       r"'perception\.tape\.width_mm'"):
        load_campaign_spec(str(spec_file(tmp_path, bad)))
    top = spec_file(tmp_path, LOOKS + "config: {supervisor: {follow_speed: 0.1}}\n")
    with pytest.raises(ScenarioError, match=r"spec\.yaml: config: unknown key "
                       r"'supervisor\.follow_speed'") as raised:
        load_campaign_spec(str(top))
    assert len(str(raised.value).splitlines()) == 1  # not once more for every piece over it
    camera = yaml.safe_load(spec_file(tmp_path).read_text(encoding="utf-8"))
    camera["cameras"][0]["simulation"] = {"noise_sigma_levels": 4}
    (tmp_path / "spec.yaml").write_text(yaml.safe_dump(camera), encoding="utf-8")
    with pytest.raises(ScenarioError, match=r"cameras\.0 \(.*\).*unknown key "
                       r"'simulation\.noise_sigma_levels'"):
        load_campaign_spec(str(tmp_path / "spec.yaml"))


def test_every_option_of_a_fault_parameter_is_checked_at_load(tmp_path: Path) -> None:
    """Three random draws let {one_of: [2, 99]} through (99 bumper bits); run 0 then failed."""
    spec = yaml.safe_load(spec_file(tmp_path).read_text(encoding="utf-8"))
    spec["faults"] = [{"kind": "bumper", "params": {"bits": {"one_of": [2] * 30 + [99]}}}]
    (tmp_path / "spec.yaml").write_text(yaml.safe_dump(spec), encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_campaign_spec(str(tmp_path / "spec.yaml"))
    # worded as a scenario file's problem is (it had been "faults.0 (bumper): bits = 99: Input
    # should be less than or equal to 7")
    assert str(info.value) == (f"{tmp_path / 'spec.yaml'}: faults.0.params.bits = 99: expected "
                               "an integer with 1 <= value <= 7")


def test_the_default_spec_draws_floors_tapes_and_effects() -> None:
    spec, where = load_campaign_spec("default")
    drawn = [draw_case(spec, where, 0, i, {}, 0.15) for i in range(200)]
    floors = Counter(c.floor for c in drawn)
    assert {"scenario", "terrazzo", "ceramic", "foam-mats", "parquet", "carpet",
            "concrete"} <= set(floors)
    assert len({c.effect for c in drawn}) >= 6
    for case in drawn:  # the scenario's own tape stays on the scenario's own floor
        assert (case.floor == "scenario") == (case.tape == "scenario")


def test_results_and_report_name_the_floor_tape_and_effect(tmp_path: Path) -> None:
    # a results file from before these columns existed takes them
    old = tmp_path / "results.sqlite"
    db = sqlite3.connect(old)
    db.execute("CREATE TABLE runs (id TEXT PRIMARY KEY, idx INTEGER, scenario TEXT, camera TEXT,"
               " seed INTEGER, fault_kinds TEXT, outcome TEXT, reason TEXT, halt_reason TEXT, "
               "halt_time_s REAL, time_to_halt_s REAL, sim_time_s REAL, frames INTEGER, "
               "cpu_s REAL, wall_s REAL, worker TEXT, metrics_json TEXT, effects_json TEXT)")
    db.execute("INSERT INTO runs (id, idx, scenario, camera, outcome) VALUES "
               "('r00000', 0, 'straight', 'small', 'nominal')")
    db.commit()
    db.close()
    rows: list[dict[str, Any]] = [
        {"id": "r00001", "idx": 1, "scenario": "straight", "camera": "small", "floor": "carpet",
         "tape": "white", "effect": "dim", "seed": 0, "fault_kinds": "bumper",
         "outcome": "safe_halt"},
        {"id": "r00002", "idx": 2, "scenario": "straight", "camera": "small", "floor": "carpet",
         "tape": "black", "effect": "default", "seed": 0, "fault_kinds": "camera_drop",
         "outcome": "false_halt"}]
    with ResultStore(old) as store:
        for row in rows:
            store.put(row)
        stored = store.rows()
    assert [(r["id"], r["floor"], r["effect"]) for r in stored] == [
        ("r00000", None, None), ("r00001", "carpet", "dim"), ("r00002", "carpet", "default")]
    report = tmp_path / "report.html"
    write_report(report, "t", summarize(stored), tmp_path, "summary")
    text = report.read_text(encoding="utf-8")
    assert "<h2>Floor x outcome</h2>" in text and "<h2>Camera effect x outcome</h2>" in text
    floor_table = text.split("<h2>Floor x outcome</h2>")[1].split("</table>")[0]
    # carpet: one safe halt, one false halt (in the outcome columns' order), two runs
    assert "<th>carpet</th><td style=\"color:#2e7d32;font-weight:bold\">" not in floor_table
    assert "<th>carpet</th><td>1</td><td></td><td></td>" in floor_table
    assert floor_table.count("<th>?</th>") == 1  # the old row, from before floors


def test_a_spec_without_looks_reports_no_look_tables(tmp_path: Path) -> None:
    rows = [{"id": "r00001", "idx": 1, "scenario": "straight", "camera": "small",
             "floor": "scenario", "tape": "scenario", "effect": "default", "seed": 0,
             "fault_kinds": "bumper", "outcome": "safe_halt"}]
    report = tmp_path / "report.html"
    write_report(report, "t", summarize(rows), tmp_path, "summary")
    assert "Floor x outcome" not in report.read_text(encoding="utf-8")


def test_case_files_round_trip_the_looks(tmp_path: Path) -> None:
    case = next(c for c in cases(spec_file(tmp_path)) if c.floor == "terrazzo")
    from lanewarden.scenarios.campaign.cases import case_yaml, load_case

    path = tmp_path / "case.yaml"
    path.write_text(case_yaml(case), encoding="utf-8")
    again = load_case(path)
    assert (again.floor, again.tape, again.effect) == (case.floor, case.tape, case.effect)
    assert yaml.safe_load(path.read_text())["scenario"]["floor"]["kind"] == "terrazzo"


def test_a_case_files_seed_is_bounded_as_the_seed_flag_is(tmp_path: Path) -> None:
    """`--seed` takes 0 to 2**32 - 1; a case file's seed of 10**39 had been taken (an attacker's
    review)."""
    from lanewarden.scenarios.campaign.cases import case_yaml, load_case

    case = cases(spec_file(tmp_path), n=1)[0]
    path = tmp_path / "case.yaml"
    document = yaml.safe_load(case_yaml(case))
    for key in ("seed", "campaign_seed"):
        path.write_text(yaml.safe_dump({**document, key: 10**39}), encoding="utf-8")
        with pytest.raises(ScenarioError) as info:
            load_case(path)
        assert str(info.value) == (f"{path}: {key} = 1000000000000000000000000000000000000000: "
                                   "expected an integer with 0 <= value <= 4294967295")
    path.write_text(yaml.safe_dump({**document, "seed": 2**32 - 1}), encoding="utf-8")
    assert load_case(path).seed == 2**32 - 1


def _refused(tmp_path: Path, **changes: object) -> tuple[Path, list[str]]:
    """The test spec with `changes`, written and loaded: its file, and the lines refusing it."""
    spec = yaml.safe_load(spec_file(tmp_path).read_text(encoding="utf-8"))
    spec.update(changes)
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_campaign_spec(str(path))
    return path, str(info.value).splitlines()


def _keys(lines: list[str]) -> list[str]:
    """The key each line names ('/x/spec.yaml: faults.0.kind = ...' -> 'faults.0.kind')."""
    return [line.split(": ")[1].split(" =")[0] for line in lines]


@pytest.mark.parametrize(("kind", "said"), [
    ("camera_freez", "faults.0.kind = 'camera_freez': did you mean 'camera_freeze'? (input "
                     "should be 'camera_freeze', 'camera_ring', "),
    ("xyzzy", "faults.0.kind = 'xyzzy': input should be 'camera_freeze', 'camera_ring', "),
])
def test_a_misspelt_fault_kind_gets_the_closest_one_first(tmp_path: Path, kind: str,
                                                          said: str) -> None:
    """A safety reviewer's review: a misspelt kind listed all 26 and suggested none, where a
    misspelt scenario or config key gets 'did you mean'."""
    path, lines = _refused(tmp_path, faults=[{"kind": kind}])
    assert "\n".join(lines).startswith(f"{path}: {said}"), lines


def test_every_problem_of_a_spec_is_said_at_once(tmp_path: Path) -> None:
    """A safety reviewer's spec with several typos took two rounds: the scenario names and the
    fault parameters were checked only once the spec's own structure passed."""
    path, lines = _refused(
        tmp_path, controller="superviesd",  # a structural problem ...
        scenarios=["lane-end"],  # ... and the two kinds checked after it
        faults=[{"kind": "glare_sweep", "params": {"intensity": [0.5, 2.0]}}])
    assert _keys(lines) == ["controller", "scenarios.0", "faults.0.params.intensity"], lines
    assert lines[2] == (f"{path}: faults.0.params.intensity = 2.0: expected a finite number with "
                        "0 <= value <= 1")


def test_a_list_longer_than_a_spec_may_hold_is_not_checked_entry_by_entry(tmp_path: Path) -> None:
    """The checks beside a failing spec are bounded as the spec is: 60 000 scenario names had
    been resolved one by one (41 s) after the line that refused their number."""
    path, lines = _refused(tmp_path, controller="superviesd",
                           scenarios=["lane-end"] * (MAX_LISTED + 1))
    assert _keys(lines) == ["controller", "scenarios"], lines
    assert lines[1] == (f"{path}: scenarios = a list of {MAX_LISTED + 1} items: list should have "
                        f"at most {MAX_LISTED} items after validation, not {MAX_LISTED + 1}")
