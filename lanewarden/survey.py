"""`lanewarden survey`'s pure core: labelled frames and what perception and the supervisor made of
them -> the figures per class and the verdict.

A survey judges a camera on a real floor before it drives: frames labelled `lane` (two tapes in
view) or `none` (bare floor, seams, one tape, a tape's end, clutter, a dark frame). Per class it
counts the frames with a decision (perception's `decision` with the supervisor's thresholds: not
"none"), the confident ones (the supervisor's own test, `supervisor.lane_evidence`: both edges and
`confidence_confident_min`), the false lanes (any decision on a `none` frame: as judged, in a
shifted version of a still, or, for a recording's frame, judged again on its own), the weakest
confidence components and the longest runs of confident frames in sequence order. The verdict:
SAFE when no `none` frame got a decision, else NOT SAFE naming them; and whether the real
supervisor engaged (`EngageFigures`, measured by `lanewarden.survey_run`).

Also here: the labels file format (`parse_labels`), pure text in, rows out, with one-line errors
naming the file, the line and the value.

Pure: no images, no files, no clock, no printing.
"""

from __future__ import annotations

import csv
import math
import re
import statistics
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from lanewarden.errors import InputFileError
from lanewarden.perception.ground import default_pose
from lanewarden.perception.observation import weakest_component
from lanewarden.wording import counted, shown_name

LANE = "lane"
NONE = "none"
#: The no-lane photos of the README's recipe ("Before you drive: survey your floor"): a SAFE
#: verdict on fewer gets a note that it says little.
RECIPE_NO_LANE_FRAMES = 6
#: The labels, and the folder (and title) of each class.
EXPECTS = (LANE, NONE)
CLASS_FOLDERS = {LANE: "lane", NONE: "no-lane"}
#: How many longest confident runs, frames named in one line, are reported.
RUNS_SHOWN = 3
NAMES_SHOWN = 12

#: Largest labels file read, bytes, and most labelled rows in it.
MAX_LABELS_BYTES = 1_000_000
MAX_LABEL_ROWS = 100_000
LABEL_HEADERS = {
    ("file", "expect"): "file",
    ("file", "expect", "note"): "file",
    ("frames", "expect"): "frames",
    ("frames", "expect", "note"): "frames",
}
HEADER_HELP = "file,expect[,note] (images) or frames,expect[,note] (a video, run or tub)"
#: Where a labels file's lines end: as an editor counts them (str.splitlines also ends a line at a
#: form feed, U+2028 or U+0085 inside a note, and then names the wrong line).
LINE_BREAK = re.compile(r"\r\n|\r|\n")
#: A frame index or an inclusive range of them, in ASCII digits (int() also takes '٣', '+3' and
#: '1_000'), at most 12 digits each (int() refuses a field of 4301 digits with a ValueError).
FRAME_RANGE = re.compile(r"([0-9]{1,12})(?: *- *([0-9]{1,12}))?")  # ("490 - 841" too)


# ---- labels -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class LabelRow:
    """One row of a labels file: `file` (a path) or `frames` (first, last; inclusive)."""

    line: int
    expect: str
    note: str
    file: str | None = None
    frames: tuple[int, int] | None = None


@dataclass(frozen=True)
class LabelsTable:
    source: str
    kind: str  # "file" or "frames"
    rows: tuple[LabelRow, ...]


def quoted(value: str) -> str:
    """A labels file's text as an error quotes it: stripped, at most 60 characters, and nothing a
    terminal acts on (an escape sequence in a row is shown as '\\x1b]0;...', never sent)."""
    return shown_name(value.strip()[:60])


def _expect(value: str, where: str) -> str:
    expect = value.strip().lower()
    if expect not in EXPECTS:
        # the no-lane class folder's name given as a label: say the label it stands for
        folder = CLASS_FOLDERS[NONE]
        hint = (f" (did you mean {NONE}? {folder}/ is the folder's name)"
                if expect.rstrip("/") == folder else "")
        raise InputFileError(f"{where}: label '{quoted(value)}': expected lane or "
                             f"none{hint}")
    return expect


def _frame_range(value: str, where: str) -> tuple[int, int]:
    found = FRAME_RANGE.fullmatch(value.strip())
    if found is None:
        raise InputFileError(f"{where}: frames '{quoted(value)}': expected a frame index in "
                             "digits 0-9 (120) or an inclusive range (120-340)")
    first = int(found.group(1))
    last = int(found.group(2)) if found.group(2) is not None else first
    if last < first:
        raise InputFileError(f"{where}: frames '{quoted(value)}': expected 0 <= first <= last")
    return first, last


def parse_labels(text: str, source: str) -> LabelsTable:
    """The rows of a labels file (`source` names it in errors). CSV with a header
    (`HEADER_HELP`); blank lines and lines starting with '#' are skipped; the note is free text
    (commas in it need no quotes). A frame or a file labelled twice is an error."""
    header: str | None = None
    with_note = False
    rows: list[LabelRow] = []
    files: dict[str, int] = {}
    spans: list[tuple[int, int, int]] = []
    for number, raw in enumerate(LINE_BREAK.split(text), start=1):
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        where = f"{source}:{number}"
        if "\0" in raw:  # csv passes a NUL on; a path with one was a ValueError traceback
            raise InputFileError(f"{where}: a NUL character; expected a line of text")
        try:
            fields = next(csv.reader([raw]))
        except csv.Error as exc:  # a field beyond csv's limit (131072 characters), a stray NUL
            raise InputFileError(f"{where}: not a CSV line ({exc})") from None
        if header is None:
            names = tuple(f.strip().lower() for f in fields)
            if names not in LABEL_HEADERS:
                raise InputFileError(f"{where}: header '{quoted(raw)}': expected "
                                     f"{HEADER_HELP}")
            header = LABEL_HEADERS[names]
            with_note = len(names) == 3
            continue
        if len(fields) < 2 or (len(fields) > 2 and not with_note):
            raise InputFileError(f"{where}: '{quoted(raw)}': expected "
                                 f"{'2 or 3' if with_note else '2'} columns")
        if len(rows) >= MAX_LABEL_ROWS:
            raise InputFileError(f"{where}: more than {MAX_LABEL_ROWS} labelled rows")
        expect = _expect(fields[1], where)
        note = ",".join(fields[2:]).strip()
        if header == "file":
            name = fields[0].strip()
            if not name:
                raise InputFileError(f"{where}: empty file name")
            if name in files:
                raise InputFileError(f"{where}: {quoted(name)} is already labelled on line "
                                     f"{files[name]}")
            files[name] = number
            rows.append(LabelRow(number, expect, note, file=name))
        else:
            first, last = _frame_range(fields[0], where)
            spans.append((first, last, number))
            rows.append(LabelRow(number, expect, note, frames=(first, last)))
    if header is None:
        raise InputFileError(f"{source}: no header; expected {HEADER_HELP}")
    if not rows:
        raise InputFileError(f"{source}: no labelled frames after the header")
    _refuse_overlaps(spans, source)
    return LabelsTable(source, header, tuple(rows))


def _refuse_overlaps(spans: list[tuple[int, int, int]], source: str) -> None:
    """An error naming two (first, last, line) frame ranges that share a frame, at the later
    line. Sorted once, then swept: comparing each row with every earlier one took minutes for
    the 100000 rows a labels file may hold."""
    reach: tuple[int, int, int] | None = None  # of the ranges so far, the one ending last
    for span in sorted(spans):
        if reach is not None and span[0] <= reach[1]:
            early, late = sorted((reach, span), key=lambda s: s[2])
            raise InputFileError(f"{source}:{late[2]}: frames {late[0]}-{late[1]} overlap "
                                 f"frames {early[0]}-{early[1]} of line {early[2]}")
        if reach is None or span[1] > reach[1]:
            reach = span


# ---- per-frame results ------------------------------------------------------------------------
@dataclass(frozen=True)
class LabelledFrame:
    """A frame to survey: `name` as the report shows it (a file path, or "frame 123"), its label,
    its place in sequence order (`order`: its place among the frames of a video, run or tub,
    where a frame the camera dropped is no gap; the row for a labels file; the name order within
    a class folder) and the label's note."""

    name: str
    expect: str
    order: int
    note: str = ""


@dataclass(frozen=True)
class Shifted:
    """A still judged again in `versions` copies moved by a random fraction of a pixel:
    `decided`, the confidence of each copy that got a decision."""

    versions: int
    decided: tuple[float, ...] = ()


@dataclass(frozen=True)
class OnItsOwn:
    """A recording's no-lane frame judged again on its own, as a still is (no previous
    observation): perception's `decision` and `confidence` then. In sequence the `consistency`
    component can hide a lane that jumped since the previous frame; a robot that comes upon the
    same view gradually sees it as this does."""

    decision: str
    confidence: float

    @property
    def has_decision(self) -> bool:
        return self.decision != "none"


@dataclass(frozen=True)
class FrameResult:
    """What perception made of one labelled frame. `decision`: "straight", "left", "right" or
    "none"; `confident`: the supervisor's test; `engaged_after_s`: for a lane still held in view,
    how long the supervisor took to engage (None: it did not, or the frame was not held);
    `engaged`: for a frame of a sequence, whether the supervisor was engaged at it;
    `not_engaged`: for a lane still the supervisor did not engage on, its halt reason at the end
    of the hold (why it stayed halted); `shifted`: for a no-lane still judged again in versions
    moved by a fraction of a pixel (`survey --jitter`), how many versions and the confidence of
    each that got a decision (a false lane the camera may deliver on its next frame);
    `on_its_own`: for a recording's no-lane frame, what perception made of it on its own (a
    decision there makes it a false lane too)."""

    frame: LabelledFrame
    decision: str
    confidence: float
    confident: bool
    components: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    engaged_after_s: float | None = None
    engaged: bool | None = None
    not_engaged: str | None = None
    shifted: Shifted | None = None
    on_its_own: OnItsOwn | None = None

    @property
    def has_decision(self) -> bool:
        return self.decision != "none"

    @property
    def shifted_decisions(self) -> int:
        """How many of its shifted versions got a decision (0: none, or none were made)."""
        return 0 if self.shifted is None else len(self.shifted.decided)

    @property
    def decided_on_its_own(self) -> bool:
        """Judged on its own (a recording's no-lane frame), it got a decision."""
        return self.on_its_own is not None and self.on_its_own.has_decision

    @property
    def false_lane(self) -> bool:
        """A decision on a no-lane frame, on one of its shifted versions, or on it judged on its
        own."""
        return self.frame.expect == NONE and (self.has_decision or self.shifted_decisions > 0
                                              or self.decided_on_its_own)

    @property
    def weakest(self) -> tuple[str, float] | None:
        """The lowest confidence component (the first of equals); None when none is below 1."""
        return weakest_component(self.components)


@dataclass(frozen=True)
class ConfidentRun:
    """Consecutive confident frames of one class in sequence order."""

    first: str
    last: str
    length: int


@dataclass(frozen=True)
class ComponentFigure:
    """One confidence component over a class: in how many frames it was the weakest, its median
    over the class and its median over the frames where it was the weakest (NaN: none)."""

    name: str
    weakest_in: int
    median: float
    median_where_weakest: float = math.nan


@dataclass(frozen=True)
class ClassFigures:
    expect: str
    frames: int
    decisions: int
    confident: int
    false_lanes: tuple[FrameResult, ...]
    runs: tuple[ConfidentRun, ...]
    components: tuple[ComponentFigure, ...]

    @property
    def longest_run(self) -> int:
        return self.runs[0].length if self.runs else 0


@dataclass(frozen=True)
class EngageFigures:
    """Whether the real supervisor engaged.

    `how`: "held" (each lane still held in view for `window_s` at the camera rate after a start;
    `attempts` stills, `engaged` of them engaged, `times_s` how long each took, `not_engaged`
    the others counted by the supervisor's reason, most first) or "sequence"
    (the frames replayed in order at their own times, a start at the first and a resume after
    every halt; `engaged` 1 or 0, `first_engaged` the frame and `times_s` the time after the start,
    `engaged_lane_frames` of `lane_frames` with the supervisor engaged, `halts` where it halted
    and why)."""

    how: str
    window_s: float
    attempts: int
    engaged: int
    times_s: tuple[float, ...] = ()
    first_engaged: str | None = None
    engaged_lane_frames: int = 0
    lane_frames: int = 0
    halts: tuple[str, ...] = ()
    not_engaged: tuple[tuple[str, int], ...] = ()

    @property
    def would_engage(self) -> bool:
        return self.engaged > 0


@dataclass(frozen=True)
class Verdict:
    safe: bool
    false_lanes: tuple[FrameResult, ...]
    no_lane_frames: int
    engage: EngageFigures | None

    @property
    def headline(self) -> str:
        return "SAFE" if self.safe else "NOT SAFE"


@dataclass(frozen=True)
class SurveyFigures:
    classes: Mapping[str, ClassFigures]
    verdict: Verdict
    results: tuple[FrameResult, ...]


def reason_key(reason: str) -> str:
    """A halt reason as counted: its event name ("LANE_DEPARTURE: a lane edge ..." ->
    "LANE_DEPARTURE"), or the supervisor's words before any detail ("not engaged yet: waiting
    for start and a confident lane" -> "not engaged yet")."""
    return reason.split(":", 1)[0].strip() or reason


#: What "not engaged yet" means for a still held in view from a start: never confident enough,
#: long enough.
NOT_ENGAGED_WORDS = {"not engaged yet": "no confident lane long enough"}


def not_engaged_words(reason: str) -> str:
    """A halt reason (or its `reason_key`) as the survey says it of a still that did not engage:
    "no confident lane long enough" for the supervisor's "not engaged yet", else as it is."""
    return NOT_ENGAGED_WORDS.get(reason_key(reason), reason)


def not_engaged_counts(reasons: Iterable[str | None]) -> tuple[tuple[str, int], ...]:
    """Lane stills the supervisor did not engage on, counted by reason (`reason_key`), most
    first (ties: by name)."""
    counts = Counter(reason_key(reason) for reason in reasons if reason is not None)
    return tuple(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def confident_runs(results: Sequence[FrameResult]) -> list[ConfidentRun]:
    """Runs of consecutive confident frames (`order` one apart), longest first (ties: earlier
    first)."""
    runs: list[tuple[int, int, FrameResult, FrameResult]] = []
    start: FrameResult | None = None
    previous: FrameResult | None = None
    length = 0
    for result in sorted(results, key=lambda r: r.frame.order):
        follows = previous is not None and result.frame.order == previous.frame.order + 1
        if result.confident and start is not None and follows:
            length += 1
        else:
            if start is not None and previous is not None:
                runs.append((length, start.frame.order, start, previous))
            start, length = (result, 1) if result.confident else (None, 0)
        previous = result
    if start is not None and previous is not None:
        runs.append((length, start.frame.order, start, previous))
    runs.sort(key=lambda r: (-r[0], r[1]))
    return [ConfidentRun(a.frame.name, b.frame.name, n) for n, _, a, b in runs]


def component_figures(results: Sequence[FrameResult]) -> list[ComponentFigure]:
    """Every component seen, most often the weakest first (then the lowest median)."""
    values: dict[str, list[float]] = {}
    weakest: dict[str, list[float]] = {}
    for result in results:
        for name, value in result.components.items():
            values.setdefault(name, []).append(value)
        low = result.weakest
        if low is not None:
            weakest.setdefault(low[0], []).append(low[1])
    figures = [ComponentFigure(name, len(weakest.get(name, ())), statistics.median(v),
                               statistics.median(weakest[name]) if name in weakest else math.nan)
               for name, v in values.items()]
    figures.sort(key=lambda f: (-f.weakest_in, f.median, f.name))
    return figures


def class_figures(expect: str, results: Sequence[FrameResult]) -> ClassFigures:
    mine = [r for r in results if r.frame.expect == expect]
    return ClassFigures(
        expect=expect,
        frames=len(mine),
        decisions=sum(r.has_decision for r in mine),
        confident=sum(r.confident for r in mine),
        false_lanes=tuple(r for r in mine if r.false_lane),
        runs=tuple(confident_runs(mine)[:RUNS_SHOWN]),
        components=tuple(component_figures(mine)),
    )


def judge(results: Iterable[FrameResult], engage: EngageFigures | None) -> SurveyFigures:
    """The figures per class and the verdict (SAFE: no decision on any no-lane frame)."""
    ordered = tuple(sorted(results, key=lambda r: r.frame.order))
    classes = {expect: class_figures(expect, ordered) for expect in EXPECTS}
    false_lanes = classes[NONE].false_lanes
    verdict = Verdict(safe=classes[NONE].frames > 0 and not false_lanes, false_lanes=false_lanes,
                      no_lane_frames=classes[NONE].frames, engage=engage)
    return SurveyFigures(MappingProxyType(classes), verdict, ordered)


# ---- words ------------------------------------------------------------------------------------
#: "frame 51" or "frame 51 (frame_0204.png)" (`replay_sources.frame_name`): a frame number and
#: a file name (no spaces, an extension), not words ("frame 11 (straight at 0.53)").
_NUMBERED = re.compile(r"frame (\d+)(?: \(([^\s()]+\.\w+)\))?")


def _compact(names: Sequence[str]) -> list[str]:
    """"frame 6", "frame 7", "frame 8" -> "frames 6-8", and with their files ("frame 6
    (a.png)", ...) -> "frames 6-8 (a.png .. c.png)"; other names as they are."""
    out: list[str] = []
    run: list[tuple[int, str | None]] = []

    def flush() -> None:
        if run:
            (first, first_file), (last, last_file) = run[0], run[-1]
            files = (f" ({first_file})" if len(run) == 1 else f" ({first_file} .. {last_file})"
                     ) if first_file and last_file else ""
            out.append(f"frame {first}{files}" if len(run) == 1
                       else f"frames {first}-{last}{files}")
            run.clear()

    for name in names:
        if numbered := _NUMBERED.fullmatch(name):
            number = int(numbered.group(1))
            if run and (number != run[-1][0] + 1 or (numbered.group(2) is None)
                        != (run[-1][1] is None)):
                flush()
            run.append((number, numbered.group(2)))
        else:
            flush()
            out.append(name)
    flush()
    return out


def name_frames(names: Sequence[str], limit: int = NAMES_SHOWN) -> str:
    """Frames named in one line: consecutive frame numbers as ranges, at most `limit` items."""
    items = _compact(names)
    shown = ", ".join(items[:limit])
    return shown + (f" and {len(items) - limit} more" if len(items) > limit else "")


def false_lanes_text(count: int) -> str:
    """'1 false lane', '3 false lanes'."""
    return counted(count, "false lane")


def _percent(part: int, whole: int) -> str:
    return f"{100.0 * part / whole:.0f}%" if whole else "-"


def uncounted_text(figures: ClassFigures) -> str:
    """' (2 only in a shifted version)', ' (1 only judged on its own)': the false lanes no frame
    as judged showed ('' if none), beside a count of decisions that leaves them out (the
    terminal's line, the report's table)."""
    hidden = [r for r in figures.false_lanes if not r.has_decision]
    parts = [f"{n} only {where}" for n, where in (
        (sum(r.shifted_decisions > 0 for r in hidden), "in a shifted version"),
        (sum(r.decided_on_its_own and not r.shifted_decisions for r in hidden),
         "judged on its own")) if n]
    return f" ({', '.join(parts)})" if parts else ""


def class_line(figures: ClassFigures) -> str:
    """One line per class for the terminal."""
    title = CLASS_FOLDERS[figures.expect]
    text = (f"{title}: {counted(figures.frames, 'frame')}, {figures.decisions} with a decision "
            f"({_percent(figures.decisions, figures.frames)}), {figures.confident} confident")
    if figures.expect == NONE:
        text += f", {false_lanes_text(len(figures.false_lanes))}{uncounted_text(figures)}"
    if figures.runs:
        run = figures.runs[0]
        span = run.first if run.length == 1 else f"{run.first} .. {run.last}"
        text += f"; longest confident run {run.length} ({span})"
    else:
        text += "; no confident frame"
    weak = [c for c in figures.components if c.weakest_in][:3]
    if weak:
        first, *others = weak
        text += (f"; weakest: {first.name} in {counted(first.weakest_in, 'frame')} (median there "
                 f"{first.median_where_weakest:.2f})" + "".join(
                     f", {c.name} in {c.weakest_in} ({c.median_where_weakest:.2f})"
                     for c in others))
    return text


def verdict_line(verdict: Verdict) -> str:
    if verdict.no_lane_frames == 0:
        return "verdict: NOT SAFE: no no-lane frame was surveyed"
    if verdict.safe:
        if verdict.no_lane_frames == 1:
            return "verdict: SAFE: no decision on the only no-lane frame"
        return (f"verdict: SAFE: no decision on any of the {verdict.no_lane_frames} no-lane "
                "frames")
    return f"verdict: NOT SAFE: {false_lanes_named(verdict.false_lanes)}"


def false_lanes_named(false_lanes: Sequence[FrameResult]) -> str:
    """"2 false lanes (a decision on a no-lane frame): a.jpg, b.jpg", naming each; where a
    false lane's frame as judged had none, where the decision was: "... or a shifted version of
    it", "..., judged in sequence or on its own"."""
    names = [false_lane_name(r) for r in false_lanes]
    hidden = [r for r in false_lanes if not r.has_decision]
    shifted = " or a shifted version of it" if any(r.shifted_decisions for r in hidden) else ""
    alone = (", judged in sequence or on its own"
             if any(r.decided_on_its_own for r in hidden) else "")
    return (f"{false_lanes_text(len(names))} (a decision on a no-lane frame{shifted}{alone}): "
            f"{name_frames(names)}")


def false_lane_name(result: FrameResult) -> str:
    """A false lane's name, with how many shifted versions got a decision where any did, and
    the decision it got on its own where only that one decided: "free/a.jpg (shifted: 5 of
    16)", "frame 512 (on its own: straight at 0.33)"."""
    name = result.frame.name
    if result.shifted is not None and result.shifted_decisions:
        name += f" (shifted: {result.shifted_decisions} of {result.shifted.versions})"
    if result.on_its_own is not None and result.decided_on_its_own and not result.has_decision:
        name += f" (on its own: {on_its_own_text(result.on_its_own)})"
    return name


def on_its_own_text(judged: OnItsOwn) -> str:
    """'straight at 0.33', 'none at 0.00'."""
    return f"{judged.decision} at {judged.confidence:.2f}"


def engage_line(engage: EngageFigures | None) -> str:
    if engage is None or engage.attempts == 0:
        return "supervisor: no lane frame to engage on"
    if engage.how == "held":
        text = (f"supervisor: engages on {engage.engaged} of {engage.attempts} lane stills held "
                f"in view for {engage.window_s:.1f} s after a start")
        if engage.times_s:
            text += f" (after {max(engage.times_s):.2f} s at the most)"
        if engage.not_engaged:
            missed = sum(n for _, n in engage.not_engaged)
            text += f"; not on {missed} (" + "; ".join(
                f"{n}: {not_engaged_words(key)}" for key, n in engage.not_engaged) + ")"
        return text
    if not engage.engaged:
        return (f"supervisor: never engages on this sequence ({engage.window_s:.1f} s replayed, "
                "started at its first frame and resumed after every halt)")
    when = f"{engage.times_s[0]:.2f} s" if engage.times_s else "?"
    text = (f"supervisor: engages at {engage.first_engaged} ({when} after the start); engaged "
            f"on {engage.engaged_lane_frames} of {engage.lane_frames} lane frames "
            f"({_percent(engage.engaged_lane_frames, engage.lane_frames)})")
    if engage.halts:
        text += (f"; {counted(len(engage.halts), 'halt')} ({', '.join(engage.halts[:3])}"
                 f"{', ...' if len(engage.halts) > 3 else ''})")
    return text


def shifted_line(results: Sequence[FrameResult]) -> str | None:
    """What the shifted versions of the no-lane stills showed (None: none were made)."""
    judged = [r.shifted for r in results if r.shifted is not None]
    if not judged:
        return None
    versions = judged[0].versions
    hit = [r for r in results if r.shifted_decisions]
    decided = sum(r.shifted_decisions for r in hit)
    text = (f"no-lane, each in {counted(versions, 'version')} shifted by a fraction of a pixel: "
            f"{counted(decided, 'decision')} in {versions * len(judged)}")
    if hit:
        text += f", on {len(hit)} of {counted(len(judged), 'frame')}: " + name_frames(
            [false_lane_name(r) for r in hit])
    return text


def on_its_own_line(results: Sequence[FrameResult]) -> str | None:
    """What a recording's no-lane frames showed judged each on its own (None: none was)."""
    judged = [r for r in results if r.on_its_own is not None]
    if not judged:
        return None
    hit = [r for r in judged if r.decided_on_its_own]
    text = (f"no-lane, each also judged on its own (as a photo is, without the frame before it): "
            f"{counted(len(hit), 'decision')} in {counted(len(judged), 'frame')}")
    if hit:
        text += ": " + name_frames([f"{r.frame.name} ({on_its_own_text(r.on_its_own)})"
                                    for r in hit if r.on_its_own is not None])
    return text


def summary_lines(figures: SurveyFigures) -> list[str]:
    extra = [line for line in (shifted_line(figures.results), on_its_own_line(figures.results))
             if line is not None]
    return [*(class_line(figures.classes[e]) for e in EXPECTS), *extra,
            verdict_line(figures.verdict), engage_line(figures.verdict.engage)]


# ---- what a stricter setting makes of the same frames -----------------------------------------
@dataclass(frozen=True)
class StricterSetting:
    """A setting that refuses a kind of evidence false lanes on real floors rested on, tried on
    the same frames when a survey is NOT SAFE (`lanewarden survey`): the config `key` (dotted),
    the `value` tried, what it `does` and what it `costs`."""

    key: str
    value: float
    does: str
    costs: str

    @property
    def as_config(self) -> str:
        """The setting as a config file says it: 'perception: {tape: {unverifiable_score: 0}}'."""
        *parents, leaf = self.key.split(".")
        text = f"{leaf}: {self.value:g}"
        for parent in reversed(parents):
            text = f"{parent}: {{{text}}}"
        return text

    def nested(self) -> dict[str, Any]:
        """The setting as a nested mapping, for merging over a config's."""
        *parents, leaf = self.key.split(".")
        mapping: dict[str, Any] = {leaf: self.value}
        for parent in reversed(parents):
            mapping = {parent: mapping}
        return mapping


#: The stricter settings a NOT SAFE survey tries. Every false lane on the repository's real
#: footage paired a tape with an edge at the image's border, whose tape cannot be checked
#: (`tape.unverifiable_score`, docs/perception.md rule 7): the JetBot stills' shifted versions
#: (`--jitter 16`: 11 decisions on 2 stills) and the Donkeycar tub's frames 507-517 and 958 with
#: tests/perception/donkeycar_engage.yaml. The default keeps such edges: in the simulator's
#: bends at 320x240 the inner tape leaves the view and is one (with 0, those bends halt).
STRICTER_SETTINGS = (
    StricterSetting(
        "perception.tape.unverifiable_score", 0.0,
        does="an edge at the image's border, whose tape cannot be checked, never stands in for "
             "the lane's other tape",
        costs="a bend whose inner tape leaves the view is then no lane, and the robot halts "
              "there (LANE_LOST)"),
)


@dataclass(frozen=True)
class WhatIf:
    """The same frames surveyed again with one stricter `setting`: its `figures`."""

    setting: StricterSetting
    figures: SurveyFigures


def what_if_lines(what_if: WhatIf, before: SurveyFigures) -> list[str]:
    """What the stricter setting made of the frames, against the survey as given: its verdict,
    the lane frames with a decision and confident ones, whether the supervisor engages, and how
    to drive with it and what it costs."""
    setting, after = what_if.setting, what_if.figures
    lane_before, lane_after = before.classes[LANE], after.classes[LANE]
    verdict = verdict_line(after.verdict).removeprefix("verdict: ")
    return [
        f"what if {setting.key} were {setting.value:g} ({setting.does}): {verdict} (was "
        f"{counted(len(before.verdict.false_lanes), 'false lane')})",
        f"  with it: lane frames with a decision {lane_after.decisions} (was "
        f"{lane_before.decisions}), confident {lane_after.confident} (was "
        f"{lane_before.confident}); {engage_line(after.verdict.engage)}",
        f"  {what_if_advice(what_if)}",
    ]


def what_if_advice(what_if: WhatIf) -> str:
    """How to drive with a stricter setting and what it costs, only where it makes the survey
    SAFE with the supervisor still engaging; otherwise why not to (a new user was told to add
    a setting that left the survey NOT SAFE, or with which the robot never engages)."""
    setting, verdict = what_if.setting, what_if.figures.verdict
    if not verdict.safe:
        return ("it does not make these frames safe: not a setting to drive with (look at the "
                "pictures of the false lanes left, and check their labels)")
    if verdict.engage is None or not verdict.engage.would_engage:
        return ("it makes these frames safe, but the supervisor never engages with it: not a "
                "setting to drive with")
    return (f"to drive with it, set in --config (merged into its perception: section if it has "
            f"one): {setting.as_config}; what it costs: {setting.costs}")


def what_if_json(what_if: WhatIf) -> dict[str, Any]:
    """survey.json's entry for a stricter setting tried."""
    setting, figures = what_if.setting, what_if.figures
    lane = figures.classes[LANE]
    return {
        "setting": setting.key, "value": setting.value, "config": setting.as_config,
        "does": setting.does, "costs": setting.costs, "advice": what_if_advice(what_if),
        "verdict": _verdict_json(figures.verdict),
        "lane": {"frames": lane.frames, "decisions": lane.decisions,
                 "confident": lane.confident},
        "engage": _engage_json(figures.verdict.engage),
        "engage_text": engage_line(figures.verdict.engage).removeprefix("supervisor: "),
    }


def survey_notes(figures: SurveyFigures, calibrated: bool, ground_pose: bool = True,
                 calibration_name: str = "the --calibration", beside: str = "") -> list[str]:
    """What a verdict does not say: that perception never found the lane either (a SAFE verdict
    then proves little: a wrong tape width or camera also gives no decision anywhere), and that
    without a calibration the frames were judged through the simulator's default camera, or
    with one that has no ground pose (`ground_pose` False) on the simulator's mount (a new
    user's survey with `calibrate`'s file alone said SAFE with no note; `calibration_name`
    says which: "--calibration FILE", "the recording's calibration"; `beside`: where a clip's
    own calibration lies, `camera_clip.clip_calibration_hint`'s words, ending the note on a
    survey without one)."""
    notes = []
    lane = figures.classes[LANE]
    little = ", so SAFE says little" if figures.verdict.safe else ""
    check = ("check perception.tape and perception.lane in --config (the widths of your tape "
             "and lane) and --calibration (the camera and its pose)")
    engage = figures.verdict.engage
    if lane.frames and not lane.decisions:
        notes.append(f"note: no decision on any of the {counted(lane.frames, 'lane frame')} "
                     f"either: perception never found your lane{little}; {check}")
    elif lane.frames and engage is not None and engage.attempts and not engage.engaged:
        # a few decisions, never enough to engage: a student read that SAFE as "good to go"
        notes.append(f"note: the supervisor engages on none of the "
                     f"{counted(lane.frames, 'lane frame')} ({lane.decisions} with a decision): "
                     f"this robot would never drive here{little}; {check}")
    few = figures.verdict.no_lane_frames
    if figures.verdict.safe and 0 < few < RECIPE_NO_LANE_FRAMES:
        # a new user's survey of 2 no-lane photos said SAFE with nothing more
        notes.append(f"note: SAFE on {counted(few, 'no-lane frame')} says little: the recipe "
                     f"takes at least {RECIPE_NO_LANE_FRAMES} (bare floor with its seams, one "
                     "tape alone, the tape's end, a dark spot, clutter; README, 'Before you "
                     "drive: survey your floor')")
    if not calibrated:
        notes.append("note: no --calibration: the frames were judged as if from the simulator's "
                     "default camera (its lens, height and pitch); with your camera's "
                     "calibration (lanewarden calibrate, then calibrate ground) the figures are "
                     f"your camera's{beside}")
    elif not ground_pose:
        notes.append(f"note: {calibration_name} has no ground pose: the frames were judged as if "
                     f"your camera were mounted as the simulator's ({default_pose().describe()}), "
                     "so tapes and seams were measured through that mount; with its ground pose "
                     "(lanewarden calibrate ground) the figures are your camera's")
    return notes


# ---- survey.json ------------------------------------------------------------------------------
def _result_json(result: FrameResult) -> dict[str, Any]:
    weakest = result.weakest
    out: dict[str, Any] = {
        "frame": result.frame.name,
        "expect": result.frame.expect,
        "decision": result.decision,
        "confidence": round(result.confidence, 4),
        "confident": result.confident,
        "weakest": None if weakest is None else weakest[0],
        "components": {k: round(v, 4) for k, v in result.components.items()},
    }
    if result.engaged_after_s is not None or result.engaged is not None:
        out["engaged"] = bool(result.engaged) if result.engaged is not None else True
    if result.engaged_after_s is not None:
        out["engaged_after_s"] = round(result.engaged_after_s, 4)
    if result.not_engaged is not None:
        out["not_engaged_because"] = not_engaged_words(result.not_engaged)  # as printed
    if result.shifted is not None:
        out["shifted"] = {"versions": result.shifted.versions,
                          "decisions": len(result.shifted.decided),
                          "confidences": [round(c, 4) for c in result.shifted.decided]}
    if result.on_its_own is not None:
        out["on_its_own"] = {"decision": result.on_its_own.decision,
                             "confidence": round(result.on_its_own.confidence, 4)}
    if result.frame.note:
        out["note"] = result.frame.note
    return out


def _class_json(figures: ClassFigures) -> dict[str, Any]:
    return {
        "frames": figures.frames,
        "decisions": figures.decisions,
        "confident": figures.confident,
        "false_lanes": [r.frame.name for r in figures.false_lanes],
        "longest_confident_runs": [{"first": r.first, "last": r.last, "frames": r.length}
                                   for r in figures.runs],
        "components": [{"name": c.name, "weakest_in": c.weakest_in,
                        "median": round(c.median, 4),
                        "median_where_weakest": (None if math.isnan(c.median_where_weakest)
                                                 else round(c.median_where_weakest, 4))}
                       for c in figures.components],
    }


def _engage_json(engage: EngageFigures | None) -> dict[str, Any] | None:
    if engage is None:
        return None
    figures: dict[str, Any] = {
        "how": engage.how,
        "would_engage": engage.would_engage,
        "window_s": round(engage.window_s, 4),
        "attempts": engage.attempts,
        "engaged": engage.engaged,
        "times_s": [round(t, 4) for t in engage.times_s],
    }
    if engage.how == "held":
        figures["not_engaged"] = {not_engaged_words(key): n for key, n in engage.not_engaged}
    if engage.how == "sequence":  # a sequence's own figures (stills had shown 0s and null)
        figures.update(first_engaged=engage.first_engaged,
                       engaged_lane_frames=engage.engaged_lane_frames,
                       lane_frames=engage.lane_frames, halts=list(engage.halts))
    return figures


def _verdict_json(verdict: Verdict) -> dict[str, Any]:
    """A verdict in survey.json (the survey's, and a stricter setting's): safe, its text, the
    false lanes named."""
    return {"safe": verdict.safe, "text": verdict_line(verdict).removeprefix("verdict: "),
            "false_lanes": [r.frame.name for r in verdict.false_lanes]}


def survey_json(figures: SurveyFigures, about: Mapping[str, Any],
                what_ifs: Sequence[WhatIf] = ()) -> dict[str, Any]:
    """survey.json: `about` (source, config, calibration, ground model), the verdict, the figures
    per class, the stricter settings tried (`what_if`: a NOT SAFE survey's) and every frame's
    result."""
    verdict = figures.verdict
    false_lanes = {id(r) for r in verdict.false_lanes}  # (the verdict holds the results)
    return {
        **about,
        "verdict": {
            **_verdict_json(verdict),
            "would_engage": verdict.engage is not None and verdict.engage.would_engage,
            "engage_text": engage_line(verdict.engage).removeprefix("supervisor: "),
        },
        "classes": {CLASS_FOLDERS[e]: _class_json(figures.classes[e]) for e in EXPECTS},
        "engage": _engage_json(verdict.engage),
        "what_if": [what_if_json(w) for w in what_ifs],
        "frames": [{**_result_json(r), "false_lane": id(r) in false_lanes}
                   for r in figures.results],
    }
