"""Kalman filter (filterpy) on the lane's slope sum, with outlier gating.

State x = [slope_sum, rate_per_s] (constant-rate model). Time is the frames' capture time: F and Q
are built for each step's dt (once per distinct dt: a camera's frame intervals take few values)
and passed to `predict(F=..., Q=...)`. The measurement noise grows
as the observation's confidence falls (R = (std / max(confidence, floor))^2). A frame without a
usable slope sum only predicts, so the variance grows. Before an update the innovation's
Mahalanobis distance is checked: above `innovation_gate_sigma` the measurement is rejected and
reported as INNOVATION_OUTLIER; repeated outliers raise REPEATED_OUTLIERS, and when the last
`outliers_repeated_count` measurements were ALL rejected the lane has really changed (or perception
is garbage; either way the supervisor degrades), so the filter restarts on the newest measurement
instead of ignoring the world forever.

An outlier that the two edges' own pixels explain does not count towards REPEATED_OUTLIERS: one
that would pass the gate with `chord_slope_variance` added to R. A slope measured over a short or
nearly vertical chord moves a lot with one pixel at either end; on a bend at 320x240 perception
may report the tape's near part in one frame and a far stub of it (slope at the clamp) in the
next, and those stubs, rejected frame after frame, kept the supervisor DEGRADED until its budget
ran out. They are still rejected (the estimate is what it would be without this), and a run of
them still restarts the filter: at the lecture's corner the turn first shows as such steep
chords, and weighing them less (R itself grown by the chords) turned right too late there.

Pure: no clock (time comes with each call), no I/O.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from enum import Enum

import numpy as np
from filterpy.kalman import KalmanFilter

from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.events import Event


@dataclass(frozen=True)
class SlopeEstimate:
    """The filter's output after one frame.

    `slope_sum`/`variance`/`rate_per_s` are None until the first measurement is accepted.
    `innovation` (z - H x_prior) and `mahalanobis` are None when the frame carried no measurement.
    """

    slope_sum: float | None
    variance: float | None
    rate_per_s: float | None
    innovation: float | None = None
    mahalanobis: float | None = None
    accepted: bool = False
    events: frozenset[Event] = frozenset()

    @property
    def outlier(self) -> bool:
        return Event.INNOVATION_OUTLIER in self.events


#: How many distinct step lengths' F and Q a filter keeps (a camera's intervals take few values).
MOTION_MODELS_KEPT = 64


def transition_matrix(dt: float) -> np.ndarray:
    return np.array([[1.0, dt], [0.0, 1.0]])


def process_noise(dt: float, config: SupervisorConfig) -> np.ndarray:
    """Discrete white-noise acceleration for the constant-rate model over dt seconds.

    Closed form (the same matrix as filterpy's `Q_discrete_white_noise(dim=2, dt, var)`, without
    its general-purpose construction on every step): var * [[dt^4/4, dt^3/2], [dt^3/2, dt^2]].
    """
    var = config.slope_sum_accel_std_per_s2**2
    dt2 = dt * dt
    q01 = 0.5 * dt2 * dt * var
    return np.array([[0.25 * dt2 * dt2 * var, q01], [q01, dt2 * var]])


def measurement_variance(confidence: float, config: SupervisorConfig) -> float:
    """R for one slope-sum measurement: low confidence, large noise."""
    c = max(min(confidence, 1.0), config.measurement_confidence_floor)
    return (config.slope_sum_measurement_std / c) ** 2


class Gated(Enum):
    """What the gate made of one measurement, as `SlopeSumFilter` remembers it over
    `outliers_window_frames`."""

    ACCEPTED = "accepted"
    #: rejected, but within what the edges' own pixels allow (`chord_slope_variance`)
    EXPLAINED = "explained"
    #: rejected, and counted towards REPEATED_OUTLIERS
    OUTLIER = "outlier"


#: A chord this many pixels across, at least, in `chord_slope_variance` (a vertical chord's slope is
#: known to be steep, not how steep: its noise is then large but finite).
MIN_CHORD_RUN_PX = 0.5


def chord_slope_variance(edge: LaneEdge, config: SupervisorConfig) -> float:
    """The variance of an edge's slope from its end points' pixel noise.

    The slope of the chord (x1, y1)-(x2, y2) is s = dy / dx (dx = x2 - x1, dy = y1 - y2). With
    each end's x and y off by an independent `slope_chord_px_std` (sigma), dx and dy each have
    variance 2 sigma^2, and first-order propagation gives
        var(s) = 2 sigma^2 (dx^2 + dy^2) / dx^4 ,
    about 0.0006 for a 640x480 straight lane's 230-pixel chord at slope 1.75, about 13 000 (a
    std of 113) for a 20-pixel vertical stub (|dx| is taken as at least MIN_CHORD_RUN_PX)."""
    sigma = config.slope_chord_px_std
    dx = max(abs(edge.x2 - edge.x1), MIN_CHORD_RUN_PX)
    dy = edge.y1 - edge.y2
    return 2.0 * sigma * sigma * (dx * dx + dy * dy) / (dx * dx * dx * dx)


def slope_sum_chord_variance(observation: LaneObservation, config: SupervisorConfig) -> float:
    """`chord_slope_variance` of the two edges together (0 without both: no slope sum)."""
    if observation.left is None or observation.right is None:
        return 0.0
    return (chord_slope_variance(observation.left, config)
            + chord_slope_variance(observation.right, config))


def make_slope_sum_filter(
    slope_sum: float, confidence: float, config: SupervisorConfig
) -> KalmanFilter:
    """The one factory: a filter started at a measured slope sum with rate 0."""
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.x = np.array([[slope_sum], [0.0]])
    kf.H = np.array([[1.0, 0.0]])
    kf.F = transition_matrix(0.0)
    kf.R = np.array([[measurement_variance(confidence, config)]])
    kf.P = np.diag([kf.R[0, 0], config.slope_sum_initial_rate_std_per_s**2])
    kf.Q = process_noise(0.0, config)
    return kf


class SlopeSumFilter:
    """Runs the slope-sum Kalman filter frame by frame. One instance per run."""

    def __init__(self, config: SupervisorConfig) -> None:
        self._config = config
        self._kf: KalmanFilter | None = None
        self._time_s: float | None = None
        self._accepted_at_s: float | None = None
        self._window: deque[Gated] = deque(maxlen=config.outliers_window_frames)
        self._last = SlopeEstimate(None, None, None)
        self._motion_by_dt: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    @property
    def estimate(self) -> SlopeEstimate:
        """The latest output (also returned by `step`)."""
        return self._last

    def step(self, time_s: float, slope_sum: float | None, confidence: float,
             chord_variance: float = 0.0) -> SlopeEstimate:
        """Advance to `time_s` (a frame's capture time) and fuse `slope_sum` if there is one.

        `slope_sum` None (or not finite) means "no usable measurement in this frame": predict only.
        `chord_variance`: the variance the edges' own pixels give the measurement
        (`slope_sum_chord_variance`): an outlier within it does not count towards
        REPEATED_OUTLIERS.
        """
        cfg = self._config
        measured = slope_sum is not None and math.isfinite(slope_sum)
        if self._kf is None or (
            measured
            and self._accepted_at_s is not None
            and time_s - self._accepted_at_s > cfg.slope_filter_restart_after_s
        ):
            if not measured:
                self._time_s = time_s
                return self._remember(SlopeEstimate(None, None, None))
            assert slope_sum is not None
            return self._restart(time_s, slope_sum, confidence, frozenset())

        dt = 0.0 if self._time_s is None else max(0.0, time_s - self._time_s)
        self._time_s = time_s if self._time_s is None else max(time_s, self._time_s)
        if dt > 0.0:
            f, q = self._motion_model(dt)
            self._kf.predict(F=f, Q=q)
        if not measured:
            if (
                self._accepted_at_s is not None
                and time_s - self._accepted_at_s > cfg.slope_filter_restart_after_s
            ):
                # Expired: extrapolating the last rate for seconds would invent a bend. There is
                # no estimate until the next measurement restarts the filter.
                return self._remember(SlopeEstimate(None, None, None))
            return self._remember(self._snapshot())
        assert slope_sum is not None

        r = measurement_variance(confidence, cfg)
        # H = [1, 0]: H x is the slope sum's estimate and H P H' its variance.
        innovation = slope_sum - float(self._kf.x[0, 0])
        s = float(self._kf.P[0, 0]) + r
        distance = abs(innovation) / math.sqrt(s)
        if distance > cfg.innovation_gate_sigma:
            # Rejected either way; one that its edges' own pixels explain (a far stub of a
            # bending tape) does not count towards REPEATED_OUTLIERS (module docstring).
            counted = abs(innovation) > cfg.innovation_gate_sigma * math.sqrt(s + chord_variance)
            self._window.append(Gated.OUTLIER if counted else Gated.EXPLAINED)
            events = {Event.INNOVATION_OUTLIER}
            if self._window.count(Gated.OUTLIER) >= cfg.outliers_repeated_count:
                events.add(Event.REPEATED_OUTLIERS)
            recent = list(self._window)[-cfg.outliers_repeated_count :]
            if (len(recent) == cfg.outliers_repeated_count
                    and Gated.ACCEPTED not in recent):
                # The world moved and the gate would ignore it forever: start again from here.
                restarted = self._restart(time_s, slope_sum, confidence, frozenset(events))
                return self._remember(
                    SlopeEstimate(
                        restarted.slope_sum,
                        restarted.variance,
                        restarted.rate_per_s,
                        innovation,
                        distance,
                        True,
                        frozenset(events),
                    )
                )
            return self._remember(self._snapshot(innovation, distance, False, frozenset(events)))

        self._window.append(Gated.ACCEPTED)
        self._kf.update(np.array([[slope_sum]]), R=np.array([[r]]), H=self._kf.H)
        self._accepted_at_s = time_s
        return self._remember(self._snapshot(innovation, distance, True))

    def _motion_model(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """F and Q for a step of `dt` seconds, read-only (filterpy's predict only reads them)."""
        model = self._motion_by_dt.get(dt)
        if model is None:
            if len(self._motion_by_dt) >= MOTION_MODELS_KEPT:
                self._motion_by_dt.clear()
            model = (transition_matrix(dt), process_noise(dt, self._config))
            for matrix in model:
                matrix.flags.writeable = False
            self._motion_by_dt[dt] = model
        return model

    def _restart(
        self, time_s: float, slope_sum: float, confidence: float, events: frozenset[Event]
    ) -> SlopeEstimate:
        self._kf = make_slope_sum_filter(slope_sum, confidence, self._config)
        self._time_s = time_s
        self._accepted_at_s = time_s
        self._window.clear()
        return self._remember(self._snapshot(None, None, True, events))

    def _snapshot(
        self,
        innovation: float | None = None,
        distance: float | None = None,
        accepted: bool = False,
        events: frozenset[Event] = frozenset(),
    ) -> SlopeEstimate:
        assert self._kf is not None
        return SlopeEstimate(
            slope_sum=float(self._kf.x[0, 0]),
            variance=float(self._kf.P[0, 0]),
            rate_per_s=float(self._kf.x[1, 0]),
            innovation=innovation,
            mahalanobis=distance,
            accepted=accepted,
            events=events,
        )

    def _remember(self, estimate: SlopeEstimate) -> SlopeEstimate:
        self._last = estimate
        return estimate
