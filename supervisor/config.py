"""The supervisor's section of the one validated config: every threshold, timing, speed and gain.

Units are in the names (`_s` seconds, `_m` metres, `_m_s` m/s, `_rad_s` rad/s, `_frames` camera
frames). Slope sums are in the lecture's convention (dimensionless, positive = the lane bends left);
`center_offset` is in half image widths (see `perception.observation.LaneObservation`). Confidences
are in [0, 1]. Cross-field rules (exit below enter, late below stale, ...) are checked here, so a
bad combination is refused at start-up, before anything moves.

Never read a clock or a file here: this is data.
"""

from __future__ import annotations

from typing import Self

from pydantic import BaseModel, ConfigDict, Field, model_validator


class SupervisorConfig(BaseModel):
    """`supervisor:` section. Defaults are for the simulator's camera (scenarios.camera.CameraModel)
    at 30 frames/s on a Kobuki; the closed-loop numbers are tuned there, see docs/supervisor.md."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    # --- Slope-sum Kalman filter (state: slope sum, its rate per second) ---
    slope_sum_measurement_std: float = Field(
        default=0.3, gt=0.0, description="measurement noise of the slope sum at confidence 1"
    )
    measurement_confidence_floor: float = Field(
        default=0.1,
        gt=0.0,
        le=1.0,
        description="R = (slope_sum_measurement_std / max(confidence, floor))^2",
    )
    slope_sum_accel_std_per_s2: float = Field(
        default=40.0,
        gt=0.0,
        description="process noise: std of the slope sum's acceleration (1/s^2)",
    )
    slope_sum_initial_rate_std_per_s: float = Field(
        default=2.0, gt=0.0, description="rate uncertainty when the filter (re)starts (1/s)"
    )
    innovation_gate_sigma: float = Field(
        default=4.0,
        gt=0.0,
        description="Mahalanobis distance above which a measurement is an outlier",
    )
    outliers_repeated_count: int = Field(
        default=3,
        ge=1,
        description="this many outliers within outliers_window_frames -> REPEATED_OUTLIERS; "
        "this many in a row re-starts the filter on the newest measurement",
    )
    outliers_window_frames: int = Field(default=10, ge=1)
    slope_filter_restart_after_s: float = Field(
        default=0.5,
        gt=0.0,
        description="with no accepted measurement for this long, the next one re-starts the filter",
    )
    center_offset_time_constant_s: float = Field(
        default=0.1,
        ge=0.0,
        description="low-pass time constant of the centring term (0: no filtering)",
    )

    # --- Confidence thresholds and debounce (frames are new camera frames) ---
    confidence_usable_min: float = Field(
        default=0.2,
        ge=0.0,
        le=1.0,
        description="below this a frame has no usable lane (counts towards lane_lost_halt_s)",
    )
    confidence_degrade_below: float = Field(default=0.45, ge=0.0, le=1.0)
    low_confidence_degrade_frames: int = Field(
        default=3, ge=1, description="k: frames below confidence_degrade_below in a row -> DEGRADED"
    )
    confidence_confident_min: float = Field(
        default=0.6, ge=0.0, le=1.0, description="a confident frame: both edges and at least this"
    )
    engage_confident_frames: int = Field(
        default=10, ge=1, description="N: confident frames in a row before start/resume engages"
    )
    recover_confident_frames: int = Field(
        default=5,
        ge=1,
        description="m: confident frames in a row before DEGRADED recovers to FOLLOW",
    )

    # --- Turn hysteresis on the filtered slope sum (the lecture's +-6) ---
    turn_enter_slope_sum: float = Field(default=6.0, gt=0.0)
    turn_exit_slope_sum: float = Field(default=4.0, ge=0.0)

    # --- Watchdog and timing ---
    camera_period_s: float = Field(default=1.0 / 30.0, gt=0.0, description="expected frame period")
    loop_overrun_s: float = Field(
        default=0.1, gt=0.0, description="step-to-step time above this -> LOOP_OVERRUN"
    )
    frame_late_s: float = Field(
        default=0.08, gt=0.0, description="newest frame older than this -> FRAME_LATE (DEGRADED)"
    )
    frame_stale_s: float = Field(
        default=0.15, gt=0.0, description="newest frame older than this -> FRAME_STALE (HALT)"
    )
    frame_frozen_s: float = Field(
        default=0.15,
        gt=0.0,
        description="identical images for this long while moving -> FRAME_FROZEN (HALT)",
    )
    base_feedback_late_s: float = Field(default=0.1, gt=0.0)
    base_link_timeout_s: float = Field(
        default=0.2, gt=0.0, description="no base feedback for this long -> BASE_LINK_LOST (HALT)"
    )
    lane_lost_halt_s: float = Field(
        default=0.2,
        gt=0.0,
        description="engaged with no usable lane (by capture time) for longer -> LANE_LOST (HALT)",
    )

    # --- DEGRADED ---
    degraded_speed_fraction: float = Field(default=0.5, gt=0.0, le=1.0)
    degraded_max_angular_rad_s: float = Field(default=0.4, gt=0.0)
    degraded_budget_s: float = Field(default=2.0, gt=0.0)
    degraded_budget_m: float = Field(default=0.3, gt=0.0)

    # --- Commands per state ---
    follow_speed_m_s: float = Field(default=0.2, gt=0.0)
    slope_sum_gain_rad_s: float = Field(
        default=0.03, ge=0.0, description="rad/s of left turn per unit of filtered slope sum"
    )
    center_offset_gain_rad_s: float = Field(
        default=1.0, ge=0.0, description="rad/s of right turn per half image width of centre offset"
    )
    turn_speed_m_s: float = Field(default=0.15, gt=0.0)
    turn_extra_angular_rad_s: float = Field(
        default=0.2, ge=0.0, description="TURN_LEFT/RIGHT add this to the proportional steering"
    )

    # --- Command limiter (the Kobuki velocity smoother's 0.3 m/s^2 and 3.5 rad/s^2) ---
    max_linear_m_s: float = Field(default=0.3, gt=0.0)
    max_angular_rad_s: float = Field(default=1.0, gt=0.0)
    max_linear_accel_m_s2: float = Field(default=0.3, gt=0.0)
    max_angular_accel_rad_s2: float = Field(default=3.5, gt=0.0)

    # --- Resume policy ---
    auto_resume_after_lane_loss: bool = Field(
        default=False,
        description="re-engage by itself after a LANE_LOST halt once N confident frames",
    )

    # --- The lecture's baseline controller (--controller lecture) ---
    lecture_slope_sum_threshold: float = Field(default=6.0, gt=0.0)
    lecture_turn_angular_rad_s: float = Field(default=0.4, gt=0.0)

    @model_validator(mode="after")
    def _consistent(self) -> Self:
        problems: list[str] = []

        def require(ok: bool, text: str) -> None:
            if not ok:
                problems.append(text)

        require(
            self.turn_exit_slope_sum < self.turn_enter_slope_sum,
            f"turn_exit_slope_sum ({self.turn_exit_slope_sum}) must be below "
            f"turn_enter_slope_sum ({self.turn_enter_slope_sum})",
        )
        require(
            self.confidence_usable_min
            <= self.confidence_degrade_below
            <= self.confidence_confident_min,
            "expected confidence_usable_min <= confidence_degrade_below <= "
            f"confidence_confident_min, got {self.confidence_usable_min}, "
            f"{self.confidence_degrade_below}, {self.confidence_confident_min}",
        )
        require(
            self.frame_late_s < self.frame_stale_s,
            f"frame_late_s ({self.frame_late_s}) must be below "
            f"frame_stale_s ({self.frame_stale_s})",
        )
        require(
            self.base_feedback_late_s < self.base_link_timeout_s,
            f"base_feedback_late_s ({self.base_feedback_late_s}) must be below "
            f"base_link_timeout_s ({self.base_link_timeout_s})",
        )
        require(
            self.loop_overrun_s > self.camera_period_s,
            f"loop_overrun_s ({self.loop_overrun_s}) must be above camera_period_s "
            f"({self.camera_period_s})",
        )
        for name in ("follow_speed_m_s", "turn_speed_m_s"):
            require(
                getattr(self, name) <= self.max_linear_m_s,
                f"{name} ({getattr(self, name)}) must not exceed max_linear_m_s "
                f"({self.max_linear_m_s})",
            )
        require(
            self.degraded_max_angular_rad_s <= self.max_angular_rad_s,
            f"degraded_max_angular_rad_s ({self.degraded_max_angular_rad_s}) must not exceed "
            f"max_angular_rad_s ({self.max_angular_rad_s})",
        )
        if problems:
            raise ValueError("; ".join(problems))
        return self
