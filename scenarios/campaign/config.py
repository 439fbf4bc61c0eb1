"""The `campaign:` section of the one validated config: how a campaign run's outcome is judged,
and how a campaign's workers are sized. Every default lives here, with units in the names; every
key is bounded (a threshold outside its range would make the judgement meaningless).

This module only declares numbers: it never runs or judges anything.
"""

from __future__ import annotations

from pydantic import ConfigDict, Field

from lanewarden.documents import DocumentModel


class CampaignConfig(DocumentModel):
    """`campaign:` judging fault-injection runs (outcome classes) and sizing the workers."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    max_past_lane_end_m: float = Field(
        default=0.10, ge=0.0, le=1.0,
        description="a run whose robot ends farther than this past the end of the tape is "
        "unsafe, m",
    )
    hazard_halt_deadline_s: float = Field(
        default=0.1, ge=0.0, le=2.0,
        description="a hazard the supervisor must answer (bumper, cliff, wheel drop, lost link "
        "or camera, ...) must be in HALT this long after its detection limit at the latest, s",
    )
    fault_grace_s: float = Field(
        default=1.0, ge=0.0, le=10.0,
        description="a halt up to this long after a fault stopped acting still counts as the "
        "answer to it, s",
    )
    lane_end_window_m: float = Field(
        default=1.5, ge=0.0, le=10.0,
        description="a lane-loss halt with the robot this close before the end of the tape "
        "(or past it) is a real lane loss, not a false halt, m",
    )
    departure_near_m: float = Field(
        default=0.05, ge=0.0, le=1.0,
        description="a LANE_DEPARTURE halt is right when the robot's footprint came this close "
        "to a tape in the last second before it (ground truth), m",
    )
    worker_memory_limit_mb: int = Field(
        default=1024, ge=128, le=65536,
        description="a local campaign worker using more memory than this is restarted (its "
        "run becomes an error row), MB",
    )
