"""A damaged results.sqlite and hostile campaign sizes: one line, exit 2, nothing stored lost.

- a damaged page is refused before anything runs, and the file is left exactly as it was;
- `--recover` keeps it as results.sqlite.damaged, carries every readable run over and reruns
  only what was lost;
- a row that cannot be stored (the file goes bad during the campaign) is kept beside it and
  stored by the next campaign, never run again;
- `--runs` above the documented maximum, or below the runs the directory holds, is one line
  before anything is drawn.

Time and memory of these refusals are measured by benchmarks/campaign_limits.py (not asserted)."""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from lanewarden.cli import main
from lanewarden.scenarios.campaign import runner as runner_module
from lanewarden.scenarios.campaign.cases import load_campaign_spec, spec_fingerprint
from lanewarden.scenarios.campaign.store import ResultStore

RUNS = 40
PAGE = 4096
REAL_RUN_CASE = runner_module.run_case


def stored_row(index: int) -> dict[str, Any]:
    """A finished run's row as a campaign stores it (metrics of a realistic size), marked as
    made here (`worker`), so a row carried over is told from one run again."""
    return {"id": f"r{index:05d}", "idx": index, "scenario": "short-straight",
            "camera": "small", "seed": index % 2, "fault_kinds": "bumper", "outcome": "nominal",
            "reason": "followed the lane throughout", "halt_reason": None, "halt_time_s": None,
            "time_to_halt_s": None, "sim_time_s": 3.5, "frames": 106, "cpu_s": 1.0,
            "wall_s": 1.1, "worker": "made-by-the-test",
            "metrics_json": json.dumps({"note": "x" * 1500, "index": index}),
            "effects_json": "[]"}


def campaign_dir(tmp_path: Path, tiny_spec: Path, seed: int = 7) -> Path:
    """A campaign directory whose results.sqlite holds RUNS finished runs of `tiny_spec`."""
    out = tmp_path / "out"
    out.mkdir()
    spec, _ = load_campaign_spec(str(tiny_spec))
    with ResultStore(out / "results.sqlite") as store:
        store.claim({"spec": spec_fingerprint(spec, {}), "seed": str(seed)})
        for index in range(RUNS):
            store.put(stored_row(index))
    return out


def damage_page(path: Path, page: int) -> None:
    """Overwrite one page with garbage (and tell other connections the file changed)."""
    data = bytearray(path.read_bytes())
    assert len(data) >= (page + 1) * PAGE
    data[page * PAGE:(page + 1) * PAGE] = bytes((i * 37 + 11) % 256 for i in range(PAGE))
    data[24:28] = (int.from_bytes(data[24:28], "big") + 1).to_bytes(4, "big")
    path.write_bytes(bytes(data))


def counting(ran: list[str]) -> Callable[[str, object], dict[str, object]]:
    """The real `run_case`, noting which cases ran."""

    def run(case_json: str, build_stack: object) -> dict[str, object]:
        ran.append(json.loads(case_json)["id"])
        return REAL_RUN_CASE(case_json, build_stack)  # type: ignore[arg-type]

    return run


def args(tiny_spec: Path, out: Path, *extra: str) -> list[str]:
    return ["campaign", "--spec", str(tiny_spec), "--out", str(out), "--seed", "7", "--runs",
            str(RUNS), "--scheduler", "in-process", "--quiet", *extra]


def test_a_damaged_page_is_one_line_and_the_file_is_left_as_it_was(
        tiny_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = campaign_dir(tmp_path, tiny_spec)
    damage_page(out / "results.sqlite", 8)
    before = (out / "results.sqlite").read_bytes()
    assert main(args(tiny_spec, out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith(f"lanewarden: error: {out / 'results.sqlite'}: the results database "
                             "is damaged (")
    assert err[0].endswith("nothing was changed: run the same command with --recover to keep it "
                           "as results.sqlite.damaged, carry over every run that can still be "
                           "read and rerun the rest")
    assert (out / "results.sqlite").read_bytes() == before
    assert not (out / "cases").exists(), "refused before anything was drawn or run"


@pytest.mark.parametrize("content", [b"not a database at all" * 300, b"SQLite format 3\0" + bytes(
    PAGE * 3)])
def test_a_file_that_is_no_database_is_one_line(
        content: bytes, tiny_spec: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.sqlite").write_bytes(content)
    assert main(args(tiny_spec, out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the results database is damaged (" in err[0]
    assert (out / "results.sqlite").read_bytes() == content


def test_recover_carries_every_readable_run_over_and_reruns_only_the_lost(
        tiny_spec: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = campaign_dir(tmp_path, tiny_spec)
    damage_page(out / "results.sqlite", 8)
    damaged = (out / "results.sqlite").read_bytes()
    ran: list[str] = []
    monkeypatch.setattr(runner_module, "run_case", counting(ran))
    assert main(args(tiny_spec, out, "--recover")) == 0
    err = capsys.readouterr().err
    assert (out / "results.sqlite.damaged").read_bytes() == damaged, "kept as it was"
    with sqlite3.connect(out / "results.sqlite") as db:
        rows = {r[0]: r[1:] for r in db.execute("SELECT id, worker, metrics_json FROM runs")}
    assert sorted(rows) == [f"r{i:05d}" for i in range(RUNS)]
    carried = [i for i, (worker, _) in rows.items() if worker == "made-by-the-test"]
    assert 1 <= len(ran) <= 6, "one damaged page holds a few rows: only those run again"
    assert sorted(ran) == sorted(set(rows) - set(carried))
    for id_ in carried:  # carried over exactly as stored
        assert rows[id_][1] == stored_row(int(id_[1:]))["metrics_json"]
    assert (f"campaign tiny: the damaged results database is kept as "
            f"{out / 'results.sqlite.damaged'}; {len(carried)} stored runs carried over") in err


def test_a_row_that_cannot_be_stored_is_kept_and_never_run_again(
        tiny_spec: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The file goes bad while the campaign runs: the finished run's row is kept beside it
    (results.sqlite.unstored.jsonl), the campaign stops in one line (exit 2), and the next
    campaign stores that row without running it again."""
    out = tmp_path / "out"
    ran: list[str] = []

    def damaging(case_json: str, build_stack: object) -> dict[str, object]:
        ran.append(json.loads(case_json)["id"])
        row = REAL_RUN_CASE(case_json, build_stack)  # type: ignore[arg-type]
        if len(ran) == 2:  # the disk goes bad under the campaign
            damage_page(out / "results.sqlite", 1)
        return row

    monkeypatch.setattr(runner_module, "run_case", damaging)
    small = ["campaign", "--spec", str(tiny_spec), "--out", str(out), "--seed", "7", "--runs",
             "3", "--scheduler", "in-process", "--quiet"]
    assert main(small) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == "campaign tiny: 3 runs (seed 7), 0 already stored; running in this process"
    err = err[1:]
    unstored = out / "results.sqlite.unstored.jsonl"
    second = ran[1]
    assert len(err) == 1 and err[0].startswith(
        f"lanewarden: error: {out / 'results.sqlite'}: cannot store run {second} (")
    assert f"its result is kept in {unstored}" in err[0]
    kept = [json.loads(line) for line in unstored.read_text().splitlines()]
    assert [row["id"] for row in kept] == [second]

    ran.clear()
    monkeypatch.setattr(runner_module, "run_case", counting(ran))
    assert main([*small, "--recover"]) == 0
    assert ("campaign tiny: stored now what an earlier campaign could not store (1 run)"
            in capsys.readouterr().err)
    assert second not in ran, "its stored result was not lost, so it does not run again"
    assert not unstored.exists()
    with sqlite3.connect(out / "results.sqlite") as db:
        assert sorted(r[0] for r in db.execute("SELECT id FROM runs")) == [
            "r00000", "r00001", "r00002"]


def test_fewer_runs_than_the_directory_holds_is_refused_and_nothing_changes(
        tiny_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`--runs 4`, then `--runs 2` into the same --out: report.html and junit.xml were rewritten
    with 2 runs while results.sqlite kept 4 (a new user's trial). --runs is the campaign's size:
    a smaller one than the directory holds is one line, exit 2, before anything is written."""
    out = campaign_dir(tmp_path, tiny_spec)

    def stored() -> list[tuple[object, ...]]:
        with sqlite3.connect(out / "results.sqlite") as db:
            return db.execute("SELECT * FROM runs ORDER BY idx").fetchall()

    before = stored()
    small = args(tiny_spec, out)
    small[small.index("--runs") + 1] = "2"
    assert main(small) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"lanewarden: error: --runs 2: {out / 'results.sqlite'} already holds 40 runs of this "
        "campaign, up to r00039; expected --runs 40 or more (the report covers every stored "
        "run), or another --out for a smaller campaign"]
    assert stored() == before
    assert sorted(p.name for p in out.iterdir()) == ["results.sqlite"], "nothing drawn or written"
    # no --runs: its default (100) is refused the same way, and said to be the default
    with ResultStore(out / "results.sqlite") as store:
        store.put(stored_row(150))
    at = small.index("--runs")
    assert main(small[:at] + small[at + 2:]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"lanewarden: error: --runs 100 (the default): {out / 'results.sqlite'} already holds 41 "
        "runs of this campaign, up to r00150; expected --runs 151 or more (the report covers "
        "every stored run), or another --out for a smaller campaign"]
    assert sorted(p.name for p in out.iterdir()) == ["results.sqlite"]


@pytest.mark.parametrize("runs", ["100001", "1000000", "1000000000000"])
def test_a_hostile_campaign_size_is_one_line_before_anything_is_drawn(
        runs: str, tiny_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["campaign", "--spec", str(tiny_spec), "--out", str(out), "--runs", runs,
                 "--scheduler", "in-process"]) == 2
    assert capsys.readouterr().err == (
        f"lanewarden: error: lanewarden campaign: Invalid value for '--runs': {runs}: expected "
        "an integer with 1 <= value <= 100000\n")
    assert not out.exists()


def test_the_largest_campaign_draws_only_what_it_runs_next(
        tiny_spec: Path, tmp_path: Path) -> None:
    """100,000 runs: the first cases come at once (a first batch of 4), nothing is drawn ahead
    of the runs beyond one batch, and only the cases drawn have files."""
    spec, path = load_campaign_spec(str(tiny_spec))
    plan = runner_module.CampaignPlan(
        build_stack=runner_module.run_case, spec=spec, spec_path=path,  # type: ignore[arg-type]
        seed=7, runs=runner_module.MAX_RUNS, out_dir=tmp_path, config_overrides={},
        follow_speed_m_s=0.2)
    cases = runner_module.pending_cases(plan, done={"r00001"}, batch=16)
    first = [next(cases) for _ in range(3)]
    assert sorted(c.id for c in first) == ["r00000", "r00002", "r00003"]
    assert sorted(p.name for p in (tmp_path / "cases").iterdir()) == [
        "r00000.yaml", "r00002.yaml", "r00003.yaml"]
    next(cases)  # the next batch of 16 is drawn when the runs need it
    assert len(list((tmp_path / "cases").iterdir())) == 3 + 16
