"""The survey's pure core: the labels format, the figures per class and the verdict, on results
written out by hand (no image, no detector). Expected answers are literals."""

from __future__ import annotations

import dataclasses
import math
import sys
from types import FrameType

import pytest

import lanewarden.survey as survey_module
from lanewarden.errors import InputFileError
from lanewarden.survey import (
    STRICTER_SETTINGS,
    ConfidentRun,
    EngageFigures,
    FrameResult,
    LabelledFrame,
    OnItsOwn,
    SurveyFigures,
    Verdict,
    WhatIf,
    _engage_json,
    _result_json,
    class_figures,
    class_line,
    component_figures,
    confident_runs,
    engage_line,
    judge,
    name_frames,
    not_engaged_counts,
    parse_labels,
    summary_lines,
    survey_json,
    verdict_line,
    what_if_advice,
)


def result(name: str, expect: str, order: int, decision: str = "none", confidence: float = 0.0,
           confident: bool = False, **components: float) -> FrameResult:
    return FrameResult(LabelledFrame(name, expect, order), decision, confidence, confident,
                       components)


# ---- labels -----------------------------------------------------------------------------------
def test_file_labels_with_comments_notes_and_commas_in_notes() -> None:
    table = parse_labels(
        "# my floor\n\nfile,expect,note\nlane/a.jpg,lane,two tapes, straight\n"
        "b.png, NONE ,\n", "floor/labels.csv")
    assert table.kind == "file"
    assert [(r.line, r.file, r.expect, r.note) for r in table.rows] == [
        (4, "lane/a.jpg", "lane", "two tapes, straight"), (5, "b.png", "none", "")]


def test_frame_labels_single_frames_and_ranges() -> None:
    table = parse_labels("frames,expect\n120-340,lane\n7,none\n", "clip.csv")
    assert table.kind == "frames"
    assert [(r.frames, r.expect) for r in table.rows] == [((120, 340), "lane"), ((7, 7), "none")]
    # spaces around the dash, as around a label (a new user's '490 - 841' had been refused)
    spaced = parse_labels("frames,expect\n490 - 841, lane \n", "clip.csv")
    assert [(r.frames, r.expect) for r in spaced.rows] == [((490, 841), "lane")]


@pytest.mark.parametrize(("text", "message"), [
    ("", "clip.csv: no header; expected file,expect[,note] (images) or frames,expect[,note] "
         "(a video, run or tub)"),
    ("image,label\na.jpg,lane\n", "clip.csv:1: header 'image,label': expected file,expect[,note] "
                                  "(images) or frames,expect[,note] (a video, run or tub)"),
    ("file,expect\n", "clip.csv: no labelled frames after the header"),
    ("file,expect\na.jpg,road\n", "clip.csv:2: label 'road': expected lane or none"),
    ("file,expect\na.jpg,no-lane\n", "clip.csv:2: label 'no-lane': expected lane or none (did "
                                     "you mean none? no-lane/ is the folder's name)"),
    ("file,expect\na.jpg\n", "clip.csv:2: 'a.jpg': expected 2 columns"),
    ("file,expect\na.jpg,lane,straight\n", "clip.csv:2: 'a.jpg,lane,straight': expected 2 "
                                           "columns"),
    ("file,expect\n,lane\n", "clip.csv:2: empty file name"),
    ("file,expect\na.jpg,lane\n# again\na.jpg,none\n",
     "clip.csv:4: a.jpg is already labelled on line 2"),
    ("frames,expect\nten,lane\n", "clip.csv:2: frames 'ten': expected a frame index in digits "
                                  "0-9 (120) or an inclusive range (120-340)"),
    ("frames,expect\n40-30,lane\n", "clip.csv:2: frames '40-30': expected 0 <= first <= last"),
    ("frames,expect\n-3,lane\n", "clip.csv:2: frames '-3': expected a frame index in digits 0-9 "
                                 "(120) or an inclusive range (120-340)"),
    # int() takes any Unicode digit ('\u0663' is an Arabic-Indic 3: it had labelled frame 3), a
    # sign and underscores; a frame number is ASCII digits only
    *((f"frames,expect\n{bad},lane\n", f"clip.csv:2: frames '{bad}': expected a frame index in "
       "digits 0-9 (120) or an inclusive range (120-340)")
      for bad in ("\u0663", "1-\u0663", "\uff11\uff12", "+3", "1_000", "3-+4")),
    # over 4300 digits int() raised a ValueError of its own; any number of digits beyond a
    # recording's frames is refused as a value
    ("frames,expect\n" + "9" * 5000 + ",lane\n", "clip.csv:2: frames '" + "9" * 60
     + "': expected a frame index in digits 0-9 (120) or an inclusive range (120-340)"),
    # a labels file's text is quoted with its control characters escaped: an OSC sequence
    # (set the terminal's title) had reached the terminal as it was
    ("file,expect\na.jpg,\x1b]0;pwned\x07\n",
     "clip.csv:2: label '\\x1b]0;pwned\\x07': expected lane or none"),
    ("frames,expect\n\x1b[2J,lane\n", "clip.csv:2: frames '\\x1b[2J': expected a frame index in "
                                     "digits 0-9 (120) or an inclusive range (120-340)"),
    ("fi\x1b[31mle,expect\n", "clip.csv:1: header 'fi\\x1b[31mle,expect': expected "
                              "file,expect[,note] (images) or frames,expect[,note] (a video, "
                              "run or tub)"),
    ("file,expect\n\x1b]0;t\x07.png\n", "clip.csv:2: '\\x1b]0;t\\x07.png': expected 2 columns"),
    ("file,expect\n\x1b]0;t\x07.png,lane\n\x1b]0;t\x07.png,none\n",
     "clip.csv:3: \\x1b]0;t\\x07.png is already labelled on line 2"),
    ("frames,expect\n10-20,lane\n20-25,none\n",
     "clip.csv:3: frames 20-25 overlap frames 10-20 of line 2"),
    ("file,expect\na.jpg,lane," + "x" * 200_000 + "\n",  # csv's own field limit: was a traceback
     "clip.csv:2: not a CSV line (field larger than field limit (131072))"),
    # a NUL in a file name was a ValueError traceback when the path was resolved
    ("file,expect\na.jpg,lane\nb\0.jpg,none\n", "clip.csv:3: a NUL character; expected a line "
                                                "of text"),
    # an overlap named at the later line, whatever the rows' order
    ("frames,expect\n20-25,none\n0-3,lane\n10-20,lane\n",
     "clip.csv:4: frames 10-20 overlap frames 20-25 of line 2"),
    ("frames,expect\n0-100,lane\n40,none\n101-200,none\n",
     "clip.csv:3: frames 40-40 overlap frames 0-100 of line 2"),
    # a form feed or U+2028 pasted into a note had ended the line there: a wrong row, wrong line
    ("file,expect,note\na.jpg,lane,pasted\u2028text\nb.jpg,none,x\x0c\nc.jpg,road\n",
     "clip.csv:4: label 'road': expected lane or none"),
])
def test_bad_labels_are_one_line_naming_the_line_and_the_value(text: str, message: str) -> None:
    with pytest.raises(InputFileError) as caught:
        parse_labels(text, "clip.csv")
    assert str(caught.value) == message


def test_overlapping_ranges_are_found_in_steps_proportional_to_the_rows() -> None:
    """Each frame range had been compared with every earlier one: 100000 rows (the most a labels
    file may hold) took minutes. Counted in lines of survey.py executed, not timed: 2000 rows
    had run about 4 million, now a few dozen per row."""
    rows = 2000
    text = "frames,expect\n" + "".join(f"{i * 2},none\n" for i in range(rows)) + "5-6,lane\n"
    steps = 0

    def count(frame: FrameType, event: str, arg: object) -> object:
        nonlocal steps
        if frame.f_code.co_filename == survey_module.__file__:
            steps += event == "line"
            return count
        return None

    previous = sys.gettrace()  # a coverage tool's or a debugger's, put back after
    sys.settrace(count)
    try:
        with pytest.raises(InputFileError) as caught:
            parse_labels(text, "clip.csv")
    finally:
        sys.settrace(previous)
    assert str(caught.value) == f"clip.csv:{rows + 2}: frames 5-6 overlap frames 6-6 of line 5"
    assert steps < 50 * rows, steps


def test_lines_end_where_an_editor_ends_them() -> None:
    table = parse_labels("file,expect,note\r\na.jpg,lane,one\u2028two\rb.jpg,none,a\x85b\n",
                         "clip.csv")
    assert [(r.line, r.file, r.note) for r in table.rows] == [(2, "a.jpg", "one\u2028two"),
                                                               (3, "b.jpg", "a\x85b")]


# ---- figures ----------------------------------------------------------------------------------
def test_confident_runs_are_consecutive_in_sequence_order_longest_first() -> None:
    flags = {0: True, 1: True, 2: False, 3: True, 4: True, 5: True, 7: True, 8: True, 9: True}
    results = [result(f"frame {i}", "lane", i, confident=c) for i, c in flags.items()]
    # 7 does not follow 5 (frame 6 is not surveyed): two runs of three, the earlier first
    assert confident_runs(results[::-1]) == [
        ConfidentRun("frame 3", "frame 5", 3), ConfidentRun("frame 7", "frame 9", 3),
        ConfidentRun("frame 0", "frame 1", 2)]
    assert confident_runs([result("a", "lane", 0)]) == []


def test_weakest_components_count_only_components_below_one() -> None:
    results = [
        result("a", "lane", 0, both_sides=1.0, tape_pair_left=0.0, parallel=0.5),
        result("b", "lane", 1, both_sides=1.0, tape_pair_left=0.2, parallel=0.1),
        result("c", "lane", 2, both_sides=1.0, tape_pair_left=1.0, parallel=1.0),
    ]
    assert results[2].weakest is None
    assert results[1].weakest == ("parallel", 0.1)
    # most often the weakest first, then the lowest median over the class; beside it the
    # median over the frames where it was the weakest (none: NaN)
    figures = component_figures(results)
    assert [(f.name, f.weakest_in, f.median) for f in figures] == [
        ("tape_pair_left", 1, 0.2), ("parallel", 1, 0.5), ("both_sides", 0, 1.0)]
    assert [f.median_where_weakest for f in figures[:2]] == [0.0, 0.1]
    assert math.isnan(figures[2].median_where_weakest)
    # the class line names where each is weakest and how weak it is there
    line = class_line(class_figures("lane", results))
    # (one frame is "1 frame": it had read "in 1 frames")
    assert line.endswith("; weakest: tape_pair_left in 1 frame (median there 0.00), "
                         "parallel in 1 (0.10)")


def test_stills_not_engaged_are_counted_by_the_supervisors_reason() -> None:
    reasons = [None, "not engaged yet: waiting for start and a confident lane",
               "LANE_DEPARTURE: a lane edge inside the robot's footprint (left edge 0.01 m)",
               "LANE_DEPARTURE: a lane edge inside the robot's footprint (left edge 0.02 m)",
               "not engaged yet: waiting for start and a confident lane",
               "not engaged yet: waiting for start and a confident lane"]
    counts = not_engaged_counts(reasons)
    assert counts == (("not engaged yet", 3), ("LANE_DEPARTURE", 2))
    engage = EngageFigures(how="held", window_s=1.0, attempts=6, engaged=1, times_s=(0.3,),
                           not_engaged=counts)
    assert engage_line(engage) == (
        "supervisor: engages on 1 of 6 lane stills held in view for 1.0 s after a start (after "
        "0.30 s at the most); not on 5 (3: no confident lane long enough; 2: LANE_DEPARTURE)")
    # survey.json says it in the same words (it said "not engaged yet", the supervisor's)
    assert _engage_json(engage)["not_engaged"] == {"no confident lane long enough": 3,
                                                   "LANE_DEPARTURE": 2}
    held = dataclasses.replace(result("frame 1", "lane", 1, "straight", 0.9, True),
                               engaged=False, not_engaged=reasons[1])
    assert _result_json(held)["not_engaged_because"] == "no confident lane long enough"


def test_a_decision_on_a_no_lane_frame_makes_it_not_safe_and_names_the_frames() -> None:
    results = [
        result("frame 10", "lane", 10, "straight", 0.9, True),
        result("frame 11", "none", 11, "straight", 0.3),
        result("frame 12", "none", 12, "left", 0.7, True),
        result("frame 13", "none", 13),
        result("frame 20", "none", 20, "right", 0.25),
    ]
    figures = judge(results, None)
    assert not figures.verdict.safe
    assert [r.frame.name for r in figures.verdict.false_lanes] == ["frame 11", "frame 12",
                                                                   "frame 20"]
    assert verdict_line(figures.verdict) == (
        "verdict: NOT SAFE: 3 false lanes (a decision on a no-lane frame): frames 11-12, frame 20")
    none = figures.classes["none"]
    assert (none.frames, none.decisions, none.confident) == (4, 3, 1)
    assert class_line(none) == ("no-lane: 4 frames, 3 with a decision (75%), 1 confident, 3 false "
                                "lanes; longest confident run 1 (frame 12)")


def test_a_recordings_no_lane_frame_that_decides_on_its_own_is_a_false_lane() -> None:
    """A no-lane frame of a recording is judged in sequence and on its own: a decision either
    way is a false lane; its name says the decision on its own only where the sequence had
    none (frame 11 decided in both); a lane frame's judgement on its own is never asked."""
    results = [
        result("frame 10", "lane", 10, "straight", 0.9, True),
        dataclasses.replace(result("frame 11", "none", 11, "straight", 0.45),
                            on_its_own=OnItsOwn("straight", 0.53)),
        dataclasses.replace(result("frame 12", "none", 12, consistency=0.0),
                            on_its_own=OnItsOwn("straight", 0.33)),
        dataclasses.replace(result("frame 13", "none", 13), on_its_own=OnItsOwn("none", 0.0)),
    ]
    figures = judge(results, None)
    assert not figures.verdict.safe
    assert [r.frame.name for r in figures.verdict.false_lanes] == ["frame 11", "frame 12"]
    assert verdict_line(figures.verdict) == (
        "verdict: NOT SAFE: 2 false lanes (a decision on a no-lane frame, judged in sequence or "
        "on its own): frame 11, frame 12 (on its own: straight at 0.33)")
    assert class_line(figures.classes["none"]) == (
        "no-lane: 3 frames, 1 with a decision (33%), 0 confident, 2 false lanes (1 only judged "
        "on its own); no confident frame; weakest: consistency in 1 frame (median there 0.00)")
    assert summary_lines(figures)[2] == (
        "no-lane, each also judged on its own (as a photo is, without the frame before it): 2 "
        "decisions in 3 frames: frame 11 (straight at 0.53), frame 12 (straight at 0.33)")
    frames = {f["frame"]: f.get("on_its_own") for f in survey_json(figures, {})["frames"]}
    assert frames == {"frame 10": None,
                      "frame 11": {"decision": "straight", "confidence": 0.53},
                      "frame 12": {"decision": "straight", "confidence": 0.33},
                      "frame 13": {"decision": "none", "confidence": 0.0}}
    # none decides on its own: SAFE, and the line says so
    safe = judge([results[0], results[3]], None)
    assert safe.verdict.safe
    assert summary_lines(safe)[2] == ("no-lane, each also judged on its own (as a photo is, "
                                      "without the frame before it): 0 decisions in 1 frame")


def test_no_decision_on_no_lane_frames_is_safe_and_lane_decisions_are_no_false_lanes() -> None:
    results = [result("lane/a.jpg", "lane", 0, "left", 0.8, True),
               result("no-lane/b.jpg", "none", 1, "none", 0.1)]
    figures = judge(results, None)
    assert figures.verdict.safe
    assert verdict_line(figures.verdict) == "verdict: SAFE: no decision on the only no-lane frame"


def test_without_no_lane_frames_nothing_is_safe() -> None:
    figures = judge([result("lane/a.jpg", "lane", 0, "left", 0.8, True)], None)
    assert not figures.verdict.safe
    assert verdict_line(figures.verdict) == "verdict: NOT SAFE: no no-lane frame was surveyed"


def test_frame_names_are_compacted_and_cut() -> None:
    names = [f"frame {i}" for i in (1, 2, 3, 5, 8, 9)] + ["no-lane/x.jpg"]
    assert name_frames(names) == "frames 1-3, frame 5, frames 8-9, no-lane/x.jpg"
    assert name_frames(names, limit=2) == "frames 1-3, frame 5 and 2 more"
    # a folder of images: each frame with its file, a range with its first and last
    files = [f"frame {i} (f_{4 * i:04d}.png)" for i in (1, 2, 3, 5)]
    assert name_frames(files) == ("frames 1-3 (f_0004.png .. f_0012.png), frame 5 (f_0020.png)")
    # words in brackets are not a file: such names are not joined
    assert name_frames(["frame 11 (straight at 0.53)", "frame 12 (straight at 0.33)"]) == (
        "frame 11 (straight at 0.53), frame 12 (straight at 0.33)")


def test_engage_lines() -> None:
    held = EngageFigures("held", 1.0, 4, 3, (0.3, 0.3, 0.4))
    assert engage_line(held) == ("supervisor: engages on 3 of 4 lane stills held in view for "
                                 "1.0 s after a start (after 0.40 s at the most)")
    sequence = EngageFigures("sequence", 3.3, 1, 1, (0.31,), "frame 41", 800, 892,
                             ("frame 250 LANE_LOST",))
    assert engage_line(sequence) == (
        "supervisor: engages at frame 41 (0.31 s after the start); engaged on 800 of 892 lane "
        "frames (90%); 1 halt (frame 250 LANE_LOST)")
    never = EngageFigures("sequence", 3.3, 1, 0, lane_frames=892)
    assert engage_line(never) == ("supervisor: never engages on this sequence (3.3 s replayed, "
                                  "started at its first frame and resumed after every halt)")


def test_survey_json_has_the_verdict_the_classes_and_every_frame() -> None:
    results = [result("frame 1", "lane", 1, "straight", 0.9, True, both_sides=1.0),
               result("frame 2", "none", 2, "right", 0.3, False, both_sides=0.5)]
    document = survey_json(judge(results, None), {"source": "tub"})
    assert document["source"] == "tub"
    assert document["verdict"]["safe"] is False
    assert document["verdict"]["false_lanes"] == ["frame 2"]
    assert document["classes"]["no-lane"]["decisions"] == 1
    assert document["classes"]["lane"]["longest_confident_runs"] == [
        {"first": "frame 1", "last": "frame 1", "frames": 1}]
    assert [f["frame"] for f in document["frames"]] == ["frame 1", "frame 2"]
    assert document["frames"][1]["weakest"] == "both_sides"


def test_a_stricter_setting_is_advised_only_where_it_makes_the_frames_safe_and_engages() -> None:
    """A new user was told 'to drive with it, add ...' for a setting that left the survey NOT
    SAFE, and for one with which the supervisor never engaged."""
    setting = STRICTER_SETTINGS[0]
    engages = EngageFigures("held", 1.0, attempts=4, engaged=3, times_s=(0.3,))
    never = EngageFigures("sequence", 3.3, 1, 0, lane_frames=892)

    def advice(safe: bool, engage: EngageFigures) -> str:
        verdict = Verdict(safe=safe, false_lanes=(), no_lane_frames=6, engage=engage)
        return what_if_advice(WhatIf(setting, SurveyFigures({}, verdict, ())))

    assert advice(True, engages) == (
        "to drive with it, set in --config (merged into its perception: section if it has one): "
        "perception: {tape: {unverifiable_score: 0}}; what it costs: a bend whose inner tape "
        "leaves the view is then no lane, and the robot halts there (LANE_LOST)")
    assert advice(False, engages) == (
        "it does not make these frames safe: not a setting to drive with (look at the pictures "
        "of the false lanes left, and check their labels)")
    assert advice(True, never) == (
        "it makes these frames safe, but the supervisor never engages with it: not a setting to "
        "drive with")
