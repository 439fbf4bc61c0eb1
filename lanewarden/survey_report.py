"""`lanewarden survey`'s outputs: survey.json and a self-contained report.html (its pictures are
embedded, so the page can be mailed or archived alone).

The page: the verdict at the top (SAFE / NOT SAFE with the false lanes named, whether the
supervisor engaged), the figures per class, the pictures of the false lanes and of the weakest
lane frames (or, when every lane frame is confident, of the least confident ones; perception's
overlay, with the colours explained from `perception.overlay.OVERLAY_STYLES`, the table the
drawing uses), then one table per class with every frame. Text building is pure;
`write_outputs` is the one place that writes.
"""

from __future__ import annotations

import base64
import contextlib
import html
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from lanewarden.errors import OutputError
from lanewarden.perception.confidence import COMPONENT_MEANINGS
from lanewarden.perception.overlay import OVERLAY_STYLES
from lanewarden.survey import (
    CLASS_FOLDERS,
    EXPECTS,
    NONE,
    ClassFigures,
    FrameResult,
    SurveyFigures,
    WhatIf,
    engage_line,
    not_engaged_words,
    on_its_own_text,
    survey_json,
    uncounted_text,
    verdict_line,
    what_if_lines,
)
from lanewarden.survey_run import FALSE_LANE_PICTURES, WEAK_PICTURES, Picture

OUTPUTS = ("report.html", "survey.json")
#: Rows of a class table shown in the page (all of them are in survey.json).
MAX_TABLE_ROWS = 5000

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; max-width: 1180px; }
.verdict { padding: .8em 1.2em; border-radius: 6px; margin: 1em 0; font-size: 1.15em; }
.verdict b { font-size: 1.4em; margin-right: .4em; }
.note { background: #fff8e1; border-left: 4px solid #f9a825; padding: .4em .8em; }
.what-if { background: #e8f0fe; border-left: 4px solid #3367d6; padding: .2em .8em; margin: 1em 0; }
.what-if h2 { font-size: 1.05em; margin: .5em 0; }
.safe { background: #e3f4e1; border: 2px solid #3c8d3c; }
.unsafe { background: #fbe3e1; border: 2px solid #c0392b; }
.idle { background: #fff8e1; border: 2px solid #f9a825; }
.verdict .idle-note { font-size: 1em; }
.engage { margin: .4em 0 0; font-size: .9em; }
table { border-collapse: collapse; margin: .8em 0 1.5em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: left; vertical-align: top; }
td.num { text-align: right; }
tr.false td { background: #fbe3e1; }
tr.confident td:first-child { border-left: 4px solid #3c8d3c; }
.pictures { display: flex; flex-wrap: wrap; gap: 1em; }
figure { margin: 0; width: 330px; }
figure img { width: 320px; image-rendering: pixelated; border: 1px solid #888; }
figcaption { font-size: .85em; }
.about { color: #555; font-size: .9em; }
.swatch { display: inline-block; width: 1.6em; height: .9em; margin-right: .5em;
          vertical-align: middle; border: 1px solid #888; }
.legend ul { list-style: none; padding: 0; }
"""


def _e(text: object) -> str:
    return html.escape(str(text))


def _css_rgb(bgr: tuple[int, int, int]) -> str:
    b, g, r = bgr
    return f"rgb({r},{g},{b})"


def _summary_table(classes: Mapping[str, ClassFigures]) -> str:
    head = ("<tr><th>class</th><th>frames</th><th>with a decision</th><th>confident</th>"
            "<th>false lanes</th><th>longest confident runs</th><th>weakest components "
            "(frames where weakest, its median there)</th></tr>")
    rows = []
    for expect in EXPECTS:
        f = classes[expect]
        runs = "<br>".join(_e(f"{r.length}: {r.first}" + (f" .. {r.last}" if r.length > 1
                                                           else "")) for r in f.runs) or "-"
        weak = "<br>".join(_e(f"{c.name}: {c.weakest_in}, {c.median_where_weakest:.2f}")
                           for c in f.components if c.weakest_in) or "-"
        false = f"{len(f.false_lanes)}{uncounted_text(f)}" if expect == NONE else "-"
        rows.append(f"<tr><th>{_e(CLASS_FOLDERS[expect])}</th><td class=num>{f.frames}</td>"
                    f"<td class=num>{f.decisions}</td><td class=num>{f.confident}</td>"
                    f"<td class=num>{false}</td><td>{runs}</td><td>{weak}</td></tr>")
    return f"<table>{head}{''.join(rows)}</table>"


def _figure(picture: Picture) -> str:
    data = base64.b64encode(picture.jpeg).decode("ascii")
    caption = "<br>".join(_e(line) for line in picture.caption)
    return (f'<figure><img src="data:image/jpeg;base64,{data}" alt="{_e(picture.name)}">'
            f"<figcaption><b>{_e(picture.name)}</b><br>{caption}</figcaption></figure>")


def _pictures(title: str, pictures: Sequence[Picture], empty: str, note: str) -> str:
    body = (f'<div class="pictures">{"".join(_figure(p) for p in pictures)}</div>'
            if pictures else f"<p>{_e(empty)}</p>")
    return f"<section><h2>{_e(title)}</h2><p>{_e(note)}</p>{body}</section>"


def _lane_pictures(pictures: Sequence[Picture]) -> str:
    """The weakest lane frames; when all of them are confident (every lane frame was), the
    least confident, headed so."""
    if pictures and all(p.confident for p in pictures):
        return _pictures(
            "Least confident lane frames (every lane frame is confident)", pictures, "",
            f"No lane frame fell short of confident; these are the least confident of each of "
            f"up to {WEAK_PICTURES} stretches of the lane frames (in sequence order), to show "
            "what perception paired.")
    return _pictures("Weakest lane frames", pictures, "None: no lane frame was surveyed.",
                     f"Lane frames that are not confident: the least confident of each of up to "
                     f"{WEAK_PICTURES} stretches of the lane frames (in sequence order).")


def _legend(undistorted: bool) -> str:
    items = "".join(
        f'<li><span class="swatch" style="background:{_css_rgb(s.bgr)}"></span>'
        f"<b>{_e(s.label)}</b>: {_e(s.meaning)}</li>" for s in OVERLAY_STYLES.values())
    how = ("undistorted with the calibration" if undistorted
           else "as the camera gave it: no calibration, so not undistorted")
    components = "".join(f"<li><b>{_e(name)}</b>: {_e(meaning)}</li>"
                         for name, meaning in COMPONENT_MEANINGS.items())
    return (f'<section class="legend"><h2>Reading the pictures</h2><p>Each picture is the frame '
            f"perception analysed ({how}) with what it saw drawn on it; the caption is what "
            f"perception said about it.</p><ul>{items}</ul>"
            f"<p>The confidence is a product of components, each from 0 to 1; the caption and "
            f"the tables name the lowest (docs/perception.md, 'Confidence'):</p>"
            f"<ul>{components}</ul></section>")


def _frame_row(result: FrameResult) -> str:
    weakest = result.weakest
    weak = "-" if weakest is None else f"{weakest[0]} {weakest[1]:.2f}"
    if result.engaged_after_s is not None:
        engaged = f"after {result.engaged_after_s:.2f} s"
    elif result.engaged is None:
        engaged = "-"
    else:
        engaged = "yes" if result.engaged else "no"
    if result.not_engaged is not None:
        engaged += f": {not_engaged_words(result.not_engaged)}"
    css = "false" if result.false_lane else ("confident" if result.confident else "")
    decision = result.decision
    if result.shifted is not None:  # `--jitter`: what its shifted versions decided
        decision += (f"; shifted: {result.shifted_decisions} of {result.shifted.versions} "
                     "decided" if result.shifted_decisions
                     else f"; shifted: none of {result.shifted.versions}")
    if result.on_its_own is not None:  # a recording's no-lane frame, judged on its own too
        decision += f"; on its own: {on_its_own_text(result.on_its_own)}"
    return (f'<tr class="{css}"><td>{_e(result.frame.name)}</td><td>{_e(decision)}</td>'
            f"<td class=num>{result.confidence:.2f}</td><td>{'yes' if result.confident else 'no'}"
            f"</td><td>{_e(weak)}</td><td>{_e(engaged)}</td><td>{_e(result.frame.note)}</td></tr>")


def _class_table(expect: str, results: Sequence[FrameResult]) -> str:
    mine = [r for r in results if r.frame.expect == expect]
    shown = mine[:MAX_TABLE_ROWS]
    cut = (f"<p>The first {MAX_TABLE_ROWS} of {len(mine)} frames; every frame is in "
           "survey.json.</p>" if len(mine) > MAX_TABLE_ROWS else "")
    head = ("<tr><th>frame</th><th>decision</th><th>confidence</th><th>confident</th>"
            "<th>weakest component</th><th>supervisor engaged</th><th>note</th></tr>")
    return (f"<section><h2>{_e(CLASS_FOLDERS[expect])} frames ({len(mine)})</h2>{cut}"
            f"<table>{head}{''.join(_frame_row(r) for r in shown)}</table></section>")


def _about_row(key: str, value: Any) -> str:
    """'ground model: ...' once (the value may already say what it is)."""
    name = key.replace("_", " ")
    text = str(value)
    return text if text.startswith(f"{name}:") else f"{name}: {text}"


def _what_ifs(what_ifs: Sequence[WhatIf], figures: SurveyFigures) -> str:
    """The stricter settings a NOT SAFE survey tried on the same frames, each in the terminal's
    words."""
    return "".join(
        '<div class="what-if"><h2>Tried on the same frames: a stricter setting</h2>'
        + "".join(f"<p>{_e(line.strip())}</p>" for line in what_if_lines(what_if, figures))
        + "</div>" for what_if in what_ifs)


def report_html(figures: SurveyFigures, about: Mapping[str, Any],
                false_lane_pictures: Sequence[Picture], weak_pictures: Sequence[Picture],
                notes: Sequence[str] = (), what_ifs: Sequence[WhatIf] = ()) -> str:
    verdict = figures.verdict
    engages = verdict.engage is not None and verdict.engage.would_engage
    # SAFE where the supervisor never engages proves little (a wrong tape width gives no decision
    # anywhere): not the green of a survey that found the lane (a new user read it as good to go)
    css = "unsafe" if not verdict.safe else "safe" if engages else "idle"
    idle = ('<p class="engage"><b class="idle-note">but this robot would never drive here</b> '
            "(the supervisor engages on no lane frame): a SAFE verdict then shows little; see the "
            "notes below</p>" if css == "idle" else "")
    text = verdict_line(verdict).removeprefix("verdict: ").removeprefix(verdict.headline)
    about_rows = "".join(f"<li>{_e(_about_row(k, v))}</li>" for k, v in about.items())
    false_count = len(verdict.false_lanes)
    false_note = (f"Any decision on a no-lane frame is a false lane: the supervisor would trust "
                  f"it (a usable confidence also resets the lane-loss timer). Pictures of the "
                  f"first {FALSE_LANE_PICTURES}; all {false_count} are named in the table below "
                  "and in survey.json." if false_count > FALSE_LANE_PICTURES else
                  "Any decision on a no-lane frame is a false lane: the supervisor would trust it "
                  "(a usable confidence also resets the lane-loss timer).")
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>Lanewarden survey: {_e(about.get("source", ""))}</title><style>{_STYLE}</style></head><body>
<h1>Lanewarden survey: {_e(about.get("source", ""))}</h1>
<div class="verdict {css}"><b>{_e(verdict.headline)}</b>{_e(text.lstrip(": "))}
<p class="engage">{_e(engage_line(verdict.engage))}</p>{idle}</div>
{"".join(f'<p class="note">{_e(note)}</p>' for note in notes)}
{_what_ifs(what_ifs, figures)}
<ul class="about">{about_rows}</ul>
{_summary_table(figures.classes)}
<p class="about">A decision: perception's straight / left / right (confidence at least the
supervisor's <code>confidence_usable_min</code> and both edges). Confident: the supervisor's own
test (both edges, confidence at least <code>confidence_confident_min</code>); it engages after
<code>engage_confident_frames</code> confident frames in a row. Runs are counted in sequence
order.</p>
{_pictures("False lanes", false_lane_pictures, "None: no no-lane frame got a decision.",
           false_note)}
{_lane_pictures(weak_pictures)}
{_legend(about.get("calibration", "none") != "none")}
{"".join(_class_table(e, figures.results) for e in EXPECTS)}
</body></html>
"""


def write_outputs(out: Path, figures: SurveyFigures, about: Mapping[str, Any],
                  false_lane_pictures: Sequence[Picture],
                  weak_pictures: Sequence[Picture], notes: Sequence[str] = (),
                  what_ifs: Sequence[WhatIf] = (),
                  effective_config: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Write OUT/survey.json and OUT/report.html; returns the JSON document. `notes`: the
    terminal's `note:` lines, which both carry too (a SAFE that says little is said there);
    `what_ifs`: the stricter settings tried on the same frames (a NOT SAFE survey's);
    `effective_config`: every setting the frames were judged with (survey.json's
    `effective_config`: the config file named may change or be gone when it is read)."""
    document = {**survey_json(figures, about, what_ifs),
                "notes": [note.removeprefix("note: ") for note in notes]}
    if effective_config is not None:
        document["effective_config"] = dict(effective_config)
    texts = {"survey.json": json.dumps(document, indent=1) + "\n",
             "report.html": report_html(figures, about, false_lane_pictures, weak_pictures,
                                        notes, what_ifs)}
    # each written whole under a passing name, then renamed: a disk that fills up leaves no
    # report cut off after its verdict (nor a survey.json beside no report)
    passing = {name: out / f".{name}.part" for name in texts}
    try:
        for name, text in texts.items():
            passing[name].write_text(text, encoding="utf-8")
        for name in texts:
            passing[name].replace(out / name)
    except OSError as exc:
        for path in passing.values():
            with contextlib.suppress(OSError):
                path.unlink(missing_ok=True)
        raise OutputError(f"{out}: cannot write the survey's outputs ({exc.strerror or exc})"
                          ) from exc
    return document
