"""A campaign's summaries for people and for CI: report.html and junit.xml, from the result rows.

- junit.xml: one testcase per run (classname `campaign.<scenario>`, name `<id> <fault kinds>`);
  `unsafe` and `false_halt` are failures, `error` is an error, the rest pass.
- report.html: outcome counts, the outcome matrices (`MATRICES`: fault kind x outcome, scenario x
  outcome, camera x outcome, and floor, tape and camera effect x outcome when the campaign
  draws them; another table is one more entry), the time to halt per fault kind
  (from the moment the fault the halt answered took effect, with its distribution on one shared
  axis), the worst cases (every unsafe run and false halt, then the slowest safe halt of each
  fault kind), the blind halts (safe halts while the camera showed no lane,
  `outcome.blind_halt`: not failures, but worth a look) and the runs in error, each with the
  command that reruns it (selectable, with a copy button).

Rows are read once, one at a time (`CampaignSummary.add`): what the report keeps is bounded
(counts, one number per safe halt, a few rows per list), so a 100,000-run campaign's report costs
no more memory than its counts. Pure formatting of stored rows: never runs anything, never reads a
clock.
"""

from __future__ import annotations

import heapq
import html
import math
import shlex
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO
from xml.sax.saxutils import quoteattr

from lanewarden.documents import read_json
from lanewarden.scenarios.before_halt import describe as describe_before_halt
from lanewarden.scenarios.campaign.outcome import (
    FAILURES,
    OUTCOMES,
    answered_kind,
    blind_halt,
)
from lanewarden.scenarios.false_lane import FALSE_LANE_TOLERANCE_M
from lanewarden.wording import counted

#: How many unsafe runs, false halts and errors the report lists (each; the rest are counted).
LISTED_PER_OUTCOME = 25
_COLORS = {"safe_halt": "#2e7d32", "recovered": "#558b2f", "nominal": "#9e9e9e",
           "false_halt": "#ef6c00", "unsafe": "#c62828", "error": "#6a1b9a"}

Row = Mapping[str, Any]


def rerun_command(out_dir: Path, case_id: str) -> str:
    """The command that reruns a case, with its absolute path: it works copied from the report
    whatever folder the reader is in (a relative --out made it work only where the campaign
    was started)."""
    case = out_dir.resolve() / "cases" / f"{case_id}.yaml"
    return f"lanewarden sim --case {shlex.quote(str(case))}"


def _kinds(row: Row) -> list[str]:
    text = str(row.get("fault_kinds") or "")
    return [k for k in text.split(",") if k] or ["(none)"]


#: The outcome matrices: (title, the keys a row counts under). Another table is one more entry.
MATRICES: list[tuple[str, Callable[[Row], list[str]]]] = [
    ("Fault kind x outcome", _kinds),
    ("Scenario x outcome", lambda r: [str(r.get("scenario"))]),
    ("Camera x outcome", lambda r: [str(r.get("camera"))]),
    ("Floor x outcome", lambda r: [str(r.get("floor") or "?")]),
    ("Tape x outcome", lambda r: [str(r.get("tape") or "?")]),
    ("Camera effect x outcome", lambda r: [str(r.get("effect") or "?")]),
]
#: What the runs were seen through (floor, tape, camera effect): a table only when the campaign
#: drew them (a spec without looks leaves them at the scenario's own or unset).
LOOK_MATRICES = frozenset({"Floor x outcome", "Tape x outcome", "Camera effect x outcome"})
_NO_LOOK = frozenset({"", "?", "scenario", "default"})


def _time_to_halt_s(row: Row) -> float | None:
    value = row.get("time_to_halt_s")
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else None


@dataclass
class _Kept:
    """The few rows of one list (the `limit` first by `key`, smallest first)."""

    limit: int
    heap: list[tuple[tuple[float, int], int, Row]] = field(default_factory=list)
    count: int = 0

    def offer(self, key: tuple[float, int], row: Row) -> None:
        self.count += 1
        item = ((-key[0], -key[1]), self.count, row)  # a max-heap of the kept: drop the largest
        if len(self.heap) < self.limit:
            heapq.heappush(self.heap, item)
        elif item > self.heap[0]:
            heapq.heapreplace(self.heap, item)

    def rows(self) -> list[Row]:
        return [row for _, _, row in sorted(self.heap, reverse=True)]


class CampaignSummary:
    """Everything report.html and junit.xml need, accumulated one row at a time."""

    def __init__(self, matrices: Sequence[tuple[str, Callable[[Row], list[str]]]] = ()) -> None:
        self.matrices = list(matrices or MATRICES)
        self.counts: Counter[str] = Counter()
        self.tables: list[dict[str, Counter[str]]] = [defaultdict(Counter) for _ in self.matrices]
        self.time_to_halt: dict[str, list[float]] = defaultdict(list)
        self.slowest: dict[str, tuple[float, Row]] = {}
        self.listed = {outcome: _Kept(LISTED_PER_OUTCOME) for outcome in (*FAILURES, "error")}
        #: safe halts while the camera showed no lane (`outcome.blind_halt`), in run order
        self.blind = _Kept(LISTED_PER_OUTCOME)
        #: runs that trusted a lane off the tapes while engaged (`scenarios.false_lane`), the
        #: longest stretch first, and every such run's frames on it
        self.false_lane = _Kept(LISTED_PER_OUTCOME)
        self.false_lane_frames = 0
        #: runs whose metrics hold the false-lane figures (not those stored before they existed)
        self.false_lane_measured = 0
        self.cpu_s = 0.0
        self.sim_s = 0.0
        self.timed = 0
        self.wall_s = 0.0

    @property
    def runs(self) -> int:
        return sum(self.counts.values())

    def add(self, row: Row) -> None:
        outcome = str(row["outcome"])
        self.counts[outcome] += 1
        for table, (_, keys) in zip(self.tables, self.matrices, strict=True):
            for key in keys(row):
                table[key][outcome] += 1
        index = int(row.get("idx") or 0)
        to_halt = _time_to_halt_s(row)
        slim = _slim(row)
        if outcome in self.listed:
            # unsafe and false halts: the slowest to halt first (never halting: slowest of all)
            slow = to_halt if to_halt is not None else math.inf
            self.listed[outcome].offer((-slow if outcome != "error" else 0.0, index), slim)
        if outcome == "safe_halt" and blind_halt(str(row.get("reason") or "")):
            self.blind.offer((0.0, index), slim)
        if slim["false_lane_frames"] is not None:
            self.false_lane_measured += 1
        if slim["false_lane_frames"]:
            self.false_lane_frames += int(slim["false_lane_frames"])
            self.false_lane.offer((-float(slim["false_lane_longest_s"] or 0.0), index), slim)
        kind = answered_kind(str(row.get("reason") or ""))
        if outcome == "safe_halt" and kind is not None and to_halt is not None:
            self.time_to_halt[kind].append(to_halt)
            if kind not in self.slowest or to_halt > self.slowest[kind][0]:
                self.slowest[kind] = (to_halt, _slim(row))
        if isinstance(row.get("cpu_s"), int | float) and isinstance(row.get("sim_time_s"),
                                                                     int | float):
            self.cpu_s += float(row["cpu_s"])
            self.sim_s += float(row["sim_time_s"])
            self.timed += 1
        self.wall_s += float(row.get("wall_s") or 0.0)


def _slim(row: Row) -> dict[str, Any]:
    """What a listed row shows (the rest of a row, its metrics and effects, is not kept)."""
    metrics = read_json(row.get("metrics_json") or "{}")
    keep = ("id", "idx", "outcome", "scenario", "camera", "fault_kinds", "reason",
            "time_to_halt_s")
    return {**{k: row.get(k) for k in keep},
            "max_cross_track_error_m": metrics.get("max_cross_track_error_m"),
            "before_halt": metrics.get("before_halt"),
            **{k: metrics.get(k) for k in ("false_lane_frames", "false_lane_longest_s",
                                           "max_edge_error_m", "min_tape_clearance_m")}}


# ---- junit.xml --------------------------------------------------------------------------------
def write_junit(path: Path, name: str, rows: Iterable[Row], summary: CampaignSummary) -> None:
    """junit.xml, one testcase per run, written as the rows come (`summary`: their counts)."""
    counts = summary.counts
    with path.open("w", encoding="utf-8") as out:
        out.write("<?xml version='1.0' encoding='utf-8'?>\n")
        out.write(f"<testsuite name={quoteattr(f'campaign.{name}')} tests=\"{summary.runs}\" "
                  f"failures=\"{sum(counts[o] for o in FAILURES)}\" "
                  f"errors=\"{counts['error']}\" time=\"{summary.wall_s:.3f}\">\n")
        for row in rows:
            _junit_case(out, row, path.parent)
        out.write("</testsuite>\n")


def _junit_case(out: TextIO, row: Row, out_dir: Path) -> None:
    outcome = str(row["outcome"])
    message = f"{outcome}: {row.get('reason') or ''}"
    classname = quoteattr(f"campaign.{row['scenario']}")
    name = quoteattr(f"{row['id']} {'+'.join(_kinds(row))}")
    out.write(f"  <testcase classname={classname} name={name} "
              f"time=\"{float(row.get('wall_s') or 0.0):.3f}\">\n")
    if outcome in FAILURES:
        out.write(f"    <failure message={quoteattr(message)} type={quoteattr(outcome)} />\n")
    elif outcome == "error":
        out.write(f"    <error message={quoteattr(message)} type=\"error\" />\n")
    # the rerun command as report.html gives it: it works from wherever junit.xml is read
    text = (f"{message}\nhalt reason: {row.get('halt_reason') or '-'}\n"
            f"rerun: {rerun_command(out_dir, str(row['id']))}")
    out.write(f"    <system-out>{html.escape(text, quote=False)}</system-out>\n  </testcase>\n")


# ---- report.html ------------------------------------------------------------------------------
def _matrix(title: str, table: Mapping[str, Counter[str]]) -> str:
    head = "".join(f"<th>{o}</th>" for o in OUTCOMES)
    body = []
    for key in sorted(table):
        cells = []
        for outcome in OUTCOMES:
            n = table[key][outcome]
            style = f' style="color:{_COLORS[outcome]};font-weight:bold"' if n and outcome in (
                *FAILURES, "error") else ""
            cells.append(f"<td{style}>{n or ''}</td>")
        body.append(f"<tr><th>{html.escape(key)}</th>{''.join(cells)}"
                    f"<td>{sum(table[key].values())}</td></tr>")
    note = MATRIX_NOTES.get(title, "")
    return (f"<h2>{html.escape(title)}</h2>{note}<table><tr><th></th>{head}<th>runs</th></tr>"
            f"{''.join(body)}</table>")


#: What a table's rows do not say by themselves (a new user added up the fault-kind table's runs).
MATRIX_NOTES = {
    "Fault kind x outcome": (
        "<p>A run with two faults counts under each of its kinds, with the run's one outcome "
        "(so this table's runs add up to more than the campaign's, and a safe halt is listed "
        "under both kinds even when it answered only one: the worst cases below say which)."
        "</p>"),
}


def nice_axis(low: float, high: float, count: int = 5) -> tuple[float, float, list[float]]:
    """An axis from `low` to `high` on round numbers: (start, end, tick values)."""
    low, high = min(low, 0.0), max(high, low + 1e-3)
    raw = (high - low) / count
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1, 2, 2.5, 5, 10) if m * power >= raw)
    first, last = math.floor(low / step + 1e-9), math.ceil(high / step - 1e-9)
    ticks = [round(i * step, 10) for i in range(first, last + 1)]
    return ticks[0], ticks[-1], ticks


#: Up to this many halts a distribution shows each one (a dot); more: a histogram.
DOTS_UP_TO = 60
_PLOT_W, _PLOT_H, _PAD = 340, 46, 14
_BINS = 40


def distribution_svg(values: Sequence[float], axis: tuple[float, float, list[float]]) -> str:
    """The times of one fault kind on the shared `axis` (seconds): a dot per halt (or a
    histogram when there are many), the median as a bar, and the axis with its labels."""
    start, end, ticks = axis
    inner = _PLOT_W - 2 * _PAD

    def x(value: float) -> float:
        return _PAD + (value - start) / (end - start) * inner

    marks: list[str] = []
    for tick in ticks:
        marks.append(f'<line x1="{x(tick):.1f}" y1="4" x2="{x(tick):.1f}" y2="28" '
                     'stroke="#e4e4e4"/>'
                     f'<text x="{x(tick):.1f}" y="41" font-size="10" text-anchor="middle" '
                     f'fill="#555">{tick:g}</text>')
    marks.append(f'<line x1="{_PAD}" y1="28" x2="{_PLOT_W - _PAD}" y2="28" stroke="#555"/>')
    if len(values) <= DOTS_UP_TO:
        for i, value in enumerate(sorted(values)):
            y = 8 + (i * 7) % 17  # spread, deterministic
            marks.append(f'<circle cx="{x(value):.1f}" cy="{y}" r="3" fill="#1565c0" '
                         'fill-opacity="0.6"/>')
    else:
        counts = [0] * _BINS
        for value in values:
            counts[min(_BINS - 1, max(0, int((value - start) / (end - start) * _BINS)))] += 1
        top = max(counts)
        width = inner / _BINS
        for i, n in enumerate(counts):
            if n:
                height = 22 * n / top
                marks.append(f'<rect x="{_PAD + i * width:.1f}" y="{28 - height:.1f}" '
                             f'width="{max(width - 0.5, 0.5):.1f}" height="{height:.1f}" '
                             'fill="#1565c0"/>')
    median = _quantile(values, 0.5)
    marks.append(f'<line x1="{x(median):.1f}" y1="3" x2="{x(median):.1f}" y2="28" '
                 'stroke="#c62828" stroke-width="2"/>')
    label = (f"{counted(len(values), 'halt')} from {min(values):.3f} s to {max(values):.3f} s, "
             f"median {median:.3f} s")
    return (f'<svg width="{_PLOT_W}" height="{_PLOT_H}" role="img" '
            f'aria-label="{html.escape(label)}"><title>{html.escape(label)}</title>'
            f'{"".join(marks)}</svg>')


def _quantile(values: Sequence[float], q: float) -> float:
    ordered = sorted(values)
    pos = q * (len(ordered) - 1)
    lo, hi = math.floor(pos), math.ceil(pos)
    return ordered[lo] + (ordered[hi] - ordered[lo]) * (pos - lo)


def _time_to_halt(summary: CampaignSummary) -> str:
    by_kind = summary.time_to_halt
    if not by_kind:
        return "<h2>Time to halt (safe halts)</h2><p>No safe halt answered a fault.</p>"
    every = [v for values in by_kind.values() for v in values]
    axis = nice_axis(min(every), max(every))
    lines = []
    for kind in sorted(by_kind):
        values = by_kind[kind]
        lines.append(
            f"<tr><th>{html.escape(kind)}</th><td>{len(values)}</td>"
            f"<td>{min(values):.3f}</td><td>{_quantile(values, 0.5):.3f}</td>"
            f"<td>{_quantile(values, 0.95):.3f}</td><td>{max(values):.3f}</td>"
            f'<td class="plot">{distribution_svg(values, axis)}</td></tr>')
    return ("<h2>Time to halt (safe halts)</h2><p>From the moment the fault the halt answered "
            "took effect (its first frame or packet that changed) to HALT, seconds, under that "
            "fault's kind; halts at the end of the tape answer no fault and are not here. A "
            "floor fault (a mark, a patch, a shadow) takes effect when it first comes into view, "
            "which may be before the robot has engaged: its time includes the start. Every "
            "row is drawn on the same axis: a dot per halt (a histogram above "
            f"{DOTS_UP_TO}), the red bar the median.</p><table><tr>"
            "<th>fault kind</th><th>runs</th><th>min</th>"
            "<th>median</th><th>p95</th><th>max</th><th>distribution (s)</th></tr>"
            f"{''.join(lines)}</table>")


def _rerun_cell(out_dir: Path, case_id: str) -> str:
    command = html.escape(rerun_command(out_dir, case_id))
    # A long path wraps after a slash (<wbr>: no character, so a selection copies the command)
    shown = command.replace("/", "/<wbr>")
    return (f'<td class="rerun"><code class="cmd">{shown}</code> <button type="button" '
            f'class="copy" data-copy="{command}" title="copy the command">copy</button></td>')


def _run_cells(row: Row) -> str:
    """A listed run's first cells: its id, outcome (in its colour), scenario and camera."""
    return (f"<td>{html.escape(str(row['id']))}</td>"
            f"<td style=\"color:{_COLORS.get(str(row['outcome']), '')}\">{row['outcome']}</td>"
            f"<td>{html.escape(str(row['scenario']))}</td>"
            f"<td>{html.escape(str(row['camera']))}</td>")


def _case_rows(rows: Sequence[Row], out_dir: Path) -> str:
    lines = []
    for row in rows:
        to_halt = _time_to_halt_s(row)
        cross = row.get("max_cross_track_error_m")
        lines.append(
            f"<tr>{_run_cells(row)}"
            f"<td>{html.escape(', '.join(_kinds(row)))}</td>"
            f"<td class=\"why\">{html.escape(str(row.get('reason') or ''))}</td>"
            f"<td>{'' if to_halt is None else f'{to_halt:.3f}'}</td>"
            f"<td>{'' if cross is None else cross}</td>"
            f"<td class=\"before\">{html.escape(_before_halt_text(row))}</td>"
            f"{_rerun_cell(out_dir, str(row['id']))}</tr>")
    return ("<div class=\"wide\"><table><tr><th>run</th><th>outcome</th><th>scenario</th>"
            "<th>camera</th><th>faults</th><th>why</th><th>time to halt s</th>"
            "<th>max cross-track m</th><th>perception before the halt</th>"
            f"<th>rerun (with video and plot)</th></tr>{''.join(lines)}</table></div>")


def _figure(value: float | None, spec: str) -> str:
    """A stored figure as the report shows it; '' where it was not stored (a store written
    before the figure existed, or a damaged one: the report had stopped on it)."""
    return "" if value is None else format(value, spec)


def _before_halt_text(row: Row) -> str:
    """The run's `before_halt` summary in one line (empty for a run that never halted, or
    stored before the summary existed)."""
    summary = row.get("before_halt")
    return describe_before_halt(summary) if isinstance(summary, dict) else ""


def _more(kept: _Kept, what: str) -> str:
    hidden = kept.count - len(kept.heap)
    return (f"<p>... and {counted(hidden, 'more ' + what)} (results.sqlite has every row).</p>"
            if hidden else "")


def _worst(summary: CampaignSummary, out_dir: Path) -> str:
    unsafe, false_halts = summary.listed["unsafe"], summary.listed["false_halt"]
    slowest = [row for _, row in sorted(summary.slowest.values(),
                                        key=lambda item: (-item[0], str(item[1]["id"])))]
    parts = ["<h2>Worst cases</h2><p>Every unsafe run and every false halt (the slowest to halt "
             "first; never halting counts as slowest), then, for each fault kind, its slowest "
             "safe halt. Each reruns exactly with the command beside it; a click selects it, "
             "the button copies it.</p>"]
    if unsafe.count or false_halts.count:
        parts.append(_case_rows([*unsafe.rows(), *false_halts.rows()], out_dir))
        parts.append(_more(unsafe, "unsafe run") + _more(false_halts, "false halt"))
    else:
        parts.append("<p>No unsafe run and no false halt.</p>")
    if slowest:
        parts.append("<h3>Slowest safe halt of each fault kind</h3>")
        parts.append(_case_rows(slowest, out_dir))
    return "".join(parts)


def _blind(summary: CampaignSummary, out_dir: Path) -> str:
    blind = summary.blind
    if not blind.count:
        return ""
    return ("<h2>Halts while the camera showed no lane</h2><p>Safe halts for lane loss while "
            "the frames the camera delivered showed no tape with a contrast the detector could "
            "use (a light switched up faster than the auto-exposure follows, ...): not failures "
            "of the supervisor, but of the camera's view.</p>"
            + _case_rows(blind.rows(), out_dir) + _more(blind, "blind halt"))


def _false_lanes(summary: CampaignSummary, out_dir: Path) -> str:
    """Runs that drove on a lane that was not there, whatever their outcome (a safe halt can
    be luck: docs/campaigns.md, r00322)."""
    kept = summary.false_lane
    head = ("<h2>Driving on a false lane</h2><p>Runs in which the supervisor, engaged, trusted a "
            f"lane with a reported edge more than {FALSE_LANE_TOLERANCE_M * 100:.0f} cm from "
            "every tape (ground truth, scenarios/false_lane.py), whatever their outcome: a "
            "floor pattern, a stray piece of tape or a shadow's edge taken for the lane. A safe "
            "halt after one may be luck.</p>")
    if not summary.false_lane_measured:
        return head + ("<p>Not measured: these runs were stored before the false-lane figures "
                       "existed (run them again in a new folder to measure them).</p>")
    if not kept.count:
        return head + f"<p>None in {counted(summary.false_lane_measured, 'run')}.</p>"
    lines = []
    for row in kept.rows():
        clear = row.get("min_tape_clearance_m")
        lines.append(
            f"<tr>{_run_cells(row)}"
            f"<td>{_figure(row.get('false_lane_longest_s'), '.2f')}</td>"
            f"<td>{row['false_lane_frames']}</td>"
            f"<td>{_figure(row.get('max_edge_error_m'), '.3f')}</td>"
            f"<td>{'' if clear is None else f'{1000 * clear:.1f}'}</td>"
            f"{_rerun_cell(out_dir, str(row['id']))}</tr>")
    return (head + f"<p>{counted(kept.count, 'run')} of {summary.false_lane_measured}, "
            f"{counted(summary.false_lane_frames, 'frame')} in all; the longest stretch "
            "first.</p><div class=\"wide\"><table><tr><th>run</th><th>outcome</th>"
            "<th>scenario</th><th>camera</th><th>longest stretch s</th><th>frames</th>"
            "<th>largest edge error m</th><th>closest approach to a tape mm</th>"
            f"<th>rerun (with video and plot)</th></tr>{''.join(lines)}</table></div>"
            + _more(kept, "run on a false lane"))


def _errors(summary: CampaignSummary, out_dir: Path) -> str:
    errors = summary.listed["error"]
    if not errors.count:
        return ""
    return ("<h2>Runs in error</h2><p>These runs did not test what they were meant to (the "
            "reason says why); running the campaign again reruns them.</p>"
            + _case_rows(errors.rows(), out_dir) + _more(errors, "runs in error"))


_COPY_SCRIPT = """
document.addEventListener('click', async (event) => {
  const button = event.target.closest('button.copy');
  if (!button) return;
  const text = button.dataset.copy;
  try {
    await navigator.clipboard.writeText(text);
  } catch (error) {  // no clipboard API (an old browser, a page not allowed): select and copy
    const range = document.createRange();
    range.selectNodeContents(button.previousElementSibling);
    getSelection().removeAllRanges();
    getSelection().addRange(range);
    document.execCommand('copy');
  }
  button.textContent = 'copied';
  setTimeout(() => { button.textContent = 'copy'; }, 1500);
});
"""


def report_html(name: str, summary: CampaignSummary, out_dir: Path, text: str) -> str:
    counts = summary.counts
    badges = " ".join(
        f'<span style="background:{_COLORS[o]};color:white;padding:2px 8px;border-radius:4px">'
        f"{o}: {counts[o]}</span>" for o in OUTCOMES)
    cost = (f"<p>{counted(summary.timed, 'run')} timed: {summary.cpu_s:.0f} s CPU for "
            f"{summary.sim_s:.0f} s simulated "
            f"({summary.cpu_s / max(summary.timed, 1):.2f} s CPU per run).</p>"
            ) if summary.timed else ""
    matrices = "\n".join(_matrix(title, table) for (title, _), table
                         in zip(summary.matrices, summary.tables, strict=True)
                         if title not in LOOK_MATRICES or set(table) - _NO_LOOK)
    return f"""<!doctype html>
<html><head><meta charset="utf-8"><title>campaign {html.escape(name)}</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; }}
table {{ border-collapse: collapse; margin-bottom: 1em; }}
td, th {{ border: 1px solid #ccc; padding: 2px 8px; text-align: right; }}
th {{ background: #f4f4f4; }}
td.why {{ text-align: left; max-width: 32em; }}
td.before {{ text-align: left; min-width: 11em; max-width: 22em; font-size: .85em; }}
td.plot {{ padding: 0 4px; }}
div.wide {{ overflow-x: auto; margin-bottom: 1em; }}
div.wide table {{ margin-bottom: 0; }}
td.rerun {{ text-align: left; min-width: 10em; }}
code.cmd {{ font-size: 90%; user-select: all; background: #f6f6f6; padding: 1px 4px;
            overflow-wrap: anywhere; }}
button.copy {{ font-size: 80%; }}
</style></head><body>
<h1>Campaign {html.escape(name)}</h1>
<p>{html.escape(text)}</p>
<p>{badges}</p>
{cost}
<p>Outcomes: <b>safe_halt</b> halted for a reason that matches a fault acting then, a real lane
loss or a camera that showed no lane; <b>recovered</b> degraded, then followed again;
<b>nominal</b> followed throughout; <b>false_halt</b> halted with no fault and a good lane;
<b>unsafe</b> crossed a tape, ended past the tape end, moved after HALT or did not halt in time
for a hazard it must answer; <b>error</b> the run did not test what it was meant to (a fault
never took effect, it never engaged, a worker was lost). See docs/campaigns.md.</p>
{matrices}
{_time_to_halt(summary)}
{_worst(summary, out_dir)}
{_false_lanes(summary, out_dir)}
{_blind(summary, out_dir)}
{_errors(summary, out_dir)}
<script>{_COPY_SCRIPT}</script>
</body></html>
"""


def summarize(rows: Iterable[Row],
              matrices: Sequence[tuple[str, Callable[[Row], list[str]]]] = ()) -> CampaignSummary:
    summary = CampaignSummary(matrices)
    for row in rows:
        summary.add(row)
    return summary


def write_report(path: Path, name: str, summary: CampaignSummary, out_dir: Path,
                 text: str) -> None:
    path.write_text(report_html(name, summary, out_dir, text), encoding="utf-8")
