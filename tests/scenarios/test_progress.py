"""Progress of demo, sim, campaign and replay when nobody watches a terminal (a pipe, a CI log,
`| tee`): a complete line every few seconds, on a fake clock; the bar stays on a terminal."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from lanewarden.cli import main
from lanewarden.scenarios import progress as progress_module
from lanewarden.scenarios.progress import Progress


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _progress(stream: io.StringIO, clock: FakeClock, total: int = 20,
              **options: object) -> Progress:
    return Progress(total, "campaign default", "runs", stream=stream, clock=clock,
                    terminal=False, **options)  # type: ignore[arg-type]


def test_without_a_terminal_a_line_after_one_second_then_every_five() -> None:
    stream, clock = io.StringIO(), FakeClock()
    progress = _progress(stream, clock)
    clock.now += 0.5
    progress.update()
    assert stream.getvalue() == "", "nothing in the first second"
    clock.now += 0.5
    progress.set_postfix("safe_halt=2")
    progress.update()
    clock.now += 2.0
    progress.update()  # not due yet
    clock.now += 3.0
    progress.update(2)  # 5 done in 6 s
    clock.now += 30.0
    progress.update(15)
    progress.close()
    assert stream.getvalue().splitlines() == [
        "campaign default: 2/20 runs (10%), 2 runs/s, ETA 9 s  safe_halt=2",
        "campaign default: 5/20 runs (25%), 0.83 runs/s, ETA 18 s  safe_halt=2",
        "campaign default: 20/20 runs (100%), 0.56 runs/s, ETA 0 s  safe_halt=2",
        "campaign default: done, 20/20 runs in 36 s  safe_halt=2",
    ]


def test_short_work_prints_nothing_and_a_resumed_count_starts_the_rate_anew() -> None:
    stream, clock = io.StringIO(), FakeClock()
    with _progress(stream, clock) as progress:
        clock.now += 0.4
        progress.update()
    assert stream.getvalue() == ""
    resumed = _progress(stream, clock, initial=10)
    clock.now += 2.0
    resumed.update()
    assert stream.getvalue() == "campaign default: 11/20 runs (55%), 0.5 runs/s, ETA 18 s\n"


def test_a_resumed_campaign_says_it_is_estimating_until_a_run_of_this_session_ends() -> None:
    """The review's resumed campaign printed '6/16 runs (38%), 0 runs/s, ETA unknown' twice."""
    stream, clock = io.StringIO(), FakeClock()
    progress = _progress(stream, clock, total=16, initial=6)
    clock.now += 1.0
    progress.tick()
    clock.now += 5.0
    progress.tick()
    clock.now += 14.0
    progress.update()  # the first run of this session, 20 s in
    clock.now += 20.0
    progress.update()
    assert stream.getvalue().splitlines() == [
        "campaign default: 6/16 runs (38%), estimating the time left (1 s so far)",
        "campaign default: 6/16 runs (38%), estimating the time left (6 s so far)",
        "campaign default: 7/16 runs (44%), 0.05 runs/s, ETA 3 min 00 s",
        "campaign default: 8/16 runs (50%), 0.05 runs/s, ETA 2 min 40 s",
    ]


def test_a_bounded_total_measured_from_the_first_step_and_minutes() -> None:
    """A simulation: 10 s of set-up, then 1 s simulated per second. Counted from the start, the
    first estimate was 5.5 s simulated in 15 s, ETA 'at most' 27 min (the review's demo: 'at
    most 5 min 46 s', then done in 18 s)."""
    stream, clock = io.StringIO(), FakeClock()
    progress = Progress(600.0, "lecture/supervised", "s simulated", stream=stream, clock=clock,
                        terminal=False, fmt="{:.1f}", at_most=605.5, warm_up=True)
    clock.now += 10.0
    progress.advance_to(0.5)
    clock.now += 5.0
    progress.advance_to(5.5)
    clock.now += 5.0
    progress.advance_to(10.5)
    assert stream.getvalue().splitlines() == [
        "lecture/supervised: 0.5/600.0 s simulated (0%), estimating the time left (10 s so far)",
        "lecture/supervised: 5.5/600.0 s simulated (1%), 1 s simulated/s, ETA at most 10 min "
        "00 s (if it runs to its limit)",
        "lecture/supervised: 10.5/600.0 s simulated (2%), 1 s simulated/s, ETA at most 9 min "
        "55 s (if it runs to its limit)",
    ]


def test_the_heartbeat_prints_while_nothing_advances_and_nothing_after_close() -> None:
    stream, clock = io.StringIO(), FakeClock()
    progress = _progress(stream, clock)
    clock.now += 1.0
    progress.tick()
    assert stream.getvalue() == ("campaign default: 0/20 runs (0%), estimating the time left "
                                 "(1 s so far)\n")
    progress.close(finished=False)
    clock.now += 60.0
    progress.tick()
    assert len(stream.getvalue().splitlines()) == 1, "no 'done' line for unfinished work"


def test_on_a_terminal_the_bar_and_no_lines() -> None:
    stream, clock = io.StringIO(), FakeClock()
    progress = Progress(20, "campaign default", "runs", stream=stream, clock=clock,
                        terminal=True)
    clock.now += 10.0
    progress.update(5)
    progress.close()
    text = stream.getvalue()
    assert "25%|" in text and " 5/20 " in text and "\r" in text, "tqdm's bar"
    assert "ETA" not in text


def test_disabled_or_a_closed_stream_shows_nothing_and_never_raises() -> None:
    stream, clock = io.StringIO(), FakeClock()
    quiet = Progress(20, "x", "runs", stream=stream, clock=clock, terminal=False, enabled=False)
    clock.now += 10.0
    quiet.update()
    assert stream.getvalue() == ""
    stream.close()
    broken = Progress(20, "x", "runs", stream=stream, clock=clock, terminal=False)
    clock.now += 10.0
    broken.update()
    broken.close()


# ---- the commands, piped ----------------------------------------------------------------------
SHORT = """\
name: short
lane:
  segments:
    - straight_m: 3.0
run:
  max_time_s: 2
config:
  simulation: {width_px: 320, height_px: 240, texture_mm_per_px: 5.0}
"""


@pytest.fixture
def every_update(monkeypatch: pytest.MonkeyPatch) -> None:
    """A line at every update (the wall clock of a short test run moves too little)."""
    monkeypatch.setattr(progress_module, "FIRST_LINE_S", 0.0)
    monkeypatch.setattr(progress_module, "PLAIN_EVERY_S", 0.0)


@pytest.mark.usefixtures("every_update")
def test_sim_and_replay_say_how_far_they_are_when_piped(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tmp_path / "short.yaml"
    scenario.write_text(SHORT, encoding="utf-8")
    assert main(["sim", "--scenario", str(scenario), "--no-video", "--out", str(tmp_path / "s"),
                 "--camera-out", str(tmp_path / "frames")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("short/supervised: 0.5/2.0 s simulated (25%), estimating the "
                             "time left (")
    assert err[1].startswith("short/supervised: 1.0/2.0 s simulated (50%), ")
    assert err[1].endswith(" (if it runs to its limit)")
    assert err[-1].startswith("short/supervised: done, 2.0/2.0 s simulated in ")
    calibration = tmp_path / "frames.calibration.yaml"  # (`--camera-out` wrote it beside)
    assert main(["replay", str(tmp_path / "frames"), "--calibration", str(calibration),
                 "--no-video", "--out", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err.splitlines()
    steps = json.loads((tmp_path / "r" / "metrics.json").read_text())["steps"]
    assert err[0].startswith(f"replay frames: 1/{steps} steps (")
    assert err[-1].startswith(f"replay frames: done, {steps}/{steps} steps in ")


@pytest.mark.usefixtures("every_update")
def test_a_piped_campaign_says_how_far_it_is(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    spec = tmp_path / "spec.yaml"
    spec.write_text("""\
name: tiny
scenarios: [straight]
max_time_s: 3
fault_start_s: [2.5, 2.6]
faults:
  - kind: operator_stop
config: {simulation: {texture_mm_per_px: 5.0}}
""", encoding="utf-8")
    assert main(["campaign", "--spec", str(spec), "--out", str(tmp_path / "c"), "--runs", "2",
                 "--scheduler", "in-process"]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines()
             if line.startswith("campaign tiny: ")]
    assert lines[0] == "campaign tiny: 2 runs (seed 0), 0 already stored; running in this process"
    assert any(line.startswith("campaign tiny: 1/2 runs (50%), ") for line in lines), lines
    assert lines[-1].startswith("campaign tiny: done, 2/2 runs in ")
