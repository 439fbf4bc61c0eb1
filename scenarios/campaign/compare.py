"""Two campaigns of the same draws compared run by run (pure: rows in, a comparison out).

What a change of config (or of code) did to a campaign: run the same spec and seed before and
after it (`--config` may differ), then compare the two results. The runs are matched by id, and a
run is the same run in both only when everything drawn for it is the same (scenario, camera,
floor, tape, effect, faults, its seed): otherwise the two campaigns are not comparable and
`CampaignsDiffer` says which run differs in what. Runs stored in only one of the two (a campaign
cut short, or one of more runs) are counted and left out of every figure.

Each run that changed outcome is put in one class, from the safety side:
- `worse`: it became unsafe, or became a false halt (a halt the run did not call for);
- `better`: it stopped being unsafe, or stopped being a false halt (and did not become unsafe);
- `error`: it could not be judged in one of the two (`error`), so it says nothing either way;
- `other`: any other change (say a safe halt that now recovers).
Beside the outcomes: each campaign's closest approach to a tape, the runs that came within
`NEAR_TAPE_M` of one, and how many runs trusted a false lane (`scenarios.false_lane`), over the
runs both hold.

Never reads a clock and never runs anything.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

from lanewarden.scenarios.campaign.outcome import OUTCOMES
from lanewarden.scenarios.campaign.stored_row import METRICS, checked_row
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.wording import counted

#: What was drawn for a run: the same id is the same run only when all of these agree.
DRAWN = ("scenario", "camera", "floor", "tape", "effect", "fault_kinds", "seed")
#: A run whose footprint came this close to a tape is listed as a near miss, metres.
NEAR_TAPE_M = 0.03
#: Outcomes ranked from the safety side: a run that moves up this list got worse.
_SEVERITY = {"unsafe": 2, "false_halt": 1}

Change = Literal["worse", "better", "error", "other"]
Row = Mapping[str, Any]


class CampaignsDiffer(ScenarioError):
    """Two result folders whose runs were not drawn alike (bad input: exit 2)."""


def drawn_difference(a: Row, b: Row) -> str | None:
    """The first of DRAWN in which two rows of the same id differ (None: the same run)."""
    return next((k for k in DRAWN if a.get(k) != b.get(k)), None)


@dataclass(frozen=True)
class RunChange:
    """One run whose outcome differs: its id, what it is, both outcomes and both closest
    approaches to a tape (metres; None where not measured)."""

    run_id: str
    change: Change
    what: str
    before: str
    after: str
    before_clearance_m: float | None
    after_clearance_m: float | None


@dataclass(frozen=True)
class Side:
    """One campaign's figures over the runs both campaigns hold."""

    counts: Counter[str]
    closest_m: float | None
    closest_id: str | None
    near_tape: int
    false_lane_measured: int  # runs stored with the false-lane metric (older ones lack it)
    false_lane_runs: int
    false_lane_frames: int


@dataclass(frozen=True)
class CampaignComparison:
    shared: int
    only_before: int
    only_after: int
    before: Side
    after: Side
    changes: tuple[RunChange, ...]  # worse first, then better, error, other; by id within

    def of(self, change: Change) -> tuple[RunChange, ...]:
        return tuple(c for c in self.changes if c.change == change)


def compare_campaigns(before: Iterable[Row], after: Iterable[Row],
                      names: tuple[str, str] = ("before", "after")) -> CampaignComparison:
    """The comparison of two campaigns' rows (see the module docstring; `names` say which is
    which in a refusal). Raises CampaignsDiffer when a run both hold was drawn differently, when
    they share no run, and UnreadableRow for a row no campaign writes (an unknown outcome,
    metrics that are not a JSON object): a damaged row must not make a campaign look safer."""
    old = {str(r["id"]): checked_row(r, names[0]) for r in before}
    new = {str(r["id"]): checked_row(r, names[1]) for r in after}
    ids = sorted(old.keys() & new.keys())
    if not ids:
        raise CampaignsDiffer("the two campaigns share no run: compare two result folders of "
                              "the same spec and seed")
    for run_id in ids:
        k = drawn_difference(old[run_id], new[run_id])
        if k is not None:
            raise CampaignsDiffer(
                f"{run_id} is not the same run in both ({k}: {old[run_id].get(k)!r} before, "
                f"{new[run_id].get(k)!r} after): compare campaigns of the same spec and seed "
                "(only --config may differ)")
    changes = [_change(run_id, old[run_id], new[run_id]) for run_id in ids
               if old[run_id].get("outcome") != new[run_id].get("outcome")]
    order = {"worse": 0, "better": 1, "error": 2, "other": 3}
    changes.sort(key=lambda c: (order[c.change], c.run_id))
    return CampaignComparison(
        shared=len(ids), only_before=len(old) - len(ids), only_after=len(new) - len(ids),
        before=_side([old[i] for i in ids]), after=_side([new[i] for i in ids]),
        changes=tuple(changes))


def is_notable(row: Row) -> bool:
    """Whether a run is worth rerunning first when trying a change (a screen): unsafe, a false
    halt, or, whatever its outcome, it trusted a false lane or came within NEAR_TAPE_M of a
    tape. UnreadableRow as `compare_campaigns` (a damaged notable run must not drop out of a
    screen unseen)."""
    row = checked_row(row, "")
    clear = clearance_m(row)
    return bool(row.get("outcome") in _SEVERITY or (_metric(row, "false_lane_frames") or 0) > 0
                or (clear is not None and clear < NEAR_TAPE_M))


def _change(run_id: str, old: Row, new: Row) -> RunChange:
    was, now = str(old.get("outcome")), str(new.get("outcome"))
    kind: Change
    if "error" in (was, now):
        kind = "error"
    elif _SEVERITY.get(now, 0) > _SEVERITY.get(was, 0):
        kind = "worse"
    elif _SEVERITY.get(now, 0) < _SEVERITY.get(was, 0):
        kind = "better"
    else:
        kind = "other"
    what = " / ".join(str(old.get(k)) for k in ("scenario", "camera", "floor", "tape"))
    return RunChange(run_id, kind, what, was, now, clearance_m(old), clearance_m(new))


def _side(rows: list[Row]) -> Side:
    counts: Counter[str] = Counter({o: 0 for o in OUTCOMES})
    counts.update(str(r.get("outcome")) for r in rows)
    closest: tuple[float, str] | None = None
    near = measured = fl_runs = fl_frames = 0
    for row in rows:
        clear = clearance_m(row)
        if clear is not None:
            if closest is None or clear < closest[0]:
                closest = (clear, str(row["id"]))
            near += clear < NEAR_TAPE_M
        frames = _metric(row, "false_lane_frames")
        if frames is not None:
            measured += 1
            fl_runs += frames > 0
            fl_frames += int(frames)
    return Side(counts=counts, closest_m=None if closest is None else closest[0],
                closest_id=None if closest is None else closest[1], near_tape=near,
                false_lane_measured=measured, false_lane_runs=fl_runs,
                false_lane_frames=fl_frames)


def clearance_m(row: Row) -> float | None:
    """A checked row's closest approach to a tape (negative: it crossed one), metres; None
    where not measured."""
    return _metric(row, "min_tape_clearance_m")


def _metric(row: Row, name: str) -> float | None:
    """A number from a checked row's metrics (`stored_row.checked_row`); None where missing or
    not a finite number."""
    value = row[METRICS].get(name)
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


def describe(comparison: CampaignComparison, before_name: str, after_name: str,
             listed: int = 20) -> list[str]:
    """The comparison as lines of text: the outcome table, the closest approaches, the false
    lanes, then the runs that changed, worse first (at most `listed` of each class)."""
    c = comparison
    lines = [f"{counted(c.shared, 'run')} in both (before: {before_name}; after: {after_name})"
             + (f"; left out: {c.only_before} only before, {c.only_after} only after"
                if c.only_before or c.only_after else "")]
    width = max(len(o) for o in OUTCOMES)
    lines.append(f"  {'outcome':<{width}}  before   after")
    for outcome in OUTCOMES:
        a, b = c.before.counts[outcome], c.after.counts[outcome]
        mark = "" if a == b else f"  ({b - a:+d})"
        lines.append(f"  {outcome:<{width}}  {a:>6}  {b:>6}{mark}")
    lines.append(f"  closest approach to a tape: {_closest(c.before)} before, "
                 f"{_closest(c.after)} after; within {NEAR_TAPE_M * 1000:.0f} mm: "
                 f"{c.before.near_tape} before, {c.after.near_tape} after")
    if c.before.false_lane_measured == c.after.false_lane_measured == c.shared:
        lines.append(f"  trusted a false lane: {c.before.false_lane_runs} runs "
                     f"({c.before.false_lane_frames} frames) before, "
                     f"{c.after.false_lane_runs} runs ({c.after.false_lane_frames} frames) after")
    else:
        lines.append(f"  trusted a false lane: measured in "
                     f"{counted(c.before.false_lane_measured, 'run')} before and "
                     f"{c.after.false_lane_measured} after, of {c.shared} (the others were "
                     "stored before the metric existed): not compared")
    titles: dict[Change, str] = {"worse": "worse (became unsafe or a false halt)",
                                 "better": "better (was unsafe and no longer is, or was a false "
                                           "halt and now ends well)",
                                 "error": "not judged in one of the two (error)",
                                 "other": "other changes"}
    for kind, title in titles.items():
        runs = c.of(kind)
        if not runs:
            continue
        lines.append(f"{title}: {len(runs)}")
        for run in runs[:listed]:
            lines.append(f"  {run.run_id}  {run.before} -> {run.after}  (closest "
                         f"{_mm(run.before_clearance_m)} -> {_mm(run.after_clearance_m)})  "
                         f"{run.what}")
        if len(runs) > listed:
            lines.append(f"  ... and {len(runs) - listed} more (--json lists them all)")
    if not c.changes:
        lines.append("no run changed outcome")
    return lines


def as_json(comparison: CampaignComparison, before_name: str,
            after_name: str) -> dict[str, Any]:
    """The comparison as plain JSON data (every changed run listed)."""
    def side(s: Side) -> dict[str, Any]:
        return {"counts": dict(s.counts), "closest_m": s.closest_m, "closest_id": s.closest_id,
                "near_tape": s.near_tape, "false_lane_measured": s.false_lane_measured,
                "false_lane_runs": s.false_lane_runs,
                "false_lane_frames": s.false_lane_frames}
    c = comparison
    return {"before_name": before_name, "after_name": after_name,
            "shared": c.shared, "only_before": c.only_before, "only_after": c.only_after,
            "near_tape_m": NEAR_TAPE_M, "before": side(c.before), "after": side(c.after),
            "changes": [{"id": r.run_id, "change": r.change, "what": r.what,
                         "before": r.before, "after": r.after,
                         "before_clearance_m": r.before_clearance_m,
                         "after_clearance_m": r.after_clearance_m} for r in c.changes]}


def _closest(side: Side) -> str:
    if side.closest_id is None:
        return "not measured"
    return f"{_mm(side.closest_m)} ({side.closest_id})"


def _mm(value: float | None) -> str:
    return "?" if value is None else f"{value * 1000:.1f} mm"
