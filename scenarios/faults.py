"""Fault injection: a scenario's `faults:` list turned into actions at the right simulated time
(or the right place on the floor), and a log of when each one really took effect.

Each fault kind acts on the real part a real fault would hit, never on the supervisor's logic:
camera faults change what the simulated camera delivers (`SimCamera`), image hazards change the
rendered frame (`fault_image`), floor hazards are painted into the world's floor (`floor_marks`),
base and serial-link faults change what the base reports or receives (`FaultyLink`, with the
real Kobuki packet parser in the path), an operator stop is the control loop's own
`operator_stop(now)`, and a loop stall makes the simulator skip steps (as a hung control process
would). The supervisor must notice and respond by itself.

Took effect: a fault only counts once the part it acts on changed something the loop received
(a dropped or frozen frame, a changed image, a packet the parser rejected, a floor mark inside the
camera's region of interest, ...). `FaultSchedule.effects` logs the first such frame per fault; a
fault that never takes effect makes a campaign run an `error`, never a pass (a simulator may
accept a fault and never apply it).

`FaultSchedule.apply(now, ...)` is called once per tick before the loop steps; it returns the
names of the faults that began or ended at this tick (for logs). Never reads a clock.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from lanewarden.actuation.base import Pose2D
from lanewarden.actuation.sim_base import SimBase
from lanewarden.scenarios.fault_image import IMAGE_FAULT_KINDS, ImageHazard
from lanewarden.scenarios.fault_link import FaultyLink
from lanewarden.scenarios.sim_camera import SimCamera
from lanewarden.scenarios.spec import FLOOR_FAULT_KINDS, FaultSpec
from lanewarden.scenarios.texture import FloorMark
from lanewarden.scenarios.world import World

FloatArray = NDArray[np.float64]

_BASE_BITS = ("bumper", "cliff", "wheel_drop")
#: How a floor mark darkens: a shadow keeps this fraction of the light at intensity 1.
SHADOW_DEPTH = 0.7
#: A floor_mark reaches this far beyond each tape.
MARK_OVERHANG_M = 0.3
#: A shadow covers the floor this far beyond the lane on its side.
SHADOW_REACH_M = 1.0

#: Which alteration (noted by SimCamera or FaultyLink) proves each fault kind took effect.
_CAMERA_ALTERATION = {
    "camera_freeze": "freeze", "camera_ring": "ring", "camera_drop": "drop",
    "camera_error": "error", "late_frames": "latency", "frame_from_future": "future",
    "perception_exception": "corrupt", "frame_rate_collapse": "rate",
    "timestamp_jump": "time_jump",
}
_LINK_ALTERATION = {
    "bumper": "bits", "cliff": "bits", "wheel_drop": "bits", "base_link_loss": "link_loss",
    "link_garbage": "link_garbage", "checksum_storm": "checksum_storm",
    "write_blocks": "write_blocks", "low_battery": "low_battery",
}


class OperatorStoppable(Protocol):
    def operator_stop(self, now: float) -> object: ...


class RoiVisibility(Protocol):
    def visible_points(self, pose: Pose2D, samples: FloatArray) -> bool: ...


@dataclass(frozen=True)
class FaultEffect:
    """Fault number `index` (its place in the scenario's list) took effect at camera frame
    `frame_index` (the tick), time `time_s`."""

    index: int
    kind: str
    frame_index: int
    time_s: float

    def as_json(self) -> dict[str, object]:
        return {"index": self.index, "kind": self.kind, "frame_index": self.frame_index,
                "time_s": round(self.time_s, 4)}


@dataclass
class _Active:
    index: int
    spec: FaultSpec
    started: bool = False
    ended: bool = False
    #: floor hazards: the world points that show it (for "is it in view?")
    samples: FloatArray | None = None
    last_seen_s: float | None = None

    @property
    def end_s(self) -> float:
        return math.inf if self.spec.duration_s is None else self.spec.at_s + self.spec.duration_s


def camera_pool_size(faults: Sequence[FaultSpec], camera_rate_hz: float) -> int:
    """Frames the simulated camera must keep so the largest injected latency can be served."""
    latency = max((f.latency_s for f in faults if f.kind == "late_frames"), default=0.0)
    return max(4, math.ceil(latency * camera_rate_hz) + 4)


# ---- floor hazards ----------------------------------------------------------------------------
def _ribbon(centre: FloatArray, width_m: float) -> FloatArray:
    d = np.gradient(centre, axis=0)
    n = np.column_stack([-d[:, 1], d[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    half = width_m / 2.0
    return np.vstack([centre + half * n, (centre - half * n)[::-1]])


def _straight(start: FloatArray, heading: float, length_m: float) -> FloatArray:
    t = np.linspace(0.0, length_m, max(2, math.ceil(length_m / 0.05) + 1))
    return start + np.column_stack([t * math.cos(heading), t * math.sin(heading)])


def floor_mark(world: World, spec: FaultSpec) -> tuple[FloorMark, FloatArray]:
    """What a floor fault paints, and the points that show it is in view (world metres)."""
    assert spec.at_m is not None
    point, heading = world.centreline.at(spec.at_m)
    normal = heading + math.pi / 2.0
    tape = world.tapes[0] if world.tapes else None
    tape_width = tape.width_m if tape is not None else 0.048
    tape_bgr = tape.color_bgr if tape is not None else (40, 40, 40)
    if spec.kind == "tape_patch":
        start = point + spec.offset_m * np.array([math.cos(normal), math.sin(normal)])
        centre = _straight(start, heading + math.radians(spec.angle_deg), spec.length_m)
        return FloorMark(_ribbon(centre, tape_width), "paint", tape_bgr, 1.0), centre
    if spec.kind == "floor_mark":
        reach = world.lane_width_m / 2.0 + MARK_OVERHANG_M
        across = normal + math.radians(spec.angle_deg)
        middle = point + spec.offset_m * np.array([math.cos(normal), math.sin(normal)])
        start = middle - reach * np.array([math.cos(across), math.sin(across)])
        centre = _straight(start, across, 2 * reach)
        return (FloorMark(_ribbon(centre, spec.width_m), "paint", tape_bgr, spec.intensity),
                centre)
    if spec.kind == "shadow_edge":
        s1 = min(spec.at_m + spec.length_m, world.centreline.length_m)
        outer = world.lane_width_m / 2.0 + SHADOW_REACH_M
        far = outer if spec.side == "left" else -outer
        edge = world.centreline.offset(spec.at_m, s1, spec.offset_m)
        beyond = world.centreline.offset(spec.at_m, s1, far)
        polygon = np.vstack([edge, beyond[::-1]])
        # In view when its edge is, or the shaded lane (its tapes, its centre): a shadow whose
        # edge is out of view still darkens everything the camera sees of the lane.
        lo, hi = sorted((spec.offset_m, far))
        shaded = [world.centreline.offset(spec.at_m, s1, lateral)
                  for lateral in (world.lane_width_m / 2.0, 0.0, -world.lane_width_m / 2.0)
                  if lo <= lateral <= hi]
        return (FloorMark(polygon, "shade", factor=1.0 - SHADOW_DEPTH * spec.intensity),
                np.vstack([edge, *shaded]))
    raise ValueError(f"not a floor fault: {spec.kind}")


def floor_marks(world: World, faults: Sequence[FaultSpec]) -> list[FloorMark]:
    return [floor_mark(world, f)[0] for f in faults if f.kind in FLOOR_FAULT_KINDS]


class FaultSchedule:
    """The scenario's faults, started and ended on the simulated clock, and their effects."""

    def __init__(self, faults: Sequence[FaultSpec], world: World | None = None,
                 frame_shape: tuple[int, ...] | None = None) -> None:
        self._faults = [_Active(i, f) for i, f in sorted(enumerate(faults),
                                                          key=lambda p: p[1].at_s)]
        self._images: list[tuple[_Active, ImageHazard]] = []
        for fault in self._faults:
            if fault.spec.kind in FLOOR_FAULT_KINDS:
                if world is None:
                    raise ValueError(f"a {fault.spec.kind} fault needs the world")
                fault.samples = floor_mark(world, fault.spec)[1]
            elif fault.spec.kind in IMAGE_FAULT_KINDS:
                if frame_shape is None:
                    raise ValueError(f"a {fault.spec.kind} fault needs the frame shape")
                self._images.append((fault, ImageHazard(fault.spec, frame_shape)))
        self.effects: dict[int, FaultEffect] = {}

    # ---- per tick -----------------------------------------------------------------------------
    def apply(self, now: float, camera: SimCamera, base: FaultyLink | SimBase,
              loop: OperatorStoppable, k: int | None = None) -> list[str]:
        """Start and end the faults due at `now` (tick `k`). `base`: the FaultyLink the loop
        drives (or a bare SimBase, which only takes the base's own faults)."""
        changed: list[str] = []
        eps = 1e-9
        for fault in self._faults:
            if fault.spec.kind in FLOOR_FAULT_KINDS:
                continue
            if not fault.started and now + eps >= fault.spec.at_s:
                fault.started = True
                changed.append(f"{fault.spec.kind} begins")
                if fault.spec.kind == "operator_stop":
                    loop.operator_stop(now)
                    fault.ended = True
                    self._took_effect(fault, now, k)
            if fault.started and not fault.ended and now + eps >= fault.end_s:
                fault.ended = True
                changed.append(f"{fault.spec.kind} ends")
        if changed:
            self._set_state(now, camera, base)
        return changed

    def after_render(self, k: int, now: float, image: NDArray[np.uint8]) -> None:
        """Image hazards active now change the frame just rendered (before it is captured)."""
        for fault, hazard in self._images:
            if fault.started and not fault.ended and hazard.apply(image, now):
                self._took_effect(fault, now, k)

    def observe(self, k: int, now: float, camera: SimCamera, base: FaultyLink,
                looked: RoiVisibility | None = None, pose: Pose2D | None = None) -> None:
        """After a step: note which active faults have visibly altered what the loop got."""
        for fault in self._faults:
            kind = fault.spec.kind
            if kind in FLOOR_FAULT_KINDS:
                if looked is not None and pose is not None and fault.samples is not None:
                    if looked.visible_points(pose, fault.samples):
                        fault.last_seen_s = now
                        self._took_effect(fault, now, k)
                continue
            if fault.index in self.effects or not fault.started:
                continue
            if kind in _CAMERA_ALTERATION:
                seen = camera.altered.get(_CAMERA_ALTERATION[kind])
                if seen is not None and seen[1] >= fault.spec.at_s - 1e-9 - (
                        fault.spec.latency_s if kind == "late_frames" else 0.0):
                    self._took_effect(fault, now, k)
            elif kind in _LINK_ALTERATION:
                at = base.altered.get(_LINK_ALTERATION[kind])
                if at is not None and at >= fault.spec.at_s - 1e-9:
                    self._took_effect(fault, now, k)

    def stalled_tick(self, k: int, now: float) -> None:
        """The loop skipped this tick (loop_stall): that fault took effect."""
        for fault in self._faults:
            if fault.spec.kind == "loop_stall" and fault.started and not fault.ended:
                self._took_effect(fault, now, k)

    def _took_effect(self, fault: _Active, now: float, k: int | None = None) -> None:
        if fault.index not in self.effects:
            self.effects[fault.index] = FaultEffect(fault.index, fault.spec.kind,
                                                    -1 if k is None else k, now)

    def _active(self, kind: str) -> list[FaultSpec]:
        return [f.spec for f in self._faults if f.started and not f.ended and f.spec.kind == kind]

    def _set_state(self, now: float, camera: SimCamera, link: FaultyLink | SimBase) -> None:
        camera.dropping = bool(self._active("camera_drop"))
        late = self._active("late_frames")
        camera.latency_s = max((f.latency_s for f in late), default=0.0)
        camera.corrupt = bool(self._active("perception_exception"))
        camera.failing = bool(self._active("camera_error"))
        camera.future_s = max((f.latency_s for f in self._active("frame_from_future")),
                              default=0.0)
        camera.time_offset_s = sum(f.jump_s for f in self._active("timestamp_jump"))
        rates = [f.rate_hz for f in self._active("frame_rate_collapse")]
        camera.rate_hz = min(rates) if rates else None
        frozen = bool(self._active("camera_freeze"))
        if frozen != camera.frozen:
            camera.freeze(frozen)
        rings = self._active("camera_ring")
        if bool(rings) != camera.ringing:
            camera.ring(bool(rings), max((f.buffers for f in rings), default=2))
        bits = {name: 0 for name in _BASE_BITS}
        for name in _BASE_BITS:
            for spec in self._active(name):
                bits[name] |= spec.bits
        base = link.base if isinstance(link, FaultyLink) else link
        base.inject(**bits)
        base.set_link_alive(not self._active("base_link_loss"))
        if not isinstance(link, FaultyLink):
            return
        link.garbage_intensity = max((f.intensity for f in self._active("link_garbage")),
                                     default=0.0)
        link.checksum_storm_intensity = max(
            (f.intensity for f in self._active("checksum_storm")), default=0.0)
        batteries = [f.battery_v for f in self._active("low_battery")]
        link.battery_v = min(batteries) if batteries else None
        if self._active("write_blocks"):
            link.block_writes(now)
        else:
            link.unblock_writes(now)

    # ---- queries ------------------------------------------------------------------------------
    @property
    def pending(self) -> bool:
        """A timed fault has not started yet (a run should not end before it is applied)."""
        return any(not f.started for f in self._faults if f.spec.kind not in FLOOR_FAULT_KINDS)

    @property
    def loop_stalled(self) -> bool:
        """The control process is hung (`loop_stall`): the simulator must not step the loop."""
        return bool(self._active("loop_stall"))

    def active_kinds(self) -> list[str]:
        return sorted({f.spec.kind for f in self._faults if f.started and not f.ended})

    def windows(self, run_end_s: float) -> list[tuple[int, str, float, float]]:
        """(index, kind, from, to) in seconds for every fault that took effect: from its effect
        to its end (floor hazards: to the last frame that showed them)."""
        out = []
        for fault in self._faults:
            effect = self.effects.get(fault.index)
            if effect is None:
                continue
            if fault.spec.kind in FLOOR_FAULT_KINDS:
                end = fault.last_seen_s if fault.last_seen_s is not None else effect.time_s
            else:
                end = min(fault.end_s, run_end_s)
            out.append((fault.index, fault.spec.kind, effect.time_s, end))
        return sorted(out)
