"""What a row of a campaign's results.sqlite must hold to be read: the one check every reader of
stored runs goes through (`store.ResultStore.iter_rows`: `lanewarden compare`, a campaign's
resume and its report, a screen's --only-notable; `compare.compare_campaigns` for rows given to
it directly).

A row is what `run_case` writes, or it is refused (`UnreadableRow`: one line naming the store,
the run, the column and its value shortened; exit 2). A damaged row must never make a campaign
look safer, nor stop a reader with a traceback: an outcome no campaign stores had dropped out of
the counts (junit.xml said failures="0"), an index that is no number stopped a resume, metrics
nested 100,000 deep were a RecursionError, and a field of hundreds of MB took GBs to read.

Sizes are checked by the store before a value is fetched (`field_limit`, `Oversized`); this
module only judges what was read. Pure: never reads a file.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

from lanewarden.documents import read_json
from lanewarden.scenarios.campaign.cases import case_id
from lanewarden.scenarios.campaign.outcome import OUTCOMES
from lanewarden.scenarios.errors import ScenarioError

#: The longest value read from any column but metrics_json, characters (bytes for a blob). A
#: run writes far less: an error's reason is cut at 500 characters, a verdict's reason is a
#: sentence, effects_json holds ~80 characters per fault (8 at most), the rest are names and
#: numbers; 64 KiB is more than a hundred times that, and bounds what a damaged row costs.
MAX_FIELD_CHARS = 65_536
#: The longest metrics_json read, characters: a run's metrics are 1-3 kB (a halted run's
#: before_halt summary included); 1 MiB is several hundred times that.
MAX_METRICS_CHARS = 1_048_576

#: Columns that hold text (or nothing: a file from before the column existed, a run in error).
_TEXT = ("scenario", "camera", "floor", "tape", "effect", "fault_kinds", "reason",
         "halt_reason", "worker", "effects_json")
_WHOLE = ("seed", "frames")
_SECONDS = ("halt_time_s", "time_to_halt_s", "sim_time_s", "cpu_s", "wall_s")
#: The metrics readers compute with (compare's figures, the report's lists): a number, or null
#: or absent where not measured (results stored before a metric existed).
_NUMBER_METRICS = ("false_lane_frames", "false_lane_longest_s", "max_cross_track_error_m",
                   "max_edge_error_m", "min_tape_clearance_m")
#: Where a checked row keeps its metrics, parsed once.
METRICS = "_metrics"
_SHOWN = 60


class UnreadableRow(ScenarioError):
    """A stored row that no campaign writes (bad input: exit 2)."""


class Oversized(NamedTuple):
    """A value the store did not fetch because it is longer than `field_limit` allows: its
    length (characters; bytes for a blob)."""

    length: int


def field_limit(column: str) -> int:
    """The longest value of `column` a reader fetches (see MAX_FIELD_CHARS)."""
    return MAX_METRICS_CHARS if column == "metrics_json" else MAX_FIELD_CHARS


def _shown(value: object) -> str:
    """A stored value as a refusal shows it: at most _SHOWN characters of it."""
    if isinstance(value, Oversized):
        return f"<{value.length:,} characters>"
    if value is None:
        return "NULL"
    if isinstance(value, str | bytes):
        return repr(value[:_SHOWN])
    return repr(value)[:_SHOWN]


def checked_row(row: Mapping[str, Any], where: str) -> dict[str, Any]:
    """`row` as a campaign stores it, with its metrics parsed once (under METRICS), or
    UnreadableRow naming the run and the column (after `where`, the store or folder it came
    from, when given)."""
    run_id = row.get("id")
    shown_id = run_id if isinstance(run_id, str) and len(run_id) <= _SHOWN else _shown(run_id)
    prefix = f"{where}: run {shown_id}" if where else f"run {shown_id}"

    def refuse(column: str, expected: str) -> UnreadableRow:
        value = row.get(column)
        said = (f"of {value.length:,} characters is longer than any a campaign stores "
                f"(expected at most {field_limit(column):,})" if isinstance(value, Oversized)
                else f"{_shown(value)} is {expected}")
        return UnreadableRow(f"{prefix}: {column} {said}")

    for column, value in row.items():
        if isinstance(value, Oversized):
            raise refuse(column, "")
    outcome = row.get("outcome")
    if outcome not in OUTCOMES:
        raise refuse("outcome", f"not one a campaign stores (expected one of "
                                f"{', '.join(OUTCOMES)})")
    index = row.get("idx")
    if not isinstance(index, int) or isinstance(index, bool) or index < 0:
        raise refuse("idx", "not a run's index (expected a whole number, 0 or more)")
    if run_id != case_id(index):
        raise refuse("id", f"not the id of run index {index} (expected {case_id(index)!r})")
    for names, kinds, expected in ((_TEXT, (str,), "not text"),
                                   (_WHOLE, (int,), "not a whole number"),
                                   (_SECONDS, (int, float), "not a number of seconds")):
        for column in names:
            value = row.get(column)
            if value is not None and (not isinstance(value, kinds) or isinstance(value, bool)):
                raise refuse(column, f"{expected} (expected what a campaign stores, or nothing)")
    text = row.get("metrics_json")
    metrics: object = {} if text is None or text == "" else None  # a run in error: none
    if isinstance(text, str) and text:
        try:
            metrics = read_json(text)
        except (ValueError, RecursionError):  # RecursionError: nested thousands deep
            metrics = None
    if not isinstance(metrics, dict):
        raise refuse("metrics_json", "not readable (expected the JSON object a campaign "
                                     "stores)")
    for name in _NUMBER_METRICS:
        value = metrics.get(name)
        if value is not None and not _is_number(value):
            # read as "not measured", a damaged figure would hide a near miss or a false lane
            raise UnreadableRow(f"{prefix}: metrics_json's {name} {_shown(value)} is not a "
                                "number (expected what a campaign stores, or nothing)")
    if (summary := metrics.get("before_halt")) is not None and (problem := _summary_problem(
            summary)):
        raise UnreadableRow(f"{prefix}: metrics_json's before_halt {problem} (expected the "
                            "summary a campaign stores, or nothing)")
    return {**row, METRICS: metrics}


#: The counts of a stored `before_halt` summary (`scenarios.before_halt.before_halt`) the
#: report's line reads; `window_s` is a number, `weakest` names with counts.
_SUMMARY_COUNTS = ("frames", "confident", "usable", "unusable", "longest_confident_run")


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _summary_problem(summary: object) -> str:
    """What a stored `before_halt` summary lacks for the report to describe it ('' when
    nothing): a damaged one had stopped a resumed campaign's report with a KeyError."""
    if not isinstance(summary, dict):
        return f"{_shown(summary)} is not a summary"
    if not _is_number(summary.get("window_s")):
        return "has no window_s number"
    for name in _SUMMARY_COUNTS:
        if not isinstance(summary.get(name), int) or isinstance(summary.get(name), bool):
            return f"has no whole-number {name}"
    weakest = summary.get("weakest") or {}
    if not isinstance(weakest, dict) or not all(
            isinstance(k, str) and _is_number(v) for k, v in weakest.items()):
        return f"weakest {_shown(weakest)} is not names with counts"
    return ""
