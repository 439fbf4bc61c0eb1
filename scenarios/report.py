"""The demo's comparison: a side-by-side table of two runs' metrics and report.html.

Pure text building plus one file write. The HTML references the runs' own files by relative path
(`lecture/video.mp4`, `supervised/plot.png`, ...), so the output directory can be moved or zipped.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from pathlib import Path

#: (metrics key, label) rows of the comparison table.
TABLE_ROWS: tuple[tuple[str, str], ...] = (
    ("halted", "halted"),
    ("halt_reason", "halt reason"),
    ("turns_completed", "turns completed"),
    ("states_visited", "states visited"),
    ("max_cross_track_error_m", "max cross-track error (m)"),
    ("mean_cross_track_error_m", "mean cross-track error (m)"),
    ("distance_travelled_m", "distance travelled (m)"),
    ("distance_past_lane_end_m", "distance past lane end (m)"),
    ("lane_loss_to_halt_s", "lane out of view -> HALT (s)"),
    ("crossed_tape", "crossed a tape"),
    ("final_state", "final state"),
    ("sim_time_s", "simulated time (s)"),
    ("wall_time_s", "wall time (s)"),
)


def format_value(value: object) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.3f}".rstrip("0").rstrip(".") if abs(value) < 1000 else f"{value:.0f}"
    if isinstance(value, list | tuple):
        return ", ".join(str(v) for v in value) if value else "none"
    if isinstance(value, str) and ":" in value and value.split(":")[0].isupper():
        return value.split(":")[0]  # the event name; the full text is in metrics.json
    return str(value)


def comparison_rows(runs: Mapping[str, Mapping[str, object]]) -> list[list[str]]:
    """Header + one row per metric, one column per run."""
    names = list(runs)
    rows = [["", *names]]
    for key, label in TABLE_ROWS:
        rows.append([label, *(format_value(runs[n].get(key)) for n in names)])
    return rows


def format_table(rows: Sequence[Sequence[str]]) -> str:
    """A plain-text table (for the terminal)."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = []
    for i, row in enumerate(rows):
        cells = [row[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(row[1:], widths[1:],
                                                                         strict=True)]
        lines.append("  ".join(cells).rstrip())
        if i == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def demo_summary(lecture: Mapping[str, object], supervised: Mapping[str, object]) -> str:
    """One sentence on what happened, built only from what the metrics say."""

    def past(m: Mapping[str, object]) -> str:
        value = m.get("distance_past_lane_end_m")
        if not isinstance(value, int | float):
            return "on a lane that never ends"
        return f"{abs(value):.2f} m {'past' if value >= 0 else 'before'} the end of the tape"

    def story(name: str, m: Mapping[str, object]) -> str:
        done = list(m.get("turns_completed") or [])  # type: ignore[call-overload]
        if not done:
            turns = "completed no turn"
        elif len(done) == 1:
            turns = f"completed turn {done[0]}"
        else:
            turns = f"completed turns {', '.join(done[:-1])} and {done[-1]}"
        crossed = ", crossed a tape" if m.get("crossed_tape") else ""
        value = m.get("distance_past_lane_end_m")
        if m.get("halted"):
            ending = f"halted ({format_value(m.get('halt_reason'))}) {past(m)}"
        else:
            ending = f"never stopped, ending {past(m)}"
            if isinstance(value, int | float) and value > 0.5:
                ending += " (driving on tile seams once the tape was gone)"
        return f"the {name} controller {turns}{crossed} and {ending}"

    text = story("lecture's", lecture) + "; " + story("supervised", supervised) + "."
    return text[0].upper() + text[1:]


def write_report(path: Path, runs: Mapping[str, Mapping[str, object]], summary: str,
                 title: str = "Lanewarden demo: the lecture's course") -> None:
    rows = comparison_rows(runs)
    head = "".join(f"<th>{html.escape(c)}</th>" for c in rows[0])
    body = "".join(
        "<tr>" + "".join(
            f"<td>{html.escape(c)}</td>" if i else f"<th>{html.escape(c)}</th>"
            for i, c in enumerate(row)
        ) + "</tr>"
        for row in rows[1:]
    )
    panels = []
    for name, metrics in runs.items():
        outputs = metrics.get("outputs") or []
        assert isinstance(outputs, list)
        video = (
            f'<video src="{html.escape(name)}/video.mp4" controls muted playsinline '
            f'preload="metadata"></video>' if "video.mp4" in outputs
            else "<p>(no video recorded)</p>"
        )
        panels.append(
            f'<section><h2>{html.escape(name)}</h2>{video}'
            f'<img src="{html.escape(name)}/plot.png" alt="{html.escape(name)} plot">'
            f'<p><a href="{html.escape(name)}/metrics.json">metrics.json</a> &middot; '
            f'<a href="{html.escape(name)}/run.jsonl">run.jsonl</a></p></section>'
        )
    document = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 1.5em; color: #222; }}
.runs {{ display: flex; flex-wrap: wrap; gap: 1.5em; }}
section {{ flex: 1 1 560px; }}
video, img {{ width: 100%; max-width: 900px; display: block; margin-bottom: .5em; }}
table {{ border-collapse: collapse; margin: 1em 0; }}
th, td {{ border: 1px solid #ccc; padding: .3em .7em; text-align: right; }}
th:first-child {{ text-align: left; }}
</style></head><body>
<h1>{html.escape(title)}</h1>
<p>{html.escape(summary)}</p>
<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>
<p class="note">Distances past the lane end are measured from the end of the first tape to end,
along the lane; negative means the robot stopped before it. "Lane out of view &rarr; HALT" is the
time from the last tape leaving the camera's region of interest to the halt; negative means it
halted before that. Cross-track error is the distance of the robot's centre from the lane
centre.</p>
<div class="runs">{"".join(panels)}</div>
</body></html>
"""
    path.write_text(document, encoding="utf-8")
