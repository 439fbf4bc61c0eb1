"""The campaign report files a safe halt's time under the fault it answered, not under every
fault of the run (a run with a blocked write and a frame from the future that halted on
FRAME_INVALID is no figure for write_blocks)."""

from __future__ import annotations

from lanewarden.scenarios.campaign.report import _time_to_halt


def test_time_to_halt_goes_to_the_answered_fault_only() -> None:
    rows = [
        {"outcome": "safe_halt", "fault_kinds": "write_blocks,frame_from_future",
         "reason": "FRAME_INVALID answering frame_from_future (fault 1)", "time_to_halt_s": 0.0},
        {"outcome": "safe_halt", "fault_kinds": "bumper",
         "reason": "BUMPER answering bumper (fault 0)", "time_to_halt_s": 0.034},
        {"outcome": "safe_halt", "fault_kinds": "glare_sweep",
         "reason": "LANE_LOST at the end of the tape", "time_to_halt_s": 4.5},
    ]
    table = _time_to_halt(rows)
    assert "<th>frame_from_future</th><td>1</td>" in table
    assert "<th>bumper</th><td>1</td><td>0.034</td>" in table
    assert "<th>glare_sweep</th><td>1</td><td>4.500</td>" in table  # the lane end: every kind
    assert "write_blocks" not in table
