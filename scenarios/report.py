"""Reports of simulated runs: a side-by-side table of their metrics and report.html.

Pure text building plus one file write. The HTML references the runs' own files by relative path
(`lecture/video.mp4`, `supervised/plot.png`, ... for the demo; `video.mp4` for one `sim` run), so
the output directory can be moved or zipped. The page explains every colour of the videos (from
the same tables the drawing code uses) and shows each video's poster as an image of its own, with
the play button below it (a video's controls would cover the poster's bottom): the outcome of the
run (the frame at the halt, or the last frame), not its first frame.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from pathlib import Path

from lanewarden.perception.overlay import BGR
from lanewarden.scenarios.video import video_legend

#: (metrics key, label) rows of the comparison table.
TABLE_ROWS: tuple[tuple[str, str], ...] = (
    ("halted", "halted"),
    ("halt_reason", "halt reason"),
    ("halt_time_s", "halt time (s)"),
    ("fault_effects", "faults (when each took effect)"),
    ("fault_to_halt", "last fault -> HALT"),
    ("motion_after_halt", "after HALT"),
    ("halt_position", "halt position"),
    ("turns_completed", "turns completed"),
    ("states_visited", "states visited"),
    ("max_cross_track_error_m", "max cross-track error (m)"),
    ("mean_cross_track_error_m", "mean cross-track error (m)"),
    ("distance_travelled_m", "distance travelled (m)"),
    ("distance_past_lane_end_m", "distance past lane end (m)"),
    ("lane_loss_to_halt_s", "lane out of view -> HALT (s)"),
    ("crossed_tape", "crossed a tape"),
    ("final_state", "final state"),
    ("end_reason", "run ended"),
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
    if isinstance(value, Mapping) and "x_m" in value:
        return format_position(value)
    return str(value)


def format_position(position: Mapping[str, object]) -> str:
    """'0.52 m before the tape end' where the lane ends, else 'x 3.10, y -2.00 m'."""
    x, y, past = position.get("x_m"), position.get("y_m"), position.get("past_lane_end_m")
    if isinstance(past, int | float):
        return f"{abs(past):.2f} m {'past' if past >= 0 else 'before'} the tape end"
    if isinstance(x, int | float) and isinstance(y, int | float):
        return f"x {x:.2f}, y {y:.2f} m"
    return "-"


def comparison_rows(runs: Mapping[str, Mapping[str, object]],
                    labels: Mapping[str, str] | None = None) -> list[list[str]]:
    """Header + one row per metric, one column per run; `labels`: a row's label in place of
    TABLE_ROWS' (a replay's time is a recording's, not a simulation's)."""
    names = list(runs)
    rows = [["", *names]]
    for key, label in TABLE_ROWS:
        rows.append([(labels or {}).get(key, label),
                     *(format_metric(runs[n], key) for n in names)])
    return rows


def table_notes(runs: Mapping[str, Mapping[str, object]]) -> list[str]:
    """What a reader of the table needs to read a sign: a negative lane-loss time (the
    supervisor halted before the lane left the view) or distance past the lane's end."""
    notes = []
    for key, label, meaning in (
            ("lane_loss_to_halt_s", "lane out of view -> HALT",
             "halted before the lane left the view"),
            ("distance_past_lane_end_m", "distance past lane end", "stopped before the end")):
        values = [m.get(key) for m in runs.values()]
        if any(isinstance(v, int | float) and v < 0 for v in values):
            notes.append(f"{label}: negative = {meaning}")
    return notes


def faults_text(metrics: Mapping[str, object]) -> str:
    """'camera_freeze (fault 0) at 3.000 s; fault 1 never took effect', 'none', or '-' where
    nothing was injected (a replay of a recording)."""
    if "fault_effects" not in metrics:
        return "-"
    effects = metrics.get("fault_effects") or []
    assert isinstance(effects, list)
    took = {int(e["index"]): e for e in effects}
    count = metrics.get("fault_count")
    indices = range(count) if isinstance(count, int) else sorted(took)
    said = [f"{took[i]['kind']} (fault {i}) at {float(took[i]['time_s']):.3f} s" if i in took
            else f"fault {i} never took effect" for i in indices]
    return "; ".join(said) if said else "none"


def fault_to_halt_text(metrics: Mapping[str, object]) -> str:
    """'0.133 s after camera_freeze (fault 0) took effect', or '-'."""
    last = metrics.get("fault_to_halt")
    if not isinstance(last, Mapping):
        return "-"
    return (f"{float(last['to_halt_s']):.3f} s after {last['kind']} (fault {last['index']}) "
            "took effect")


def after_halt_text(metrics: Mapping[str, object]) -> str:
    """Whether a robot that halted came to rest: 'stopped', 'NOT STOPPED: still moving ...', or
    '-' (it never halted)."""
    if not metrics.get("halted") or "motion_after_halt" not in metrics:
        return "-"  # (a replay does not know where the real base went)
    moving = metrics.get("motion_after_halt")
    return f"NOT STOPPED: {moving}" if moving else "stopped"


def fault_lines(metrics: Mapping[str, object]) -> list[str]:
    """The terminal's lines on the faults and the HALT's time (`sim`): what was injected when,
    and how long after the last fault before it the HALT came."""
    lines = []
    if metrics.get("fault_effects") or metrics.get("fault_count"):
        lines.append(f"  faults: {faults_text(metrics)}")
    halt_time = metrics.get("halt_time_s")
    if metrics.get("halted") and isinstance(halt_time, int | float):
        after = fault_to_halt_text(metrics)
        lines.append(f"  HALT at {halt_time:.3f} s" + ("" if after == "-" else f", {after}"))
    return lines


def format_metric(metrics: Mapping[str, object], key: str) -> str:
    """One metric as the table shows it; an extrapolated lane-loss time says it is estimated."""
    if key == "fault_effects":
        return faults_text(metrics)
    if key == "fault_to_halt":
        return fault_to_halt_text(metrics)
    if key == "motion_after_halt":
        return after_halt_text(metrics)
    text = format_value(metrics.get(key))
    if key == "lane_loss_to_halt_s" and metrics.get(key) is not None \
            and metrics.get("lane_loss_estimated"):
        text += " (estimated)"
    return text


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


def _past(m: Mapping[str, object]) -> str:
    value = m.get("distance_past_lane_end_m")
    if not isinstance(value, int | float):
        return "on a lane that never ends"
    return _from_the_end(value)


def _from_the_end(value: float, end: str = "the end of the tape") -> str:
    return f"{abs(value):.2f} m {'past' if value >= 0 else 'before'} {end}"


def _halted_where(m: Mapping[str, object]) -> str:
    """Where HALT began, as the table's "halt position" says it, and where the robot came to rest
    when the two differ (the demo's sentence had given the resting place as where it halted,
    0.02 m, under a table saying 0.01 m)."""
    position = m.get("halt_position")
    began = position.get("past_lane_end_m") if isinstance(position, Mapping) else None
    rest = m.get("distance_past_lane_end_m")
    if not isinstance(began, int | float):
        return _past(m)
    said = _from_the_end(began)
    if isinstance(rest, int | float) and f"{rest:.2f}" != f"{began:.2f}":
        said += f", coming to rest {_from_the_end(rest, 'it')}"
    return said


def run_story(name: str, m: Mapping[str, object]) -> str:
    """'the supervised controller completed turns A and B and halted (LANE_LOST) 0.37 m before
    the end of the tape, coming to rest 0.36 m before it', built only from what the metrics
    say."""
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
        ending = f"halted ({format_value(m.get('halt_reason'))}) {_halted_where(m)}"
        if moving := m.get("motion_after_halt"):  # HALT is a state; the base drove on
            ending += f", but the robot did not stop: {moving}"
    else:
        ending = f"never stopped, ending {_past(m)}"
        if isinstance(value, int | float) and value > 0.5 and not m.get("crossed_tape"):
            # a robot that crossed a tape left the lane before its end: not the tape's end
            ending += " (driving on tile seams once the tape was gone)"
    return f"the {name} controller {turns}{crossed} and {ending}"


def _sentence(text: str) -> str:
    return text[0].upper() + text[1:] + "."


def demo_summary(lecture: Mapping[str, object], supervised: Mapping[str, object]) -> str:
    """One sentence on what happened in both runs."""
    return _sentence(run_story("lecture's", lecture) + "; " + run_story("supervised", supervised))


def run_summary(metrics: Mapping[str, object]) -> str:
    """One sentence on what happened in one run (and a campaign case's outcome, `sim --case`)."""
    said = _sentence(run_story(str(metrics.get("controller", "")), metrics))
    if metrics.get("outcome"):
        said += f" Campaign outcome: {metrics['outcome']} ({metrics.get('outcome_reason')})."
    return said


def _css_rgb(bgr: BGR) -> str:
    b, g, r = bgr
    return f"rgb({r},{g},{b})"


def legend_html() -> str:
    """Every colour of the videos with what it means, grouped by where it appears."""
    groups = []
    for title, rows in video_legend():
        items = "".join(
            f'<li><span class="swatch" style="background:{_css_rgb(row.bgr)}"></span>'
            f"<b>{html.escape(row.label)}</b>: {html.escape(row.meaning)}</li>"
            for row in rows
        )
        groups.append(f"<div><h3>{html.escape(title)}</h3><ul>{items}</ul></div>")
    return (
        '<section class="legend"><h2>Reading the videos</h2>'
        "<p>Left: the undistorted camera view with what perception saw drawn on it. Right: a map "
        "of the course seen from above. Above them, the caption: what perception said about this "
        "frame alone (left), and what the controller did (right): its state with the reason for "
        "a HALT or DEGRADED, the slope sum it acted on, and the command it sent.</p>"
        f'<div class="groups">{"".join(groups)}</div></section>'
    )


def _poster_caption(metrics: Mapping[str, object]) -> str:
    poster = metrics.get("video_poster")
    if not isinstance(poster, Mapping):
        return ""
    when = poster.get("time_s")
    at = f" (t = {when:.1f} s)" if isinstance(when, int | float) else ""
    return (f'<p class="caption">Still image: {html.escape(str(poster.get("shows")))}{at}. '
            "Play shows the whole run.</p>")


def _run_section(name: str, folder: str, metrics: Mapping[str, object], heading: str) -> str:
    outputs = metrics.get("outputs") or []
    assert isinstance(outputs, list)
    prefix = f"{html.escape(folder)}/" if folder else ""
    if "video.mp4" in outputs and "poster.jpg" in outputs:
        # The still is an image of its own, with the play button below it: a video's controls
        # would cover the bottom of its poster (the map's and the camera view's lower part).
        video = (f'<div class="player" data-video="{prefix}video.mp4">'
                 f'<img src="{prefix}poster.jpg" alt="{html.escape(name)}: the outcome">'
                 '<button type="button" class="play">&#9654; Play the run</button></div>'
                 f'<noscript><video src="{prefix}video.mp4" controls muted playsinline '
                 f'preload="none"></video></noscript>{_poster_caption(metrics)}')
    elif "video.mp4" in outputs:
        video = (f'<video src="{prefix}video.mp4" controls muted playsinline '
                 'preload="metadata"></video>')
    else:
        video = "<p>(no video recorded)</p>"
    return (
        f"<section><h2>{html.escape(heading)}</h2>{video}"
        f'<img src="{prefix}plot.png" alt="{html.escape(name)} plot">'
        f'<p><a href="{prefix}metrics.json">metrics.json</a> &middot; '
        f'<a href="{prefix}run.jsonl">run.jsonl</a></p></section>'
    )


def write_report(path: Path, runs: Mapping[str, Mapping[str, object]], summary: str,
                 title: str = "Lanewarden demo: the lecture's course",
                 folders: Mapping[str, str] | None = None,
                 headings: Mapping[str, str] | None = None,
                 labels: Mapping[str, str] | None = None) -> None:
    """report.html for `runs` (name -> metrics). `folders`: each run's folder relative to the
    page (default: its name; "" for the page's own folder); `headings`: each run's heading;
    `labels`: the table's own labels of some rows (`comparison_rows`)."""
    rows = comparison_rows(runs, labels)
    head = "".join(f"<th>{html.escape(c)}</th>" for c in rows[0])
    body = "".join(
        "<tr>" + "".join(
            f"<td>{html.escape(c)}</td>" if i else f"<th>{html.escape(c)}</th>"
            for i, c in enumerate(row)
        ) + "</tr>"
        for row in rows[1:]
    )
    panels = [
        _run_section(name, (folders or {}).get(name, name), metrics,
                     (headings or {}).get(name, name))
        for name, metrics in runs.items()
    ]
    document = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 1.5em; color: #222; max-width: 1180px; }}
section {{ margin: 1.5em 0 2.5em; }}
video {{ width: 100%; max-width: 1120px; display: block; background: #222; }}
img {{ width: 100%; max-width: 1125px; display: block; margin: .5em 0; }}
.caption {{ color: #555; margin: .3em 0 1em; }}
table {{ border-collapse: collapse; margin: 1em 0; }}
th, td {{ border: 1px solid #ccc; padding: .3em .7em; text-align: right; }}
th:first-child {{ text-align: left; }}
.legend .groups {{ display: flex; flex-wrap: wrap; gap: 0 2em; }}
.legend .groups > div {{ flex: 1 1 340px; }}
.legend h3 {{ font-size: 1em; margin: .8em 0 .3em; }}
.legend ul {{ list-style: none; padding: 0; margin: 0; }}
.legend li {{ margin: .25em 0; }}
.swatch {{ display: inline-block; width: 1.6em; height: .9em; margin-right: .5em;
           vertical-align: middle; border: 1px solid #888; }}
.player img {{ margin: 0; }}
.player button {{ margin: .4em 0; font-size: 1em; padding: .3em 1em; cursor: pointer; }}
</style></head><body>
<h1>{html.escape(title)}</h1>
<p>{html.escape(summary)}</p>
<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>
<p class="note">Distances past the lane end are measured from the end of the first tape to end,
along the lane; negative means the robot stopped before it. The halt position is where the robot
was when HALT began (it brakes to a stop after that; x and y are in metrics.json). "Lane out of
view &rarr; HALT" is the time from the last tape leaving the camera's region of interest to the
halt; negative means it halted before that (the moment the tape would have left the view is then
estimated after the run, and the table and the plot mark it as an estimate). Cross-track error is
the distance of the robot's centre from the lane centre.</p>
{legend_html()}
{"".join(panels)}
<script>
document.addEventListener('click', (event) => {{
  const button = event.target.closest('.player button.play');
  if (!button) return;
  const player = button.closest('.player');
  const video = document.createElement('video');
  Object.assign(video, {{src: player.dataset.video, controls: true, autoplay: true,
                        muted: true, playsInline: true}});
  player.replaceWith(video);
}});
</script>
</body></html>
"""
    path.write_text(document, encoding="utf-8")
