"""The run's plot.png: slope sum, confidence, the controller's state and its lane decisions.

Four panels over time: the slope sum (raw per frame, and the filtered one the supervisor acts on
when the controller filters; the lecture's rule acts on the raw one, and the plot says so instead
of drawing the same line twice); perception's confidence; the state strip (HALT, DEGRADED, driving)
with the reasons of HALT and DEGRADED in its legend; and the lane decision (FOLLOW, TURN_LEFT,
TURN_RIGHT) as its share of each `DECISION_BIN_S` window, so a controller that flips decision every
frame reads as a mix, not as a barcode. Markers (lane out of
view, HALT) are dashed lines; an estimated one is dotted and says so, also when it falls after the
run ended.

matplotlib with the Agg backend (no display needed). Drawing only: takes arrays, writes one PNG.
"""

from __future__ import annotations

import itertools
import textwrap
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from lanewarden.scenarios.errors import ScenarioOutputError
from lanewarden.scenarios.video import STATE_COLORS

if TYPE_CHECKING:
    from matplotlib.axes import Axes

FloatArray = NDArray[np.float64]

#: Lane decisions, drawn bottom to top in the decision panel.
DECISIONS = ("FOLLOW", "TURN_RIGHT", "TURN_LEFT")
#: Width of the windows the decision panel shares are computed over, seconds (wider for a run
#: longer than MAX_DECISION_BINS windows: a replayed hour would be 7200 bars, and a window
#: count that grows with the run's span would let a forged recording cost minutes to draw).
DECISION_BIN_S = 0.5
MAX_DECISION_BINS = 600
#: The state strip's three bands: HALT, DEGRADED, and any decision state drawn as "driving".
DRIVING = "driving"
_DRIVING_COLOR = (150, 190, 120)
#: Legend labels are wrapped to this width, so the panels keep most of the figure's width.
LEGEND_WIDTH_CHARS = 44


@dataclass(frozen=True)
class StateRun:
    """`label` held from `start_s` up to `end_s`."""

    label: str
    start_s: float
    end_s: float


@dataclass(frozen=True)
class PlotMarker:
    """A vertical line at `time_s`; `estimated`: computed after the run, not observed."""

    name: str
    time_s: float
    estimated: bool = False


def state_runs(time_s: Sequence[float] | FloatArray, labels: Sequence[str]) -> list[StateRun]:
    """Consecutive equal labels merged into runs; each run ends where the next begins (the last
    one a median step after its last sample)."""
    times = np.asarray(time_s, dtype=np.float64)
    if len(times) == 0:
        return []
    step = float(np.median(np.diff(times))) if len(times) > 1 else 0.0
    runs: list[StateRun] = []
    start = 0
    for i in range(1, len(labels) + 1):
        if i == len(labels) or labels[i] != labels[start]:
            end = float(times[i]) if i < len(labels) else float(times[-1]) + step
            runs.append(StateRun(labels[start], float(times[start]), end))
            start = i
    return runs


def strip_label(state: str) -> str:
    """The state strip's band for a state: HALT, DEGRADED, or driving."""
    return state if state in ("HALT", "DEGRADED") else DRIVING


def decision_shares(time_s: Sequence[float] | FloatArray, states: Sequence[str],
                    bin_s: float = DECISION_BIN_S) -> tuple[FloatArray, dict[str, FloatArray]]:
    """Share of the steps in each `bin_s` window spent in each decision in DECISIONS (shares of
    all steps in the window: HALT/DEGRADED steps count in the total but in no decision).
    Returns (window start times, {decision: shares}); windows are [start, start + bin_s)."""
    times = np.asarray(time_s, dtype=np.float64)
    if len(times) == 0:
        return np.zeros(0), {d: np.zeros(0) for d in DECISIONS}
    index = np.floor((times - times[0]) / bin_s + 1e-9).astype(int)
    n_bins = int(index.max()) + 1
    totals = np.bincount(index, minlength=n_bins).astype(np.float64)
    shares = {}
    for decision in DECISIONS:
        hits = np.array([s == decision for s in states], dtype=np.float64)
        counts = np.bincount(index, weights=hits, minlength=n_bins)
        shares[decision] = np.divide(counts, totals, out=np.zeros(n_bins), where=totals > 0)
    return times[0] + bin_s * np.arange(n_bins), shares


def _rgb(state: str) -> tuple[float, float, float]:
    b, g, r = _DRIVING_COLOR if state == DRIVING else STATE_COLORS.get(state, (150, 150, 150))
    return r / 255, g / 255, b / 255


def _reason_summary(runs: Sequence[StateRun], reasons: dict[float, str | None]) -> str:
    counts = Counter(reasons.get(r.start_s) or "?" for r in runs)
    return ", ".join(f"{name} x{n}" if n > 1 else name for name, n in counts.most_common())


def _values(values: Sequence[float | None]) -> FloatArray:
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


def _draw_slope_sum(ax: Axes, times: FloatArray, raw: FloatArray, acted: FloatArray,
                    turn_threshold: float) -> float:
    """The slope sum panel; returns its half height (y limit)."""
    if not np.array_equal(raw, acted, equal_nan=True):
        ax.plot(times, raw, ".", ms=2, color="0.55", label="raw slope sum (each frame)")
        ax.plot(times, acted, "-", lw=1.4, color="C0",
                label="filtered slope sum\n(what the supervisor acts on)")
    else:
        ax.plot(times, raw, "-", lw=0.6, color="C0",
                label="raw slope sum\n(the controller acts on it unfiltered)")
    for sign in (1, -1):
        ax.axhline(sign * turn_threshold, color="C3", lw=0.8, ls=":",
                   label=f"turn threshold +-{turn_threshold:g}" if sign > 0 else None)
    finite = raw[np.isfinite(raw)]
    spread = float(np.percentile(np.abs(finite), 99)) if len(finite) else 0.0
    limit = max(turn_threshold * 2.0, spread) * 1.1
    ax.set_ylim(-limit, limit)
    ax.set_ylabel("slope sum")
    return limit


def _draw_state_strip(ax: Axes, times: FloatArray, states: Sequence[str],
                      reasons: Sequence[str | None]) -> None:
    """HALT / DEGRADED / driving bands, the reasons in the legend."""
    from matplotlib.patches import Patch

    runs = state_runs(times, [strip_label(s) for s in states])
    reason_at = {}
    for run in runs:
        k = int(np.searchsorted(times, run.start_s))
        reason_at[run.start_s] = reasons[k] if k < len(reasons) else None
        ax.axvspan(run.start_s, run.end_s, color=_rgb(run.label), lw=0)
    legend = []
    for label in ("HALT", "DEGRADED", DRIVING):
        present = [r for r in runs if r.label == label]
        if not present:
            continue
        if label == DRIVING:
            text = "driving (FOLLOW / TURN_*)"
        elif label == "HALT":
            text = "HALT: " + ", ".join(
                f"{reason_at[r.start_s] or '?'} ({r.start_s:.1f} s)" for r in present)
        else:
            text = f"DEGRADED: {_reason_summary(present, reason_at)}"
        legend.append(Patch(color=_rgb(label), label=textwrap.fill(text, LEGEND_WIDTH_CHARS)))
    ax.set_yticks([])
    ax.set_ylabel("state", rotation=0, ha="right", va="center")
    ax.legend(handles=legend, loc="upper left", bbox_to_anchor=(1.0, 1.15), fontsize=8,
              frameon=False)


def _draw_decisions(ax: Axes, times: FloatArray, states: Sequence[str]) -> None:
    """The lane decision's share of each DECISION_BIN_S, stacked."""
    from matplotlib.patches import Patch

    span = float(times[-1] - times[0]) if len(times) else 0.0
    bin_s = max(DECISION_BIN_S, span / MAX_DECISION_BINS)
    starts, shares = decision_shares(times, states, bin_s)
    edges = np.append(starts, starts[-1] + bin_s) if len(starts) else starts
    bottom = np.zeros(len(starts))
    for decision in DECISIONS:
        share = shares[decision]
        ax.stairs(bottom + share, edges, baseline=bottom, fill=True, color=_rgb(decision),
                  label=decision)
        bottom = bottom + share
    ax.set_ylim(0, 1)
    ax.set_ylabel(f"lane decision\n(share of each\n{bin_s:.3g} s)")
    handles, _ = ax.get_legend_handles_labels()
    handles.append(Patch(facecolor="white", edgecolor="0.6",
                         label="no decision (HALT or DEGRADED)"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8,
              frameon=False)
    ax.set_xlabel("time (s)")


def _draw_markers(axes: Sequence[Axes], markers: Sequence[PlotMarker], end: float,
                  y_text: float) -> float:
    """Vertical lines on every panel (legend on the first); an estimate is dotted and says so,
    and the time after the run's end is shaded. Returns the latest time drawn."""
    latest = end
    for marker, colour in zip(markers, itertools.cycle(["C1", "C3", "C4", "C5", "C6", "C8"]),
                              strict=False):
        t = marker.time_s
        label = f"{marker.name} ({t:.1f} s)"
        if marker.estimated:
            label = f"{marker.name} ({t:.1f} s, estimated after the run"
            label += ", beyond its end)" if t > end else ")"
        for ax in axes:
            ax.axvline(t, color=colour, lw=1.2, ls=":" if marker.estimated else "--",
                       label=textwrap.fill(label, LEGEND_WIDTH_CHARS) if ax is axes[0] else None)
        latest = max(latest, t)
    if latest > end:
        for ax in axes:
            ax.axvspan(end, latest + 0.5, color="0.9", zorder=0)
        axes[0].text(end, y_text, "run ended ", fontsize=8, color="0.4", va="bottom", ha="right")
    return latest


def write_plot(
    path: Path,
    title: str,
    time_s: FloatArray,
    raw_slope_sum: Sequence[float | None],
    acted_slope_sum: Sequence[float | None],
    confidence: Sequence[float | None],
    states: Sequence[str],
    reasons: Sequence[str | None],
    turn_threshold: float,
    markers: Sequence[PlotMarker],
) -> None:
    """`acted_slope_sum`: the slope sum the controller acted on (drawn only where it is not the
    raw one); `reasons`: each step's state reason (scenarios.state_reasons)."""
    import matplotlib

    matplotlib.use("Agg")
    # every text here is plain: a '$' pair in a source's name ('price_$5_$10.mp4') was read as
    # math and its parse error lost the replay's outputs (an attacker's review)
    matplotlib.rcParams["text.parse_math"] = False
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 1, figsize=(12.5, 8.5), sharex=True,
                             gridspec_kw={"height_ratios": [3, 1.6, 0.7, 1.6]})
    ax_slope, ax_conf, ax_state, ax_decision = axes
    times = np.asarray(time_s, dtype=np.float64)
    limit = _draw_slope_sum(ax_slope, times, _values(raw_slope_sum), _values(acted_slope_sum),
                            turn_threshold)
    ax_slope.set_title(title)
    ax_conf.plot(times, _values(confidence), "-", lw=1.0, color="C2")
    ax_conf.set_ylim(-0.05, 1.05)
    ax_conf.set_ylabel("perception\nconfidence")
    _draw_state_strip(ax_state, times, states, reasons)
    _draw_decisions(ax_decision, times, states)
    end = float(times[-1]) if len(times) else 0.0
    latest = _draw_markers(list(axes), markers, end, -limit * 0.95)
    ax_slope.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)
    for ax in (ax_slope, ax_conf, ax_decision):
        ax.grid(True, alpha=0.3)
    start = float(times[0]) if len(times) else 0.0
    # a run of one step has no span: a tenth of a second, not matplotlib's singular-limits warning
    ax_decision.set_xlim(start, max(latest + 0.5 if latest > end else end, start + 0.1))
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=90)
    except OSError as exc:  # a full disk's error names no file: this line does
        raise ScenarioOutputError(f"{path}: cannot write the plot ({exc.strerror or exc})"
                                  ) from exc
    finally:
        plt.close(fig)
