"""Perception's floor geometry in metres: the tape, the lane and the region of interest.

These keys describe the world (what the tape and the lane are, which floor to look at), never the
image: the detector turns them into pixels through the camera's ground model
(`perception.ground.GroundModel`) once per image size, so one config holds for any camera.
Lengths are metres on the floor, in the robot frame (REP 103: x forward, y left, origin under the
robot's centre). Pixel knobs that describe the image processing (blur, Canny, Hough, sampling)
stay in `perception.config`.

This module only declares and validates numbers: it never touches images or a ground model.
"""

from __future__ import annotations

import functools
from typing import Annotated, Literal, Self

from pydantic import ConfigDict, Field, model_validator

from lanewarden.documents import DocumentModel

_FROZEN = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

Fraction = Annotated[float, Field(ge=0.0, le=1.0)]
PositiveFraction = Annotated[float, Field(gt=0.0, le=1.0)]


class RoiConfig(DocumentModel):
    """The region of interest: a rectangle of floor in the robot frame, projected into the image.

    It spans `near_m` to `far_m` ahead of the robot's centre and `lateral_m` to either side; the
    image border and the horizon clip it. Default: from wherever the image starts to 1.6 m ahead,
    wide enough for a 0.8 m lane seen with the robot off-centre or turned by 15 deg, and nothing
    beyond (walls and clutter beside the lane stay out).
    """

    model_config = _FROZEN

    near_m: Annotated[float, Field(ge=0.0, le=10.0)] = Field(
        default=0.0,
        description=(
            "nearest floor the ROI covers, metres ahead of the robot's centre (the image bottom "
            "usually clips it)"
        ),
    )
    far_m: Annotated[float, Field(gt=0.0, le=20.0)] = Field(
        default=1.6,
        description="farthest floor the ROI covers, metres ahead of the robot's centre",
    )
    lateral_m: Annotated[float, Field(gt=0.0, le=10.0)] = Field(
        default=0.65,
        description="the ROI spans this far to each side of the robot's centre line, metres",
    )

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if not self.near_m < self.far_m:
            raise ValueError(
                f"near_m ({self.near_m:g}) must be below far_m ({self.far_m:g})"
            )
        return self


class TapeConfig(DocumentModel):
    """The tape, and how a tape is told from a floor seam: by its width on the floor, in metres.

    A candidate tape is two nearly parallel edges of opposite polarity with a uniform band between
    them. Both edges are projected onto the floor through the ground model and the distance
    between them is compared with two hypotheses (`perception.tape_rules.tape_width_score`):
    - seam: at most `max_seam_width_m` (grout, joints, cracks), or as thin as the image can show
      (`min_gap_px`: blur keeps the two sides of any thin line a few pixels apart);
    - tape: `width_m`, give or take `width_tolerance_fraction` (wear, calibration error);
    both widened by `width_error_px` pixels of measurement error at the measured spot. The score
    is 0 up to the widest seam, 1 from the narrowest tape, linear between: if the two overlap
    where the camera measures, nothing there passes as tape. At start-up the detector refuses a
    camera that cannot separate them at the look-ahead distance (and says which distance would).

    - `pair_angle_tol_deg`: the two edges of one tape converge slightly in the image; at most
      this apart.
    - `polarity_offset_frac_of_width`, `polarity_samples`, `min_contrast_levels`: how the
      brightness either side of a line is sampled (a pixel knob: a few pixels beside the line).
    - `min_band_fraction`: at least this fraction of the points sampled along a tape candidate
      must show a uniform band darker (or lighter) than the floor outside both edges (dashed
      tape passes with its gaps).
    - `min_profile_fraction`: an edge without a Hough partner counts as a tape edge (not a
      verified tape) when the brightness across it shows a band `width_m` wide on its outer side
      along at least this fraction of its length.
    - `unpaired_preference`: value factor of a lone line refuted as a tape edge when choosing.
    - `unverifiable_score`: tape score of an edge whose tape's far side lies outside the image.
      Such an edge never makes a lane confident on its own (see the `verified_tape` component).
    - `left_width_m` / `right_width_m`: the left and the right tape's widths when they differ
      (a 25 mm dashed centre line on the left, a 48 mm edge line on the right); each defaults to
      `width_m`. `for_side(side)` is this config as one side's rules see it.
    """

    model_config = _FROZEN

    width_m: Annotated[float, Field(ge=0.005, le=0.2)] = Field(
        default=0.048,
        description="the tape's width on the floor, metres (both sides unless overridden)",
    )
    left_width_m: Annotated[float | None, Field(ge=0.005, le=0.2)] = Field(
        default=None,
        description=(
            "the left tape's width on the floor when it differs (a dashed centre line), metres; "
            "null: width_m"
        ),
    )
    right_width_m: Annotated[float | None, Field(ge=0.005, le=0.2)] = Field(
        default=None,
        description="the right tape's width on the floor when it differs, metres; null: width_m",
    )
    max_seam_width_m: Annotated[float | None, Field(gt=0.0, le=0.2)] = Field(
        default=None,
        description=(
            "widest floor seam (grout, joint, crack) that must never pass as tape, metres; null: "
            "half of the narrower tape"
        ),
    )
    width_tolerance_fraction: Annotated[float, Field(ge=0.0, le=0.5)] = Field(
        default=0.15,
        description=(
            "a tape's measured width may differ from width_m by this fraction (wear, calibration "
            "error), on top of width_error_px"
        ),
    )
    width_error_px: Annotated[float, Field(ge=0.0, le=5.0)] = Field(
        default=1.0,
        description=(
            "measurement error of a width between two detected edges, pixels (edge "
            "localisation); converted to metres where each width is measured"
        ),
    )
    min_gap_px: Annotated[float, Field(ge=0.0, le=20.0)] = Field(
        default=5.0,
        description=(
            "two edges closer than this (pixels, where measured) may be the two sides of one "
            "thin line: a seam's measured width is at least this many pixels"
        ),
    )
    pair_angle_tol_deg: Annotated[float, Field(gt=0.0, le=30.0)] = Field(
        default=10.0,
        description="max angle between the two edges of one tape in the image",
    )
    polarity_offset_frac_of_width: PositiveFraction = Field(
        default=0.006,
        description=(
            "how far either side of a line brightness is sampled for its polarity, fraction of "
            "image width (at least 1.5 px)"
        ),
    )
    polarity_samples: Annotated[int, Field(ge=1, le=64)] = Field(
        default=6,
        description="points sampled along a line (tape band and profile; polarity: three times "
        "as many)",
    )
    min_contrast_levels: Annotated[float, Field(ge=0.0, le=255.0)] = Field(
        default=8.0,
        description=(
            "smallest brightness difference that counts (polarity, tape band and profile), grey "
            "levels"
        ),
    )
    min_band_fraction: PositiveFraction = Field(
        default=0.3,
        description=(
            "share of samples along a tape pair whose band must look like tape (uniform, darker "
            "or lighter than the floor on both sides)"
        ),
    )
    min_profile_fraction: PositiveFraction = Field(
        default=0.6,
        description=(
            "share of samples along an unpaired edge whose brightness profile must show a tape on "
            "its outer side"
        ),
    )
    unpaired_preference: Fraction = Field(
        default=0.1,
        description=(
            "value factor of a lone line refuted as a tape edge, against a tape (edge choice)"
        ),
    )
    kind: Literal["any", "dark", "light"] = Field(
        default="any",
        description=(
            "the lane's tapes: dark (darker than the floor, black tape on a light floor), light "
            "(lighter than the floor), or any: with dark or light, a band of the other kind "
            "(a light floor strip, a light slat between darker ones) is never a tape"
        ),
    )
    unverifiable_score: Fraction = Field(
        default=0.6,
        description=(
            "tape score of an edge whose tape's far side lies outside the image (cannot be "
            "checked) and that steps at least half as strongly as the other side's verified "
            "tape (else 0); never enough for a confident lane on its own"
        ),
    )

    def side_width_m(self, side: Literal["left", "right"]) -> float:
        """One side's tape width, metres (`left_width_m` / `right_width_m`, else `width_m`)."""
        width = self.left_width_m if side == "left" else self.right_width_m
        return self.width_m if width is None else width

    @property
    def narrowest_width_m(self) -> float:
        """The narrower of the two tapes, metres."""
        return min(self.side_width_m("left"), self.side_width_m("right"))

    @property
    def widest_width_m(self) -> float:
        """The wider of the two tapes, metres."""
        return max(self.side_width_m("left"), self.side_width_m("right"))

    @property
    def mean_width_m(self) -> float:
        """The mean of the two tapes' widths, metres: what a lane's width, centre to centre,
        loses between the tapes' inner edges."""
        return 0.5 * (self.side_width_m("left") + self.side_width_m("right"))

    @property
    def seam_width_m(self) -> float:
        """The widest seam to reject, metres (`max_seam_width_m`, default half the narrower
        tape)."""
        if self.max_seam_width_m is None:
            return self.narrowest_width_m / 2.0
        return self.max_seam_width_m

    def for_side(self, side: Literal["left", "right"]) -> TapeConfig:
        """This config as one side's rules see it: `width_m` that side's tape, the seam fixed
        (one floor, one widest seam for both sides). Made once per config and side (a cache
        outside the model: a cached value in the model's own `__dict__` would take part in its
        equality, and `self` in it made comparisons recurse without end)."""
        if self.left_width_m is None and self.right_width_m is None:
            return self
        return _side_config(self, side)

    @model_validator(mode="after")
    def _seam_below_tape(self) -> Self:
        narrowest_tape = self.narrowest_width_m * (1.0 - self.width_tolerance_fraction)
        if not self.seam_width_m < narrowest_tape:
            which = ("width_m" if self.left_width_m is None and self.right_width_m is None
                     else "the narrower tape")
            raise ValueError(
                f"max_seam_width_m ({self.seam_width_m:g}) must be below the narrowest tape, "
                f"{which} x (1 - width_tolerance_fraction) = {narrowest_tape:g} m: a seam that "
                "wide cannot be told from the tape"
            )
        return self


class LaneConfig(DocumentModel):
    """The lane: two tapes `width_m` apart (centre to centre) on a flat floor.

    - `width_tolerance_fraction`: the `lane_width` component scores 1 while the distance between
      the two reported (inner) edges on the floor is within this fraction of `width_m` of the
      free width between the tapes (`width_m` less half of each tape), 0 at twice. Relative to
      the lane, so a narrow lane is judged as strictly as a wide one; the config refuses a lane
      so narrow that one tape's own two edges would score (`perception.config`). Pairs of tapes
      are also chosen by it.
    - `parallel_tolerance_deg`: the `parallel` component scores 1 while the two edges' directions
      on the floor differ by at most this, 0 at twice (lane edges are parallel; random lines
      are not).
    - `max_heading_deg`: the `heading` component (a full gate) is 0 when the lane runs more than
      this from the robot's heading: a lane seen across the view is not one to steer along.
    - `dashed_side`: the side whose line is dashed (a road's centre line), `both` (a lane of
      two dashed lines), or None. While that line's dashes are out of sight (a gap, a corner
      turning them out of the view) and the other side is a verified tape where a lane seen just
      before had it, the missing edge is reported where the lane's width puts it
      (`perception.one_side`): never confident, and the supervisor degrades on it. A solid line
      out of sight is never bridged (it may have ended).
    """

    model_config = _FROZEN

    width_m: Annotated[float, Field(gt=0.1, le=3.0)] = Field(
        default=0.60,
        description="distance between the two tapes' centre lines, metres",
    )
    width_tolerance_fraction: Annotated[float, Field(gt=0.0, le=0.4)] = Field(
        default=0.15,
        description=(
            "lane_width scores 1 while the measured free width is within this fraction of "
            "width_m of the expected one, 0 at twice it"
        ),
    )

    @property
    def width_tolerance_m(self) -> float:
        """The `lane_width` tolerance in metres (`width_tolerance_fraction` of `width_m`)."""
        return self.width_tolerance_fraction * self.width_m
    parallel_tolerance_deg: Annotated[float, Field(gt=0.0, le=45.0)] = Field(
        default=12.0,
        description=(
            "parallel scores 1 while the two edges' directions on the floor differ by at most "
            "this, 0 at twice it, degrees"
        ),
    )
    max_heading_deg: Annotated[float, Field(gt=0.0, le=90.0)] = Field(
        default=45.0,
        description=(
            "no lane (confidence 0) when the lane runs more than this from the robot's heading, "
            "degrees"
        ),
    )
    dashed_side: Literal["left", "right", "both"] | None = Field(
        default=None,
        description=(
            "the side whose line is dashed (a centre line), both (two dashed lines), or null: "
            "while its dashes are out of sight and the other tape is verified where the lane "
            "just was, the missing edge is placed the lane's width away (one side seen: never "
            "confident, the supervisor degrades); a solid line out of sight is never bridged"
        ),
    )


@functools.lru_cache(maxsize=64)
def _side_config(tape: TapeConfig, side: Literal["left", "right"]) -> TapeConfig:
    """`tape` with `width_m` set to `side`'s tape (TapeConfig is frozen, so hashable)."""
    return tape.model_copy(update={
        "width_m": tape.side_width_m(side), "left_width_m": None, "right_width_m": None,
        "max_seam_width_m": tape.seam_width_m})
