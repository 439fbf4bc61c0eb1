"""A campaign's summaries for people and for CI: report.html and junit.xml, from the result rows.

- junit.xml: one testcase per run (classname `campaign.<scenario>`, name `<id> <fault kinds>`);
  `unsafe` and `false_halt` are failures, `error` is an error, the rest pass.
- report.html: outcome counts, the outcome matrix (fault kind x outcome, scenario x outcome,
  camera x outcome, and floor, tape and camera effect x outcome when the campaign draws them),
  time-to-halt distributions per fault kind (from the first fault's effect to HALT), and the
  worst cases, each with the one command that reruns it with video.

Pure formatting of rows already stored: never runs anything, never reads a clock.
"""

from __future__ import annotations

import html
import json
import math
from collections import Counter, defaultdict
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

from lanewarden.scenarios.campaign.outcome import FAILURES, OUTCOMES, answered_kind

#: Order of badness for "worst cases" (first: worst).
_SEVERITY = {"unsafe": 0, "false_halt": 1, "error": 2, "safe_halt": 3, "recovered": 4,
             "nominal": 5}
WORST_CASES = 25
_COLORS = {"safe_halt": "#2e7d32", "recovered": "#558b2f", "nominal": "#9e9e9e",
           "false_halt": "#ef6c00", "unsafe": "#c62828", "error": "#6a1b9a"}


def rerun_command(out_dir: Path, case_id: str) -> str:
    return f"lanewarden sim --case {out_dir / 'cases' / f'{case_id}.yaml'}"


def _kinds(row: Mapping[str, Any]) -> list[str]:
    text = str(row.get("fault_kinds") or "")
    return [k for k in text.split(",") if k] or ["(none)"]


def write_junit(path: Path, name: str, rows: Sequence[Mapping[str, Any]]) -> None:
    counts = Counter(str(r["outcome"]) for r in rows)
    suite = ElementTree.Element("testsuite", {
        "name": f"campaign.{name}", "tests": str(len(rows)),
        "failures": str(sum(counts[o] for o in FAILURES)), "errors": str(counts["error"]),
        "time": f"{sum(float(r.get('wall_s') or 0.0) for r in rows):.3f}"})
    for row in rows:
        case = ElementTree.SubElement(suite, "testcase", {
            "classname": f"campaign.{row['scenario']}",
            "name": f"{row['id']} {'+'.join(_kinds(row))}",
            "time": f"{float(row.get('wall_s') or 0.0):.3f}"})
        outcome = str(row["outcome"])
        message = f"{outcome}: {row.get('reason') or ''}"
        if outcome in FAILURES:
            ElementTree.SubElement(case, "failure", {"message": message, "type": outcome})
        elif outcome == "error":
            ElementTree.SubElement(case, "error", {"message": message, "type": "error"})
        ElementTree.SubElement(case, "system-out").text = (
            f"{message}\nhalt reason: {row.get('halt_reason')}\n"
            f"rerun: lanewarden sim --case cases/{row['id']}.yaml")
    ElementTree.indent(suite)
    path.write_text(ElementTree.tostring(suite, encoding="unicode", xml_declaration=True) + "\n",
                    encoding="utf-8")


def _matrix(title: str, rows: Sequence[Mapping[str, Any]], keys: Any) -> str:
    table: dict[str, Counter[str]] = defaultdict(Counter)
    for row in rows:
        for key in keys(row):
            table[key][str(row["outcome"])] += 1
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
    return (f"<h2>{html.escape(title)}</h2><table><tr><th></th>{head}<th>runs</th></tr>"
            f"{''.join(body)}</table>")


def conditions_tables(rows: Sequence[Mapping[str, Any]]) -> str:
    """Floor x outcome, tape x outcome and camera effect x outcome (what the runs were seen
    through, beside what was injected); only the dimensions the campaign drew."""
    tables = []
    for column, title in (("floor", "Floor x outcome"), ("tape", "Tape x outcome"),
                          ("effect", "Camera effect x outcome")):
        names = {str(r.get(column) or "") for r in rows}
        if names - {"", "scenario", "default"}:
            tables.append(_matrix(title, rows, lambda r, c=column: [str(r.get(c) or "?")]))
    return "\n".join(tables)


def _histogram_svg(values: Sequence[float], width: int = 260, height: int = 50) -> str:
    if not values:
        return ""
    low, high = min(values), max(values)
    bins = 20
    span = max(high - low, 1e-6)
    counts = [0] * bins
    for v in values:
        counts[min(bins - 1, int((v - low) / span * bins))] += 1
    top = max(counts)
    bar = width / bins
    rects = "".join(
        f'<rect x="{i * bar:.1f}" y="{height - c / top * height:.1f}" width="{bar - 1:.1f}" '
        f'height="{c / top * height:.1f}" fill="#1565c0"/>' for i, c in enumerate(counts) if c)
    return (f'<svg width="{width}" height="{height}" role="img" aria-label="histogram from '
            f'{low:.2f} s to {high:.2f} s">{rects}</svg>')


def _quantile(values: Sequence[float], q: float) -> float:
    ordered = sorted(values)
    pos = q * (len(ordered) - 1)
    lo, hi = math.floor(pos), math.ceil(pos)
    return ordered[lo] + (ordered[hi] - ordered[lo]) * (pos - lo)


def _answered_kinds(row: Mapping[str, Any]) -> list[str]:
    """The fault kind a safe halt answered (its reason: "CODE answering KIND (fault N)"); every
    kind of the run when the halt answered the lane's end instead."""
    kind = answered_kind(str(row.get("reason") or ""))
    return [kind] if kind is not None else _kinds(row)


def _time_to_halt(rows: Sequence[Mapping[str, Any]]) -> str:
    by_kind: dict[str, list[float]] = defaultdict(list)
    for row in rows:
        value = row.get("time_to_halt_s")
        if row["outcome"] == "safe_halt" and isinstance(value, int | float):
            for kind in _answered_kinds(row):
                by_kind[kind].append(float(value))
    lines = []
    for kind in sorted(by_kind):
        values = by_kind[kind]
        lines.append(
            f"<tr><th>{html.escape(kind)}</th><td>{len(values)}</td>"
            f"<td>{min(values):.3f}</td><td>{_quantile(values, 0.5):.3f}</td>"
            f"<td>{_quantile(values, 0.95):.3f}</td><td>{max(values):.3f}</td>"
            f"<td>{_histogram_svg(values)}</td></tr>")
    return ("<h2>Time to halt (safe halts)</h2><p>From the moment the run's first fault took "
            "effect to HALT, seconds, under the fault kind the halt answered (negative: the "
            "run halted before, for another fault or the lane end).</p><table><tr>"
            "<th>fault kind</th><th>runs</th><th>min</th>"
            "<th>median</th><th>p95</th><th>max</th><th>distribution</th></tr>"
            f"{''.join(lines)}</table>")


def _worst(rows: Sequence[Mapping[str, Any]], out_dir: Path) -> str:
    def badness(row: Mapping[str, Any]) -> tuple[int, float]:
        halt = row.get("time_to_halt_s")
        return (_SEVERITY.get(str(row["outcome"]), 9),
                -float(halt) if isinstance(halt, int | float) else 0.0)

    worst = sorted(rows, key=badness)[:WORST_CASES]
    lines = []
    for row in worst:
        metrics = json.loads(row.get("metrics_json") or "{}")
        lines.append(
            f"<tr><td>{row['id']}</td><td style=\"color:{_COLORS.get(str(row['outcome']), '')}"
            f"\">{row['outcome']}</td><td>{html.escape(str(row['scenario']))}</td>"
            f"<td>{html.escape(str(row['camera']))}</td>"
            f"<td>{html.escape(', '.join(_kinds(row)))}</td>"
            f"<td>{html.escape(str(row.get('reason') or ''))}</td>"
            f"<td>{metrics.get('max_cross_track_error_m', '')}</td>"
            f"<td><code>{html.escape(rerun_command(out_dir, str(row['id'])))}</code></td></tr>")
    return ("<h2>Worst cases</h2><p>Each reruns exactly with the command beside it (with video "
            "and plot).</p><table><tr><th>run</th><th>outcome</th><th>scenario</th>"
            "<th>camera</th><th>faults</th><th>why</th><th>max cross-track m</th>"
            f"<th>rerun</th></tr>{''.join(lines)}</table>")


def write_report(path: Path, name: str, rows: Sequence[Mapping[str, Any]], out_dir: Path,
                 summary: str) -> None:
    counts = Counter(str(r["outcome"]) for r in rows)
    badges = " ".join(
        f'<span style="background:{_COLORS[o]};color:white;padding:2px 8px;border-radius:4px">'
        f"{o}: {counts[o]}</span>" for o in OUTCOMES)
    cpu = [float(r["cpu_s"]) for r in rows if isinstance(r.get("cpu_s"), int | float)]
    sim = [float(r["sim_time_s"]) for r in rows if isinstance(r.get("sim_time_s"), int | float)]
    cost = (f"<p>{len(cpu)} runs timed: {sum(cpu):.0f} s CPU for {sum(sim):.0f} s simulated "
            f"({sum(cpu) / max(len(cpu), 1):.2f} s CPU per run).</p>") if cpu else ""
    doc = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>campaign {html.escape(name)}</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; }}
table {{ border-collapse: collapse; margin-bottom: 1em; }}
td, th {{ border: 1px solid #ccc; padding: 2px 8px; text-align: right; }}
th {{ background: #f4f4f4; }}
code {{ font-size: 90%; }}
</style></head><body>
<h1>Campaign {html.escape(name)}</h1>
<p>{html.escape(summary)}</p>
<p>{badges}</p>
{cost}
<p>Outcomes: <b>safe_halt</b> halted for a reason that matches a fault acting then or a real lane
loss; <b>recovered</b> degraded, then followed again; <b>nominal</b> followed throughout;
<b>false_halt</b> halted with no fault and a good lane; <b>unsafe</b> crossed a tape, ended past
the tape end, moved after HALT or did not halt in time for a hazard it must answer; <b>error</b>
the run did not test what it was meant to (a fault never took effect, it never engaged, a
worker was lost). See docs/campaigns.md.</p>
{_matrix("Fault kind x outcome", rows, _kinds)}
{_matrix("Scenario x outcome", rows, lambda r: [str(r["scenario"])])}
{_matrix("Camera x outcome", rows, lambda r: [str(r["camera"])])}
{conditions_tables(rows)}
{_time_to_halt(rows)}
{_worst(rows, out_dir)}
</body></html>
"""
    path.write_text(doc, encoding="utf-8")
