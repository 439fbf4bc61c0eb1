"""The run's plot.png: raw and filtered slope sum, confidence and supervisor state over time.

matplotlib with the Agg backend (no display needed). Drawing only: takes arrays, writes one PNG.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from lanewarden.scenarios.video import STATE_COLORS

FloatArray = NDArray[np.float64]

#: States in the order they are drawn on the state axis (bottom to top); others are appended.
STATE_ORDER = ["HALT", "DEGRADED", "FOLLOW", "TURN_RIGHT", "TURN_LEFT"]


def write_plot(
    path: Path,
    title: str,
    time_s: FloatArray,
    raw_slope_sum: Sequence[float | None],
    filtered_slope_sum: Sequence[float | None],
    confidence: Sequence[float | None],
    states: Sequence[str],
    turn_threshold: float,
    markers: dict[str, float | None],
) -> None:
    """`markers`: named vertical lines (e.g. lane loss, halt) at times in seconds (None: none)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def arr(values: Sequence[float | None]) -> FloatArray:
        return np.array([np.nan if v is None else v for v in values], dtype=np.float64)

    fig, (ax_slope, ax_conf, ax_state) = plt.subplots(
        3, 1, figsize=(10, 7), sharex=True, gridspec_kw={"height_ratios": [3, 2, 2]}
    )
    raw = arr(raw_slope_sum)
    ax_slope.plot(time_s, raw, ".", ms=2, color="0.55", label="raw slope sum")
    ax_slope.plot(time_s, arr(filtered_slope_sum), "-", lw=1.4, color="C0", label="filtered")
    for sign in (1, -1):
        ax_slope.axhline(sign * turn_threshold, color="C3", lw=0.8, ls=":")
    finite = raw[np.isfinite(raw)]
    spread = float(np.percentile(np.abs(finite), 99)) if len(finite) else 0.0
    limit = max(turn_threshold * 2.0, spread)
    ax_slope.set_ylim(-limit * 1.1, limit * 1.1)
    ax_slope.set_ylabel("slope sum")
    ax_slope.set_title(title)

    ax_conf.plot(time_s, arr(confidence), "-", lw=1.0, color="C2")
    ax_conf.set_ylim(-0.05, 1.05)
    ax_conf.set_ylabel("confidence")

    order = [s for s in STATE_ORDER if s in states] + sorted(
        {s for s in states if s not in STATE_ORDER})
    level = {s: i for i, s in enumerate(order)}
    ys = np.array([level[s] for s in states], dtype=np.float64)
    ax_state.step(time_s, ys, where="post", color="0.3", lw=1.0)
    for state in order:
        mask = np.array([s == state for s in states])
        b, g, r = STATE_COLORS.get(state, (150, 150, 150))
        ax_state.scatter(np.asarray(time_s)[mask], ys[mask], s=3, color=(r / 255, g / 255, b / 255))
    ax_state.set_yticks(range(len(order)), order)
    ax_state.set_ylim(-0.5, max(len(order) - 0.5, 0.5))
    ax_state.set_xlabel("time (s)")

    styles = ["C1", "C3", "C4", "C5"]
    for (name, t), style in zip(markers.items(), styles, strict=False):
        if t is None:
            continue
        for ax in (ax_slope, ax_conf, ax_state):
            ax.axvline(t, color=style, lw=1.0, ls="--",
                       label=f"{name} ({t:.1f} s)" if ax is ax_slope else None)
    ax_slope.legend(loc="upper left", fontsize=8)
    for ax in (ax_slope, ax_conf, ax_state):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
