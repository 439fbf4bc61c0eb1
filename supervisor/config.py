"""The supervisor's section of the one validated config: every threshold, timing, speed and gain.

Units are in the names (`_s` seconds, `_m` metres, `_m_s` m/s, `_rad_s` rad/s, `_frames` camera
frames). Slope sums are in the lecture's convention (dimensionless, positive = the lane bends left);
the centring signal is in metres on the floor (see `supervisor.center_offset`). Confidences
are in [0, 1]. Cross-field rules (exit below enter, late below stale, ...) are checked here, so a
bad combination is refused at start-up, before anything moves; rules across sections (the limiter's
caps within the base's limits, the camera period against the simulated camera's rate, the turn
threshold against perception's slope clamp) in `lanewarden.config.LanewardenConfig`.

This section owns the thresholds that decide what is trusted and when to turn; perception only
reports slopes and a confidence.

Never read a clock or a file here: this is data.
"""

from __future__ import annotations

from typing import Self

from pydantic import ConfigDict, Field, ValidationError, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from lanewarden.documents import DocumentModel


class SupervisorConfig(DocumentModel):
    """The supervisor's slope-sum filter, lane-evidence debounce, watchdog limits, per-state
    commands and command limiter.

    Defaults are for the simulator's camera (scenarios.camera.CameraModel) at 30 frames/s on a
    Kobuki; the closed-loop numbers are tuned there, see docs/supervisor.md.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    # --- Slope-sum Kalman filter (state: slope sum, its rate per second) ---
    slope_sum_measurement_std: float = Field(
        default=0.3,
        gt=0.0,
        le=100.0,
        description="Kalman measurement noise (std) of the slope sum at confidence 1, slope-sum "
        "units",
    )
    slope_chord_px_std: float = Field(
        default=1.0,
        ge=0.0,
        le=100.0,
        description="Pixel noise (std) of each end of a reported edge: a slope-sum outlier that "
        "would pass the gate with the variance this gives the two edges' slopes added (a short "
        "or nearly vertical chord) is still rejected but does not count towards "
        "REPEATED_OUTLIERS (0: every outlier counts), px",
    )
    measurement_confidence_floor: float = Field(
        default=0.1,
        gt=0.0,
        le=1.0,
        description="Lowest confidence used to scale the measurement noise: "
        "R = (slope_sum_measurement_std / max(confidence, floor))^2",
    )
    slope_sum_accel_std_per_s2: float = Field(
        default=40.0,
        gt=0.0,
        le=10000.0,
        description="Kalman process noise: std of the slope sum's acceleration, 1/s^2",
    )
    slope_sum_initial_rate_std_per_s: float = Field(
        default=2.0,
        gt=0.0,
        le=1000.0,
        description="Uncertainty (std) of the slope sum's rate when the filter (re)starts, 1/s",
    )
    innovation_gate_sigma: float = Field(
        default=4.0,
        gt=0.0,
        le=100.0,
        description="Mahalanobis distance, sigmas, above which a measurement is rejected as an "
        "outlier (INNOVATION_OUTLIER)",
    )
    outliers_repeated_count: int = Field(
        default=3,
        ge=1,
        le=1000,
        description="This many outliers within outliers_window_frames -> REPEATED_OUTLIERS "
        "(DEGRADED); this many in a row restart the filter on the newest measurement",
    )
    outliers_window_frames: int = Field(
        default=10,
        ge=1,
        le=1000,
        description="Window over which outliers are counted for REPEATED_OUTLIERS, camera frames",
    )
    slope_filter_restart_after_s: float = Field(
        default=0.5,
        gt=0.0,
        le=10.0,
        description="With no accepted measurement for this long the estimate expires (no "
        "extrapolation) and the next measurement restarts the filter, s",
    )
    center_offset_time_constant_s: float = Field(
        default=0.1,
        ge=0.0,
        le=10.0,
        description="Low-pass time constant of the centre offset used for steering, s (0: no "
        "filtering)",
    )
    center_preview_m: float = Field(
        default=0.36,
        ge=0.0,
        le=5.0,
        description="The centring steers towards the lane centre this far ahead of the robot's "
        "centre (combines the lane's offset and heading), m",
    )
    center_max_edge_angle_deg: float = Field(
        default=30.0,
        gt=0.0,
        le=180.0,
        description="A lane whose two reported edges run more than this far apart on the floor "
        "does not steer: the centring relaxes towards straight ahead instead (a stray tape or a "
        "shadow taken for one edge; a lane placed from one tape never steers), degrees",
    )

    # --- Confidence thresholds and debounce (frames are new camera frames) ---
    confidence_usable_min: float = Field(
        default=0.2,
        ge=0.0,
        le=1.0,
        description="Below this confidence (0-1) a frame has no usable lane (LANE_UNTRUSTED; "
        "counts towards lane_lost_halt_s); the one trust threshold: perception only reports "
        "confidence, and `lanewarden detect` and the overlay decide 'none' below this",
    )
    confidence_degrade_below: float = Field(
        default=0.45,
        ge=0.0,
        le=1.0,
        description="Confidence (0-1) below which low_confidence_degrade_frames frames in a row "
        "give LANE_LOW_CONFIDENCE (DEGRADED)",
    )
    low_confidence_degrade_frames: int = Field(
        default=3,
        ge=1,
        le=300,
        description="k: frames in a row below confidence_degrade_below before DEGRADED, camera "
        "frames",
    )
    confidence_confident_min: float = Field(
        default=0.6,
        ge=0.0,
        le=1.0,
        description="A confident frame (counts to engage and recover) has both edges and at "
        "least this confidence (0-1)",
    )
    lane_departure_clearance_m: float = Field(
        default=0.195,
        ge=0.0,
        le=1.0,
        description="A usable frame whose lane edge passes the robot's centre nearer than this "
        "(read square to the edge, near x far / (near + far) ahead, where its chord from "
        "where it is seen nearest to where it is seen farthest passes a bend's arc at the "
        "robot), or beyond it, shows "
        "the robot leaving the lane, m. 0.195: the Kobuki's footprint radius 0.175 and 0.02 "
        "to stop in (3 frames and the brakes, closing on a tape at 25 degrees). A lane whose "
        "tapes' inner edges lie less than twice this apart is refused (the robot does not fit)",
    )
    lane_departure_view_m: float = Field(
        default=0.4,
        gt=0.0,
        le=5.0,
        description="The departure rule reads an edge only when it is seen beginning within this "
        "far ahead of the robot's centre (read back at most half-way, an edge seen from 0.55 m "
        "errs by 24 mm for 5 degrees of error in its direction, more than the clearance's "
        "margin), m",
    )
    lane_departure_jump_m: float = Field(
        default=0.03,
        ge=0.0,
        le=0.5,
        description="A usable frame counts towards (or against) a departure only when its "
        "edges lie within limiter_max_linear_m_s x the time since the last frame that counted, "
        "plus this, of where that frame had them: the robot cannot have moved further, so the "
        "rest is a jump of perception (a slat or seam beside the tape), m",
    )
    lane_departure_turn_deg: float = Field(
        default=15.0,
        ge=0.0,
        le=180.0,
        description="A usable frame counts towards (or against) a departure only when its "
        "edges' directions lie within limiter_max_angular_rad_s x the time since the last frame "
        "that counted, plus this, of that frame's: the robot cannot have turned further, so the "
        "rest is a wrong line (a texture edge at 40 degrees read 0.18 m from the robot), deg",
    )
    lane_departure_frames: int = Field(
        default=3,
        ge=1,
        le=30,
        description="Usable frames in a row showing a departure before LANE_DEPARTURE "
        "(HALT), camera frames",
    )
    engage_confident_frames: int = Field(
        default=10,
        ge=1,
        le=300,
        description="N: confident frames in a row before a start or resume engages FOLLOW, "
        "camera frames",
    )
    engage_window_frames: int = Field(
        default=0,
        ge=0,
        le=300,
        description="M: a start or resume engages once engage_confident_frames of the last M "
        "judged camera frames were confident, the newest among them (k of n, for cameras whose "
        "confident frames come in short bursts); 0: all engage_confident_frames in a row",
    )
    recover_confident_frames: int = Field(
        default=5,
        ge=1,
        le=300,
        description="m: confident frames before DEGRADED recovers to FOLLOW (in a row, or "
        "among the last recover_window_frames), camera frames",
    )
    recover_window_frames: int = Field(
        default=8,
        ge=0,
        le=300,
        description="M: DEGRADED recovers to FOLLOW once recover_confident_frames of the last M "
        "camera frames judged since it was entered were confident, the newest among them (k of "
        "n, as engage_window_frames; 8: 5 of the last 8, confident frames on a speckled floor "
        "come in bursts); 0: all recover_confident_frames in a row (docs/campaigns.md, the "
        "twenty-sixth run)",
    )

    # --- Turn hysteresis on the filtered slope sum (the lecture's +-6) ---
    turn_enter_slope_sum: float = Field(
        default=6.0,
        gt=0.0,
        le=100.0,
        description="The lecture's 6, its one home: enter TURN_LEFT/TURN_RIGHT when the filtered "
        "slope sum passes +- this; the lecture controller turns beyond +- this raw slope sum, and "
        "`lanewarden detect` and the video overlay decide left/right with it",
    )
    turn_exit_slope_sum: float = Field(
        default=4.0,
        ge=0.0,
        le=100.0,
        description="Leave a turn for FOLLOW when the filtered slope sum is back inside +- this "
        "(below turn_enter_slope_sum)",
    )

    # --- Watchdog and timing ---
    camera_period_s: float = Field(
        default=1.0 / 30.0,
        gt=0.0,
        le=1.0,
        description="Expected camera frame period, also the runner's control-loop period, s "
        "(must match simulation.camera_rate_hz, checked at load)",
    )
    loop_overrun_s: float = Field(
        default=0.1,
        gt=0.0,
        le=2.0,
        description="Step-to-step time above this gives LOOP_OVERRUN (a warning) and caps the "
        "limiter's dt, s",
    )
    frame_late_s: float = Field(
        default=0.08,
        gt=0.0,
        le=1.0,
        description="Newest frame older than this gives FRAME_LATE (DEGRADED), s",
    )
    frame_stale_s: float = Field(
        default=0.15,
        gt=0.0,
        le=1.0,
        description="Newest frame older than this gives FRAME_STALE (HALT), s",
    )
    frame_frozen_s: float = Field(
        default=0.15,
        gt=0.0,
        le=2.0,
        description="Identical images for this long while commanded to move give FRAME_FROZEN "
        "(HALT), s",
    )
    base_feedback_late_s: float = Field(
        default=0.1,
        gt=0.0,
        le=1.0,
        description="Newest base feedback older than this gives BASE_FEEDBACK_LATE (DEGRADED), s",
    )
    base_link_timeout_s: float = Field(
        default=0.2,
        gt=0.0,
        le=1.0,
        description="No base feedback for this long gives BASE_LINK_LOST (HALT), s",
    )
    battery_low_v: float = Field(
        default=14.0,
        ge=0.0,
        le=20.0,
        description="Base battery below this gives BATTERY_LOW (WARN), V (the Kobuki driver's "
        "low level for its 14.8 V pack)",
    )
    battery_critical_v: float = Field(
        default=13.2,
        ge=0.0,
        le=20.0,
        description="Base battery below this gives BATTERY_CRITICAL (HALT, latched like a "
        "bumper), V (the Kobuki driver's dangerous level); 0 switches the check off for a base "
        "that reports no battery",
    )
    lane_lost_halt_s: float = Field(
        default=0.2,
        gt=0.0,
        le=1.0,
        description="Halt (LANE_LOST) when engaged with no usable lane for longer than this, by "
        "capture time, s",
    )

    # --- DEGRADED ---
    degraded_speed_fraction: float = Field(
        default=0.5,
        gt=0.0,
        le=1.0,
        description="DEGRADED drives at follow_speed_m_s times this fraction (0-1]",
    )
    degraded_max_angular_rad_s: float = Field(
        default=0.4,
        gt=0.0,
        le=3.2,
        description="DEGRADED clips its steering to +- this, rad/s",
    )
    degraded_budget_s: float = Field(
        default=3.0,
        gt=0.0,
        le=10.0,
        description="Staying DEGRADED longer than this halts (DEGRADED_BUDGET_EXHAUSTED), s. "
        "The default is the distance budget at DEGRADED's own speed (0.3 m at 0.1 m/s): a robot "
        "driving is bounded by the distance, this bounds one that barely moves",
    )
    degraded_budget_m: float = Field(
        default=0.3,
        gt=0.0,
        le=2.0,
        description="Driving further than this while DEGRADED (commanded speed x dt) halts, m",
    )

    # --- Commands per state ---
    follow_speed_m_s: float = Field(
        default=0.2,
        gt=0.0,
        le=0.7,
        description="Forward speed in FOLLOW, m/s (at most limiter_max_linear_m_s)",
    )
    slope_sum_gain_rad_s: float = Field(
        default=0.03,
        ge=0.0,
        le=1.0,
        description="Left-turn rate per unit of filtered slope sum, rad/s",
    )
    center_offset_gain_rad_s_per_m: float = Field(
        default=3.6,
        ge=0.0,
        le=20.0,
        description="Left-turn rate per metre the lane centre lies left of the robot, "
        "center_preview_m ahead (filtered), rad/s per m",
    )
    turn_speed_m_s: float = Field(
        default=0.15,
        gt=0.0,
        le=0.7,
        description="Forward speed in TURN_LEFT/TURN_RIGHT and in the lecture controller's "
        "turns, m/s (at most limiter_max_linear_m_s)",
    )
    turn_extra_angular_rad_s: float = Field(
        default=0.2,
        ge=0.0,
        le=3.2,
        description="TURN_LEFT/TURN_RIGHT add this to the proportional steering, rad/s",
    )
    turn_extra_fade_m: float = Field(
        default=0.05,
        gt=0.0,
        le=1.0,
        description="TURN_LEFT/TURN_RIGHT withhold turn_extra_angular_rad_s in proportion as "
        "the lane centre (center_preview_m ahead) lies on the outer side of the turn, all of it "
        "from this far: the robot is on the inner side of the bend, and the extra would take it "
        "onto the inner tape, m",
    )

    # --- Command limiter in the SafetyGate (the Kobuki velocity smoother: 0.3 m/s^2, 3.5 rad/s^2)
    limiter_max_linear_m_s: float = Field(
        default=0.3,
        gt=0.0,
        le=0.7,
        description="The gate's cap on a controller's linear speed, m/s; at most "
        "actuation.max_linear_m_s (the base's own limit, checked at load)",
    )
    limiter_max_angular_rad_s: float = Field(
        default=1.0,
        gt=0.0,
        le=3.2,
        description="The gate's cap on a controller's angular speed, rad/s; at most "
        "actuation.max_angular_rad_s (the base's own limit, checked at load)",
    )
    max_linear_accel_m_s2: float = Field(
        default=0.3,
        gt=0.0,
        le=5.0,
        description="Limiter ramp for increases of linear speed, m/s^2 (decreases pass at once)",
    )
    max_angular_accel_rad_s2: float = Field(
        default=3.5,
        gt=0.0,
        le=50.0,
        description="Limiter ramp for increases of angular speed, rad/s^2 (decreases pass at "
        "once)",
    )

    # --- Resume policy ---
    auto_resume_after_lane_loss: bool = Field(
        default=False,
        description="Re-engage by itself after a LANE_LOST halt once engage_confident_frames "
        "confident frames are seen (no other halt is forgiven)",
    )

    # --- The lecture's baseline controller (--controller lecture; it turns at turn_enter_slope_sum)
    lecture_turn_angular_rad_s: float = Field(
        default=0.4,
        gt=0.0,
        le=3.2,
        description="Lecture controller: fixed turn rate while turning, rad/s",
    )

    @model_validator(mode="after")
    def _consistent(self) -> Self:
        """Values that must agree: each disagreement is one error at one key, naming the other
        (`supervisor.follow_speed_m_s = 0.5: must not exceed limiter_max_linear_m_s (0.3)`)."""
        problems: list[tuple[str, str]] = []

        def require(ok: bool, key: str, text: str) -> None:
            if not ok:
                problems.append((key, text))

        for kind in ("engage", "recover"):  # a k-of-n window holds at least its k frames
            window = getattr(self, f"{kind}_window_frames")
            needed = getattr(self, f"{kind}_confident_frames")
            # (Only a window the config sets: the default window of 8 with more frames asked
            # is all of them in a row, `ConfidentFrames`.)
            require(window == 0 or window >= needed
                    or f"{kind}_window_frames" not in self.model_fields_set,
                    f"{kind}_window_frames",
                    f"must be 0 or at least {kind}_confident_frames ({needed})")
        require(self.turn_exit_slope_sum < self.turn_enter_slope_sum, "turn_exit_slope_sum",
                f"must be below turn_enter_slope_sum ({self.turn_enter_slope_sum})")
        require(self.confidence_usable_min <= self.confidence_degrade_below,
                "confidence_usable_min",
                f"must not exceed confidence_degrade_below ({self.confidence_degrade_below})")
        require(self.confidence_degrade_below <= self.confidence_confident_min,
                "confidence_degrade_below",
                f"must not exceed confidence_confident_min ({self.confidence_confident_min})")
        require(self.frame_late_s < self.frame_stale_s, "frame_late_s",
                f"must be below frame_stale_s ({self.frame_stale_s})")
        require(self.base_feedback_late_s < self.base_link_timeout_s, "base_feedback_late_s",
                f"must be below base_link_timeout_s ({self.base_link_timeout_s})")
        require(self.battery_critical_v < self.battery_low_v, "battery_critical_v",
                f"must be below battery_low_v ({self.battery_low_v})")
        require(self.loop_overrun_s > self.camera_period_s, "loop_overrun_s",
                f"must be above camera_period_s ({self.camera_period_s})")
        for name in ("follow_speed_m_s", "turn_speed_m_s"):
            require(getattr(self, name) <= self.limiter_max_linear_m_s, name,
                    f"must not exceed limiter_max_linear_m_s ({self.limiter_max_linear_m_s})")
        require(self.degraded_max_angular_rad_s <= self.limiter_max_angular_rad_s,
                "degraded_max_angular_rad_s",
                f"must not exceed limiter_max_angular_rad_s ({self.limiter_max_angular_rad_s})")
        if problems:
            raise ValidationError.from_exception_data(type(self).__name__, [
                InitErrorDetails(type=PydanticCustomError("values_disagree", text), loc=(key,),
                                 input=getattr(self, key))
                for key, text in problems
            ])  # fmt: skip
        return self
