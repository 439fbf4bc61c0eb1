"""The scenario file format: what a scenario YAML may say, validated, with every default here.

A scenario is data: the floor, the tapes and the lane they mark (built from straight segments and
arcs), gaps, dashes and tape ends, the lighting, the robot's camera, where the robot starts, when
the run stops, the faults to inject, optional config overrides, and the expected outcome per
controller.

Units are in the names (`_m`, `_deg`, `_s`). Lane positions (`at_m`, `from_m`, ...) are arc lengths
along the lane's centre line from its start. Angles: `turn_deg` > 0 turns left (counter-clockwise),
< 0 turns right. Colours are "#rrggbb".

This module only declares and validates; it never renders, never reads a clock and never builds
the closed loop. Bad files become ScenarioError with one line per bad key, naming the file.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from lanewarden.documents import DocumentModel, read_yaml_document, validation_error_lines
from lanewarden.perception.ground import (
    DEFAULT_HFOV_DEG,
    DEFAULT_POSE_FORWARD_M,
    DEFAULT_POSE_HEIGHT_M,
    DEFAULT_POSE_PITCH_DEG,
)
from lanewarden.scenarios.camera import DEFAULT_DIST_COEFFS
from lanewarden.scenarios.errors import ScenarioError

ModelT = TypeVar("ModelT", bound=BaseModel)

#: Limits on the world a scenario may describe, checked before anything is built or painted (the
#: floor texture costs ~35 bytes per pixel while it is painted; see `scenarios.texture`).
MAX_LANE_LENGTH_M = 100.0
MAX_SEGMENTS = 200
MAX_GAPS = 100
MAX_GLARE_SPOTS = 20
MAX_FAULTS = 50
MAX_LIGHT_CHANGES = 20
#: Anywhere in the world (start positions, offsets), metres from the origin.
MAX_COORDINATE_M = 1000.0
#: A position or shift on the floor, metres, within MAX_COORDINATE_M (a tile grid's or the ceiling
#: lights' offset of 1e300 had made the floor NaN with warnings, or a traceback).
Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE_M, le=MAX_COORDINATE_M)]

Color = Annotated[str, Field(pattern=r"^#[0-9a-fA-F]{6}$")]
TapeSide = Literal["left", "right", "both"]

#: Every fault a scenario can inject (see `scenarios.faults` for what each does).
FaultKind = Literal[
    "camera_freeze",
    "camera_ring",
    "camera_drop",
    "camera_error",
    "late_frames",
    "frame_from_future",
    "perception_exception",
    "loop_stall",
    "bumper",
    "cliff",
    "wheel_drop",
    "base_link_loss",
    "operator_stop",
    # perception hazards on the floor (placed at a lane position, painted into the world)
    "tape_patch",
    "floor_mark",
    "shadow_edge",
    # perception hazards in the camera's image (a time window)
    "glare_sweep",
    "occlusion",
    "lens_smudge",
    "exposure_jump",
    # the camera driver
    "frame_rate_collapse",
    "timestamp_jump",
    # the base and its serial link
    "link_garbage",
    "checksum_storm",
    "write_blocks",
    "low_battery",
]

#: Fault kinds that are things on the floor: placed by `at_m` (lane position), not by time.
FLOOR_FAULT_KINDS = ("tape_patch", "floor_mark", "shadow_edge")


class _Model(DocumentModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def color_bgr(color: str) -> tuple[int, int, int]:
    """"#rrggbb" -> (b, g, r), OpenCV's channel order."""
    value = int(color[1:], 16)
    return (value & 0xFF, (value >> 8) & 0xFF, (value >> 16) & 0xFF)


FloorKind = Literal["tiles", "plain", "wood", "noisy", "ceramic", "terrazzo", "foam",
                    "parquet", "carpet", "concrete"]

#: What each floor kind looks like unless the scenario says otherwise (the other kinds: the
#: field defaults, the lecture's tiles). `gloss`: the share of a ceiling light's brightness the
#: surface mirrors (glazed ceramic about 8%, polished terrazzo 5%, varnished parquet 4%, sealed
#: concrete 2%; see `CeilingLightsSpec`).
KIND_DEFAULTS: dict[str, dict[str, Any]] = {
    "ceramic": {"color": "#d9d5cd", "seam_color": "#a29b90", "tile_m": 0.45, "seam_m": 0.003,
                "variation": 0.02, "grain": 0.015, "gloss": 0.08, "roughness_rad": 0.015},
    "terrazzo": {"color": "#b7b1a6", "seam_color": "#98928a",
                 "colors": ["#eeebe4", "#3c3a37", "#8e6652", "#c8c1b3", "#6e7371"],
                 "tile_m": 0.40, "seam_m": 0.002, "variation": 0.02, "grain": 0.03,
                 "gloss": 0.05, "roughness_rad": 0.03},
    "foam": {"color": "#58667e", "seam_color": "#262a31", "colors": ["#58667e", "#8a8e95"],
             "tile_m": 0.60, "seam_m": 0.003, "variation": 0.03, "grain": 0.08},
    "parquet": {"color": "#a5763f", "seam_color": "#55391c", "tile_m": 0.24, "seam_m": 0.0015,
                "variation": 0.10, "grain": 0.05, "gloss": 0.04, "roughness_rad": 0.06},
    "carpet": {"color": "#6a6d73", "seam_m": 0.0, "variation": 0.06, "grain": 0.2},
    "concrete": {"color": "#9b9994", "seam_color": "#57554f", "colors": ["#76726b"],
                 "tile_m": 3.0, "seam_m": 0.004, "variation": 0.08, "grain": 0.05,
                 "gloss": 0.02, "roughness_rad": 0.08},
}
#: Gloss of a tape of `sheen` 1 (glossy vinyl).
TAPE_GLOSS_AT_FULL_SHEEN = 0.1
#: Largest gloss (the floor texture's gloss layer spans 0 .. this).
MAX_GLOSS = 0.25


class FloorSpec(_Model):
    """The floor, every size in metres (`scenarios.floors` paints each kind):

    - `tiles`: square tiles `tile_m` with grout seams `seam_m` (the lecture's floor);
    - `ceramic`: glossy ceramic tiles: tiles whose glaze mirrors the ceiling lights;
    - `terrazzo`: stone chips (`chip_m` across, `chip_fraction` of the surface, in `colors`)
      in a cement matrix (`color`), in tiles `tile_m` with thin grout (seam_m 0: poured, none);
    - `foam`: interlocking foam mats `tile_m` square, jigsaw seams (teeth `tooth_m` deep),
      mats coloured from `colors` in turn, a fine embossed texture;
    - `wood`: planks `tile_m` / 2.5 wide along x with butt joints every 1.2 m, grain;
    - `parquet`: basket-weave blocks `tile_m` square, each of `slats` slats, alternating
      direction, grain along each slat;
    - `carpet`: fibre texture and blotches, no seams;
    - `concrete`: blotches, fine speckle, `cracks_per_m2` cracks and `stains_per_m2` stains,
      saw-cut joints every `tile_m` when `seam_m` > 0;
    - `plain`: one colour with faint blotches; `noisy`: strong speckle.

    `variation` is the spread of brightness between tiles, mats, planks (fraction), `grain` the
    fine texture amplitude (fraction), `grid_angle_deg` rotates the tile grid against the world
    axes (tiles, ceramic). `gloss` is the share of a ceiling light the floor mirrors,
    `roughness_rad` how far its mirror image is spread. A key not given takes the kind's usual
    value (`KIND_DEFAULTS`), else the default below.
    """

    kind: FloorKind = "tiles"
    color: Color = "#c9c5bd"
    seam_color: Color = "#8c877e"
    #: further colours: terrazzo chips, foam mats (in turn), concrete stains (the first)
    colors: Annotated[list[Color], Field(max_length=8)] = []
    tile_m: Annotated[float, Field(gt=0.05, le=5.0)] = 0.30
    seam_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.004
    grid_angle_deg: Annotated[float, Field(ge=-360.0, le=360.0)] = 0.0
    grid_offset_m: tuple[Coordinate, Coordinate] = (0.0, 0.0)
    variation: Annotated[float, Field(ge=0.0, le=0.5)] = 0.04
    grain: Annotated[float, Field(ge=0.0, le=0.5)] = 0.03
    chip_m: Annotated[float, Field(ge=0.003, le=0.08)] = 0.012
    chip_fraction: Annotated[float, Field(ge=0.0, le=0.7)] = 0.4
    tooth_m: Annotated[float, Field(ge=0.0, le=0.1)] = 0.025
    slats: Annotated[int, Field(ge=2, le=10)] = 4
    cracks_per_m2: Annotated[float, Field(ge=0.0, le=5.0)] = 0.15
    stains_per_m2: Annotated[float, Field(ge=0.0, le=5.0)] = 0.3
    gloss: Annotated[float, Field(ge=0.0, le=MAX_GLOSS)] = 0.0
    roughness_rad: Annotated[float, Field(ge=0.002, le=0.5)] = 0.04

    @model_validator(mode="before")
    @classmethod
    def _kind_defaults(cls, data: Any) -> Any:
        if isinstance(data, Mapping) and isinstance(data.get("kind"), str):
            usual = KIND_DEFAULTS.get(data["kind"], {})
            return {**usual, **data}
        return data


class TapeLook(_Model):
    """One side's tape where it differs from `tape:` (only the keys given change)."""

    width_m: Annotated[float | None, Field(gt=0.005, le=0.2)] = None
    color: Color | None = None
    sheen: Annotated[float | None, Field(ge=0.0, le=1.0)] = None
    wear: Annotated[float | None, Field(ge=0.0, le=1.0)] = None
    tears_per_m: Annotated[float | None, Field(ge=0.0, le=20.0)] = None
    wrinkles_per_m: Annotated[float | None, Field(ge=0.0, le=40.0)] = None
    end_angle_deg: Annotated[float | None, Field(ge=0.0, le=60.0)] = None


class TapeSpec(_Model):
    """The tape the lane edges are made of (the lecture's: dark tape, 48 mm wide).

    - `sheen`: how glossy the tape is (0 matte paper tape .. 1 glossy vinyl, which mirrors
      `TAPE_GLOSS_AT_FULL_SHEEN` of a ceiling light: `CeilingLightsSpec`);
    - `wear`: fraction of the tape's length in worn patches (faded: the floor shows through);
    - `tears_per_m`: torn-off chunks along an edge, per metre of tape;
    - `wrinkles_per_m`: creases across the tape, per metre;
    - `end_angle_deg`: every tape end (dashes, gaps, the end) cut at up to this angle from square;
    - `left` / `right`: that side's tape where it differs (a 25 mm yellow line on the left, a
      48 mm white line on the right).

    Wear, tears and wrinkles are drawn with the floor's seed (`--seed`).
    """

    width_m: Annotated[float, Field(gt=0.005, le=0.2)] = 0.048
    color: Color = "#26262a"
    sheen: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0
    wear: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0
    tears_per_m: Annotated[float, Field(ge=0.0, le=20.0)] = 0.0
    wrinkles_per_m: Annotated[float, Field(ge=0.0, le=40.0)] = 0.0
    end_angle_deg: Annotated[float, Field(ge=0.0, le=60.0)] = 0.0
    left: TapeLook | None = None
    right: TapeLook | None = None

    def side(self, side: str) -> TapeSpec:
        """The tape of one side (`left`, `right` or `centre`), its overrides applied."""
        look = self.left if side == "left" else self.right if side == "right" else None
        base = self.model_copy(update={"left": None, "right": None})
        if look is None:
            return base
        return base.model_copy(update=look.model_dump(exclude_none=True))


class PoseSpec(_Model):
    x_m: Annotated[float, Field(ge=-MAX_COORDINATE_M, le=MAX_COORDINATE_M)] = 0.0
    y_m: Annotated[float, Field(ge=-MAX_COORDINATE_M, le=MAX_COORDINATE_M)] = 0.0
    heading_deg: Annotated[float, Field(ge=-360.0, le=360.0)] = 0.0


class SegmentSpec(_Model):
    """One piece of the lane's centre line: either `straight_m`, or `arc_radius_m` + `turn_deg`.

    `mark` names the gate at the END of this segment (e.g. A after the right turn); a run that
    crosses the gate between the tapes has completed that turn (`turns_completed`).
    """

    straight_m: Annotated[float | None, Field(gt=0.0, le=MAX_LANE_LENGTH_M)] = None
    arc_radius_m: Annotated[float | None, Field(gt=0.0, le=MAX_LANE_LENGTH_M)] = None
    turn_deg: Annotated[float | None, Field(ge=-360.0, le=360.0)] = None
    mark: str | None = None

    @model_validator(mode="after")
    def _one_kind(self) -> SegmentSpec:
        is_straight = self.straight_m is not None
        is_arc = self.arc_radius_m is not None or self.turn_deg is not None
        if is_straight == is_arc:
            raise ValueError("expected either straight_m, or arc_radius_m with turn_deg")
        if is_arc and (self.arc_radius_m is None or self.turn_deg in (None, 0.0)):
            raise ValueError("an arc needs both arc_radius_m > 0 and a non-zero turn_deg")
        return self

    @property
    def length_m(self) -> float:
        """Its length along the centre line, m."""
        if self.straight_m is not None:
            return self.straight_m
        return (self.arc_radius_m or 0.0) * abs(math.radians(self.turn_deg or 0.0))


class GapSpec(_Model):
    """A stretch where one tape (or both) is missing: [from_m, to_m) along the centre line."""

    tape: TapeSide
    from_m: Annotated[float, Field(ge=0.0)]
    to_m: Annotated[float, Field(gt=0.0)]

    @model_validator(mode="after")
    def _ordered(self) -> GapSpec:
        if self.to_m <= self.from_m:
            raise ValueError(f"to_m ({self.to_m}) must be greater than from_m ({self.from_m})")
        return self


class DashSpec(_Model):
    """Dashed tape: `on_m` of tape, `off_m` of gap, repeated from `from_m` (to `to_m` or the
    end)."""

    tape: TapeSide = "both"
    on_m: Annotated[float, Field(ge=0.05, le=MAX_LANE_LENGTH_M)]
    off_m: Annotated[float, Field(ge=0.05, le=MAX_LANE_LENGTH_M)]
    from_m: Annotated[float, Field(ge=0.0)] = 0.0
    to_m: Annotated[float | None, Field(gt=0.0)] = None


class EndsSpec(_Model):
    """Where each tape ends along the centre line; None: it runs to the end of the segments.

    The path may continue past the tape ends (unmarked floor): it gives the lane's final direction
    and keeps that floor inside the rendered world.
    """

    left_m: Annotated[float | None, Field(gt=0.0)] = None
    right_m: Annotated[float | None, Field(gt=0.0)] = None


class LaneSpec(_Model):
    """The lane: `width_m` between the tape centres; `lines`: `edges` (a tape along each side)
    or `centre` (a single-line track: one tape along the centre line, `width_m` the lane the
    robot must keep to)."""

    width_m: Annotated[float, Field(gt=0.1, le=3.0)] = 0.60
    lines: Literal["edges", "centre"] = "edges"
    start: PoseSpec = PoseSpec()
    segments: Annotated[list[SegmentSpec], Field(min_length=1, max_length=MAX_SEGMENTS)]
    gaps: Annotated[list[GapSpec], Field(max_length=MAX_GAPS)] = []
    dashes: DashSpec | None = None
    ends: EndsSpec = EndsSpec()

    @property
    def length_m(self) -> float:
        """The centre line's length (every segment), m."""
        return sum(seg.length_m for seg in self.segments)

    @model_validator(mode="after")
    def _length(self) -> LaneSpec:
        total = self.length_m
        if total > MAX_LANE_LENGTH_M:
            raise ValueError(
                f"the segments add up to {total:.6g} m of lane, expected at most "
                f"{MAX_LANE_LENGTH_M:g} m"
            )
        return self


class GradientSpec(_Model):
    """Illumination changing linearly across the floor: +`per_m` (fraction) per metre along
    `direction_deg`, measured from the lane start."""

    per_m: Annotated[float, Field(ge=-1.0, le=1.0)] = 0.0
    direction_deg: Annotated[float, Field(ge=-360.0, le=360.0)] = 0.0


class GlareSpec(_Model):
    """A bright reflection on the floor (a ceiling light): centred `at_m` along the lane,
    `offset_m` to its left, Gaussian with `radius_m` (1 sigma), pushing up to `strength` of
    full white."""

    at_m: Annotated[float, Field(ge=0.0, le=MAX_LANE_LENGTH_M)]
    offset_m: Annotated[float, Field(ge=-MAX_COORDINATE_M, le=MAX_COORDINATE_M)] = 0.0
    radius_m: Annotated[float, Field(gt=0.0, le=3.0)] = 0.25
    strength: Annotated[float, Field(gt=0.0, le=1.5)] = 0.8


class LightChangeSpec(_Model):
    """The room's light changes at `at_s` (a switch, a cloud: over `ramp_s`) to `brightness`
    and `color`; the camera's auto-exposure and white balance follow with their lag."""

    at_s: Annotated[float, Field(ge=0.0, le=600.0)]
    ramp_s: Annotated[float, Field(ge=0.0, le=60.0)] = 0.0
    brightness: Annotated[float, Field(gt=0.01, le=4.0)] = 1.0
    color: Color = "#ffffff"


class CeilingLightsSpec(_Model):
    """Lights in the ceiling, `height_m` above the floor on a grid `spacing_m` (along world x,
    y) shifted by `offset_m`, each `size_m` across. A glossy floor or tape mirrors them: a
    highlight that moves with the camera (it lies where the ray from the camera to the light's
    mirror image meets the floor), rendered per frame (`scenarios.highlights`). `strength`: the
    light's brightness in units of a white floor (a ceiling panel is some 40 times brighter than
    the floor it lights: even 5% of it mirrored saturates the image). `reach_m`: the room's
    size: lights further than this from the camera are not there (a low camera sees the mirror
    images of lights far away: one at distance d appears d h / (h + H) ahead on the floor)."""

    height_m: Annotated[float, Field(gt=0.5, le=20.0)] = 2.6
    spacing_m: tuple[Annotated[float, Field(gt=0.3, le=50.0)],
                     Annotated[float, Field(gt=0.3, le=50.0)]] = (2.4, 1.8)
    offset_m: tuple[Coordinate, Coordinate] = (0.7, 0.4)
    size_m: Annotated[float, Field(gt=0.01, le=3.0)] = 0.4
    strength: Annotated[float, Field(gt=0.0, le=1000.0)] = 40.0
    reach_m: Annotated[float, Field(gt=1.0, le=100.0)] = 20.0


class LightingSpec(_Model):
    """The room's light. `brightness` and `color` light the whole floor (the camera's
    auto-exposure and white balance answer them); `gradient` and `glare` are painted into the
    floor; `changes` change brightness and colour over time; `ceiling` are the lights a glossy
    surface mirrors (None: no ceiling lights)."""

    brightness: Annotated[float, Field(gt=0.01, le=4.0)] = 1.0
    color: Color = "#ffffff"
    gradient: GradientSpec = GradientSpec()
    glare: Annotated[list[GlareSpec], Field(max_length=MAX_GLARE_SPOTS)] = []
    changes: Annotated[list[LightChangeSpec], Field(max_length=MAX_LIGHT_CHANGES)] = []
    ceiling: CeilingLightsSpec | None = CeilingLightsSpec()


class RobotSpec(_Model):
    """Where the robot starts, relative to the lane start: `offset_m` to the left of the centre
    line, heading `heading_deg` from the lane's start direction."""

    offset_m: Annotated[float, Field(ge=-1.0, le=1.0)] = 0.0
    heading_deg: Annotated[float, Field(ge=-90.0, le=90.0)] = 0.0


class RunSpec(_Model):
    """When a run ends: `max_time_s` of simulated time; `halt_settle_s` after the first HALT
    (time for the base to come to rest); once the robot is `stop_past_lane_end_m` past the end
    of the markings; or when it leaves the rendered world."""

    max_time_s: Annotated[float, Field(gt=0.0, le=600.0)] = 90.0
    halt_settle_s: Annotated[float, Field(ge=0.0, le=30.0)] = 1.5
    stop_past_lane_end_m: Annotated[float, Field(gt=0.0, le=MAX_LANE_LENGTH_M)] = 2.0


class SensorSpec(_Model):
    """The image sensor's noise (`scenarios.camera_effects`): shot noise (the photons counted,
    `full_well_e` electrons fill a pixel at gain 1) and read noise (`read_noise_e` electrons),
    both multiplied by the analog gain, so a dark scene that the auto-exposure answers with gain
    is noisier. Defaults: a Pi-class sensor (IMX219 binned to 640x480: about 2.3 grey levels of
    noise at mid-grey at gain 1, about 7 at gain 8)."""

    full_well_e: Annotated[float, Field(ge=200.0, le=200_000.0)] = 6000.0
    read_noise_e: Annotated[float, Field(ge=0.0, le=200.0)] = 3.0


class ExposureSpec(_Model):
    """Exposure (`scenarios.camera_effects`). `auto`: the auto-exposure meters each frame and
    moves the exposure towards `target_level` (the frame's mean, a fraction of full scale) with
    the time constant `time_constant_s` (it lags a change of light), first by the shutter time
    (up to `max_exposure_s`, at most one frame period), then by analog gain (up to `max_gain`);
    it starts settled. Fixed (`auto: false`): `exposure_s` and `gain`. At brightness 1 a 10 ms
    exposure at gain 1 shows the floor as painted. The shutter time also sizes the motion blur."""

    auto: bool = True
    target_level: Annotated[float, Field(gt=0.05, le=0.95)] = 0.5
    time_constant_s: Annotated[float, Field(ge=0.0, le=30.0)] = 0.3
    max_exposure_s: Annotated[float, Field(gt=0.0, le=0.5)] = 0.03
    min_exposure_s: Annotated[float, Field(gt=0.0, le=0.01)] = 0.0001
    max_gain: Annotated[float, Field(ge=1.0, le=64.0)] = 8.0
    exposure_s: Annotated[float, Field(gt=0.0, le=0.5)] = 0.01
    gain: Annotated[float, Field(ge=1.0, le=64.0)] = 1.0


class WhiteBalanceSpec(_Model):
    """Auto white balance (colour frames): channel gains that make the frame's mean grey,
    following a change of the light's colour with `time_constant_s`; it starts settled. Off:
    the light's colour stays in the image."""

    auto: bool = True
    time_constant_s: Annotated[float, Field(ge=0.0, le=30.0)] = 1.0


class OpticsSpec(_Model):
    """The lens beyond its geometry: `vignetting` (fraction of the light lost in the image's
    corners, falling off with the square of the distance from the centre), `blur_mrad` (the
    lens's blur spot, 1 sigma, milliradians of view: pixels = mrad / 1000 * focal length), and
    `chromatic` (lateral chromatic aberration: red magnified by this fraction, blue shrunk by it,
    against green: coloured fringes towards the corners)."""

    vignetting: Annotated[float, Field(ge=0.0, le=0.9)] = 0.25
    blur_mrad: Annotated[float, Field(ge=0.0, le=20.0)] = 1.2
    chromatic: Annotated[float, Field(ge=0.0, le=0.02)] = 0.0015


class CompressionSpec(_Model):
    """What the camera sends: `none` (a CSI camera's raw/YUV frames) or `jpeg` at `quality`
    (1..100; a USB camera's MJPEG stream is one JPEG per frame)."""

    format: Literal["none", "jpeg"] = "none"
    quality: Annotated[int, Field(ge=1, le=100)] = 75


class CameraSpec(_Model):
    """The robot's camera (`camera:`); without the block, the simulator's default camera.

    Mount (robot frame, `perception.ground.CameraPose`): `height_m` above the floor, `pitch_deg`
    down from level, `roll_deg` left side up, `forward_m` ahead of the robot's centre. Lens: an
    ideal pinhole with `hfov_deg` across the image and OpenCV's `distortion` [k1, k2, p1, p2, k3].
    `width_px` x `height_px`: the rendered size; when given it is THE render size of this scenario
    (the config's `simulation.width_px`/`height_px` apply to scenarios that do not give one, and a
    scenario may not give both). Perception gets this camera's true calibration, ground pose
    included, as a calibrated robot would.

    What the camera does to the light beyond geometry (`scenarios.camera_effects`; defaults: a
    Pi-class camera): `sensor` noise, `exposure` (auto, with its lag), `white_balance`,
    `optics` (vignetting, blur, chromatic fringes), `motion_blur` (from the robot's speed and
    turn rate over the shutter time), `rolling_shutter_s` (the time the sensor takes to read its
    rows, top to bottom: a turning robot sees a skewed floor), `compression`.
    """

    height_m: Annotated[float, Field(gt=0.03, le=2.0)] = DEFAULT_POSE_HEIGHT_M
    pitch_deg: Annotated[float, Field(ge=0.0, le=85.0)] = DEFAULT_POSE_PITCH_DEG
    roll_deg: Annotated[float, Field(ge=-30.0, le=30.0)] = 0.0
    hfov_deg: Annotated[float, Field(ge=20.0, le=150.0)] = DEFAULT_HFOV_DEG
    forward_m: Annotated[float, Field(ge=-0.5, le=1.0)] = DEFAULT_POSE_FORWARD_M
    width_px: Annotated[int | None, Field(ge=64, le=1920, multiple_of=2)] = None
    height_px: Annotated[int | None, Field(ge=48, le=1440, multiple_of=2)] = None
    distortion: tuple[float, float, float, float, float] = DEFAULT_DIST_COEFFS
    sensor: SensorSpec = SensorSpec()
    exposure: ExposureSpec = ExposureSpec()
    white_balance: WhiteBalanceSpec = WhiteBalanceSpec()
    optics: OpticsSpec = OpticsSpec()
    motion_blur: bool = True
    rolling_shutter_s: Annotated[float, Field(ge=0.0, le=0.1)] = 0.02
    compression: CompressionSpec = CompressionSpec()

    @model_validator(mode="after")
    def _size_together(self) -> CameraSpec:
        if (self.width_px is None) != (self.height_px is None):
            raise ValueError("give width_px and height_px together (or neither: the config's "
                             "simulation.width_px/height_px)")
        return self


class FaultSpec(_Model):
    """One injected fault: `kind` from `at_s` for `duration_s` (None: to the end of the run); the
    floor hazards (tape_patch, floor_mark, shadow_edge) are placed at lane position `at_m`
    instead and are there for the whole run.

    - camera_freeze: the camera keeps delivering the same image (with fresh indices and times).
    - camera_ring: the camera keeps re-delivering its last `buffers` images in turn (A, B, A,
      B, ...: a driver stuck on its ring of buffers), with fresh indices and times.
    - camera_drop: no new frames at all (the newest one ages).
    - camera_error: reading the camera raises an error.
    - late_frames: frames arrive `latency_s` after capture.
    - frame_from_future: frames carry a capture time `latency_s` AFTER the loop's now.
    - perception_exception: the camera delivers unusable (empty) images; the detector raises.
    - loop_stall: the control process hangs: no control step at all (the base keeps its last
      command), then steps resume.
    - bumper / cliff / wheel_drop: the base reports these bits (`bits`, Kobuki layout).
    - base_link_loss: the base's feedback stops arriving.
    - operator_stop: the operator presses stop (instantaneous).
    - tape_patch: a piece of lane tape `length_m` long on the floor, its centre line starting
      `offset_m` left of the lane centre at `at_m`, turned `angle_deg` from the lane direction
      (0: a second tape beside the lane).
    - floor_mark: a scuff mark or a cable across the floor at `at_m`: a stripe `width_m` wide,
      turned `angle_deg` from straight across, darkened by `intensity` (1: as dark as the tape).
    - shadow_edge: from `at_m` for `length_m` the floor on the `side` of a line `offset_m` left
      of the lane centre is in shadow (light times 1 - 0.7 * `intensity`): a sharp light edge.
    - glare_sweep: a bright reflection (`intensity`: up to that fraction of full white added)
      sweeps across the image from the `side` edge to the other during the fault.
    - occlusion: something in front of the lens hides the `side` tape from the bottom of the image
      up to `intensity` of the image height.
    - lens_smudge: the image is blurred (Gaussian, sigma 0.5 + 6 * `intensity` pixels).
    - exposure_jump: the image is multiplied by 4 ** (2 * `intensity` - 1) (0.25x .. 4x).
    - frame_rate_collapse: the camera delivers only `rate_hz` frames per second.
    - timestamp_jump: the driver's clock jumps: frames are stamped `jump_s` later (or earlier).
    - link_garbage: `intensity` * 64 random bytes arrive between feedback packets on the serial
      link (the real framing parser has to resync).
    - checksum_storm: a fraction `intensity` of the feedback packets arrive with a bad checksum.
    - write_blocks: writing commands to the serial port blocks: the base keeps executing the
      command it had; after `actuation.write_timeout_s` the link counts as lost.
    - low_battery: the battery voltage the base reports drops to `battery_v`.
    """

    kind: FaultKind
    at_s: Annotated[float, Field(ge=0.0, le=600.0)] = 0.0
    duration_s: Annotated[float | None, Field(gt=0.0, le=600.0)] = None
    latency_s: Annotated[float, Field(gt=0.0, le=5.0)] = 0.5
    bits: Annotated[int, Field(ge=1, le=7)] = 2
    at_m: Annotated[float | None, Field(ge=0.0, le=MAX_LANE_LENGTH_M)] = None
    offset_m: Annotated[float, Field(ge=-3.0, le=3.0)] = 0.0
    length_m: Annotated[float, Field(gt=0.0, le=20.0)] = 1.0
    width_m: Annotated[float, Field(gt=0.0, le=0.2)] = 0.01
    angle_deg: Annotated[float, Field(ge=-90.0, le=90.0)] = 0.0
    side: Literal["left", "right"] = "left"
    intensity: Annotated[float, Field(ge=0.0, le=1.0)] = 0.5
    rate_hz: Annotated[float, Field(gt=0.0, le=120.0)] = 5.0
    jump_s: Annotated[float, Field(ge=-10.0, le=10.0)] = -0.5
    battery_v: Annotated[float, Field(ge=0.0, le=20.0)] = 12.0
    buffers: Annotated[int, Field(ge=2, le=16)] = 2

    @model_validator(mode="after")
    def _placed(self) -> FaultSpec:
        on_floor = self.kind in FLOOR_FAULT_KINDS
        if on_floor and self.at_m is None:
            raise ValueError(f"a {self.kind} fault lies on the floor: expected at_m (lane "
                             "position, metres), not a time")
        if not on_floor and self.at_m is not None:
            raise ValueError(f"at_m: a {self.kind} fault happens at a time: expected at_s")
        return self


def _known_names(names: list[str], known: list[str], what: str) -> list[str]:
    """`names`, each of which must be one of `known` (a misspelt event or state otherwise runs
    the whole simulation before the check fails on it)."""
    for name in names:
        if name not in known:
            close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
            hint = f"did you mean {close[0]}? " if close else ""
            raise ValueError(f"{name!r} is no {what}: {hint}expected one of {', '.join(known)}")
    return names


class Expectation(_Model):
    """The outcome a controller must reach on this scenario (None / empty: not checked).
    Event and state names are checked when the file is read; a halt reason may also be given
    by its own words (`not engaged`)."""

    halted: bool | None = None
    #: the halt reason must contain one of these (e.g. LANE_LOST)
    halt_reason_any_of: list[str] = []
    turns_completed: list[str] | None = None
    max_cross_track_error_m: Annotated[float | None, Field(gt=0.0)] = None
    max_distance_past_lane_end_m: float | None = None
    min_distance_past_lane_end_m: float | None = None
    crossed_tape: bool | None = None
    min_distance_travelled_m: Annotated[float | None, Field(ge=0.0)] = None
    max_distance_travelled_m: Annotated[float | None, Field(ge=0.0)] = None
    max_lane_loss_to_halt_s: float | None = None
    states_visited_include: list[str] = []
    states_visited_exclude: list[str] = []
    events_include: list[str] = []
    halted_before_s: Annotated[float | None, Field(gt=0.0)] = None

    @field_validator("halt_reason_any_of")
    @classmethod
    def _halt_reasons(cls, names: list[str]) -> list[str]:
        # an event's name (capitals and underscores) must be a supervisor event
        named = [n for n in names if re.fullmatch(r"[A-Z][A-Z_]*", n)]
        _known_names(named, _event_names(), "supervisor event")
        return names

    @field_validator("events_include")
    @classmethod
    def _events(cls, names: list[str]) -> list[str]:
        return _known_names(names, _event_names(), "supervisor event")

    @field_validator("states_visited_include", "states_visited_exclude")
    @classmethod
    def _states(cls, names: list[str]) -> list[str]:
        from lanewarden.supervisor.state_machine import SupervisorState

        return _known_names(names, [s.value for s in SupervisorState], "supervisor state")

    @model_validator(mode="after")
    def _can_pass(self) -> Expectation:
        """An expectation no run can meet is refused when the file is read: one had run the whole
        scenario (minutes, at max_time_s 600) to fail --check (an attacker's review)."""
        for low, high in (("min_distance_past_lane_end_m", "max_distance_past_lane_end_m"),
                          ("min_distance_travelled_m", "max_distance_travelled_m")):
            a, b = getattr(self, low), getattr(self, high)
            if a is not None and b is not None and a > b:
                raise ValueError(f"{low} {a:g} is more than {high} {b:g}: no run can meet both")
        if self.halted is False and (self.halt_reason_any_of or self.halted_before_s is not None):
            given = "halt_reason_any_of" if self.halt_reason_any_of else "halted_before_s"
            raise ValueError(f"halted: false with {given}: a run that does not halt has no halt "
                             "to check")
        both = sorted(set(self.states_visited_include) & set(self.states_visited_exclude))
        if both:
            raise ValueError(f"states {both} are both in states_visited_include and in "
                             "states_visited_exclude")
        return self


def _event_names() -> list[str]:
    from lanewarden.supervisor.events import Event

    return [e.value for e in Event]


class ExpectSpec(_Model):
    supervised: Expectation | None = None
    lecture: Expectation | None = None


class ScenarioSpec(_Model):
    name: Annotated[str, Field(min_length=1, pattern=r"^[A-Za-z0-9_.-]+$")]
    description: str = ""
    floor: FloorSpec = FloorSpec()
    tape: TapeSpec = TapeSpec()
    lane: LaneSpec
    lighting: LightingSpec = LightingSpec()
    camera: CameraSpec | None = None
    robot: RobotSpec = RobotSpec()
    run: RunSpec = RunSpec()
    faults: Annotated[list[FaultSpec], Field(max_length=MAX_FAULTS)] = []
    config: dict[str, Any] = {}
    expect: ExpectSpec = ExpectSpec()

    @model_validator(mode="after")
    def _turns_are_marked(self) -> ScenarioSpec:
        """Every turn an expectation names is a lane segment's `mark` (one that is not could
        never be completed: the run failed --check after running in full)."""
        marks = {seg.mark for seg in self.lane.segments if seg.mark is not None}
        for controller in ("supervised", "lecture"):
            expected = getattr(self.expect, controller)
            unknown = [t for t in (expected.turns_completed or []) if t not in marks] if (
                expected is not None) else []
            if unknown:
                raise ValueError(f"expect.{controller}.turns_completed: {unknown} are not marks "
                                 f"of the lane's segments ({sorted(marks) or 'none'})")
        return self

    @model_validator(mode="after")
    def _one_render_size(self) -> ScenarioSpec:
        simulation = self.config.get("simulation")
        if self.camera is not None and self.camera.width_px is not None and isinstance(
                simulation, Mapping) and ({"width_px", "height_px"} & set(simulation)):
            raise ValueError(
                "camera.width_px/height_px and config.simulation.width_px/height_px both give "
                "the render size: give it in one place")
        return self


def merge_overrides(base: Mapping[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """`base` with `extra` merged over it, mapping by mapping (a config-file-shaped override)."""
    out = dict(base)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), dict):
            out[key] = merge_overrides(out[key], value)
        else:
            out[key] = value
    return out


def with_overrides(config: ModelT, overrides: Mapping[str, Any], source: str) -> ModelT:
    """`config` (a pydantic model) with a scenario's `config:` block merged over it, validated
    again; a bad key is a ScenarioError naming the file and `config.<key>`."""
    if not overrides:
        return config
    merged = merge_overrides(config.model_dump(), overrides)
    try:
        return type(config).model_validate(merged)
    except ValidationError as exc:
        raise ScenarioError(
            validation_error_lines(source, exc, type(config), prefix=("config",))
        ) from None


def parse_scenario(data: Any, source: str) -> ScenarioSpec:
    """Validate a parsed YAML mapping; each problem is one line of the ScenarioError."""
    if not isinstance(data, dict):
        raise ScenarioError(
            f"{source}: expected a YAML mapping at the top level, got {type(data).__name__}"
        )
    from lanewarden.config import misplaced_document  # (lanewarden.config imports this package)

    if other := misplaced_document(data, "scenario", ScenarioSpec.model_fields):
        raise ScenarioError(f"{source}: {other}")
    try:
        return ScenarioSpec.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(validation_error_lines(source, exc, ScenarioSpec)) from None


def load_scenario_file(path: str | Path) -> ScenarioSpec:
    """Read and validate one scenario YAML file."""
    data = read_yaml_document(path, "scenario", ScenarioError)
    return parse_scenario(data, str(path))
