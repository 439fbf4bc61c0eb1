"""The campaign report files a safe halt's time under the fault it answered, not under every
fault of the run (a run with a blocked write and a frame from the future that halted on
FRAME_INVALID is no figure for write_blocks; a halt at the end of the tape answers none)."""

from __future__ import annotations

from lanewarden.scenarios.campaign.report import _time_to_halt, summarize


def test_time_to_halt_goes_to_the_answered_fault_only() -> None:
    rows = [
        {"outcome": "safe_halt", "fault_kinds": "write_blocks,frame_from_future",
         "reason": "FRAME_INVALID answering frame_from_future (fault 1)", "time_to_halt_s": 0.0},
        {"outcome": "safe_halt", "fault_kinds": "bumper",
         "reason": "BUMPER answering bumper (fault 0)", "time_to_halt_s": 0.034},
        {"outcome": "safe_halt", "fault_kinds": "glare_sweep",
         "reason": "LANE_LOST at the end of the tape", "time_to_halt_s": None},
    ]
    table = _time_to_halt(summarize(rows))
    assert "<th>frame_from_future</th><td>1</td>" in table
    assert "<th>bumper</th><td>1</td><td>0.034</td>" in table
    assert "glare_sweep" not in table  # the lane end answered no fault
    assert "write_blocks" not in table
