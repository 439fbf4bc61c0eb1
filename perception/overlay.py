"""The debug overlay: what the detector saw, drawn on a copy of the frame.

Draws the ROI outline, every Hough segment faintly, the tape partners thinly, the chosen edges
bold, and (in `draw_overlay`) a text block with the slope sum, the confidence (with its lowest
component, or "all components 1.00") and the decision. Every colour it uses is a row of
`OVERLAY_STYLES`, which is also the legend a report prints, so a colour cannot be drawn without
being explained. Only for `lanewarden detect --out`, recordings and diagnosis: never called from
the detector's hot path, and it never changes the observation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from lanewarden.perception.detector import DetectionDebug
from lanewarden.perception.observation import LaneObservation, weakest_component

BGR = tuple[int, int, int]


@dataclass(frozen=True)
class OverlayStyle:
    """One colour of a drawing and what it means (the legend's row)."""

    bgr: BGR
    label: str
    meaning: str


#: Every colour the detection overlay draws, in legend order.
OVERLAY_STYLES: dict[str, OverlayStyle] = {
    "left": OverlayStyle((0, 255, 0), "left edge",
                         "the edge perception chose on the left (bold)"),
    "right": OverlayStyle((255, 0, 255), "right edge",
                          "the edge perception chose on the right (bold)"),
    "partner": OverlayStyle((200, 120, 255), "tape partner",
                            "the other side of the same tape (thin): the chosen edge belongs "
                            "to a tape, not to a tile seam"),
    # Deep blue: yellow's (and wood's, and beige's) opposite, so it stands apart from yellow and
    # white tape, grey and brown floors and the other colours here (it was orange-yellow, which
    # a yellow centre line hid in real frames).
    "segment": OverlayStyle((255, 100, 60), "Hough segments",
                            "every line segment Hough found inside the ROI (faint)"),
    "roi": OverlayStyle((255, 200, 0), "ROI",
                        "perception's region of interest (the floor it looks at)"),
}
_TEXT: BGR = (255, 255, 255)
_FONT = cv2.FONT_HERSHEY_SIMPLEX
#: Height of a capital letter of FONT_HERSHEY_SIMPLEX at font scale 1, pixels (measured).
_CAP_HEIGHT_AT_SCALE_1 = 20.0


def text_scale(cap_height_px: float) -> float:
    """The font scale whose capital letters are `cap_height_px` tall."""
    return cap_height_px / _CAP_HEIGHT_AT_SCALE_1


def line_step_px(cap_height_px: float) -> int:
    """Baseline-to-baseline distance of a text block whose capitals are `cap_height_px` tall."""
    return round(cap_height_px * 1.7)


def put_text_lines(
    image: np.ndarray,
    lines: Sequence[str | tuple[str, BGR]],
    origin: tuple[int, int],
    cap_height_px: float,
    *,
    shade: bool = True,
) -> None:
    """Write lines of text, the first baseline at `origin`, in place.

    A line is a string (white) or (text, BGR colour). With `shade` the band behind the text is
    darkened first so the text reads on any background. One text pass per line: OpenCV's glyph
    advance depends on the thickness, so an outline pass would not line up.
    """
    x, y = origin
    step = line_step_px(cap_height_px)
    scale = text_scale(cap_height_px)
    thickness = 1 if cap_height_px < 14 else 2
    if shade and lines:
        top = max(0, y - step + 2)
        bottom = min(image.shape[0], y + step * (len(lines) - 1) + round(cap_height_px * 0.6))
        band = image[top:bottom]
        cv2.addWeighted(band, 0.35, np.zeros_like(band), 0.65, 0.0, dst=band)
    for line in lines:
        text, colour = (line, _TEXT) if isinstance(line, str) else line
        cv2.putText(image, text, (x, y), _FONT, scale, colour, thickness, cv2.LINE_AA)
        y += step


def draw_detection(canvas: np.ndarray, observation: LaneObservation,
                   debug: DetectionDebug) -> None:
    """Draw the ROI, the Hough segments, the tape partners and the chosen edges onto `canvas`
    (BGR uint8, the analysed image's size), in place."""
    height = canvas.shape[0]
    scale = max(1, round(height / 240))
    styles = OVERLAY_STYLES
    cv2.polylines(canvas, [debug.roi_polygon_px], True, styles["roi"].bgr, scale, cv2.LINE_AA)
    faint = canvas.copy()
    for x1, y1, x2, y2 in debug.segments:
        cv2.line(faint, (int(x1), int(y1)), (int(x2), int(y2)), styles["segment"].bgr, 1,
                 cv2.LINE_AA)
    cv2.addWeighted(faint, 0.55, canvas, 0.45, 0.0, dst=canvas)

    lines = debug.lines
    for choice in (debug.left, debug.right):
        if choice is not None and choice.partner is not None:
            k = choice.partner
            cv2.line(
                canvas,
                (round(lines.near_x[k]), round(lines.near_y[k])),
                (round(lines.far_x[k]), round(lines.far_y[k])),
                styles["partner"].bgr,
                scale,
                cv2.LINE_AA,
            )
    for edge, style in ((observation.left, styles["left"]), (observation.right, styles["right"])):
        if edge is not None:
            cv2.line(
                canvas,
                (round(edge.x1), round(edge.y1)),
                (round(edge.x2), round(edge.y2)),
                style.bgr,
                2 * scale + 1,
                cv2.LINE_AA,
            )


def confidence_text(observation: LaneObservation) -> str:
    """'confidence 0.77 (lowest tape_pair_left 0.60)': the component that held it down most;
    with none below 1, 'confidence 1.00 (all components 1.00)' (naming one as the lowest said
    something untrue); without components, the confidence alone."""
    text = f"confidence {observation.confidence:.2f}"
    weakest = weakest_component(observation.components)
    if weakest is not None:
        return f"{text} (lowest {weakest[0]} {weakest[1]:.2f})"
    return f"{text} (all components 1.00)" if observation.components else text


def perception_text(observation: LaneObservation, decision: str) -> list[str]:
    """What perception says about one frame, in words (slope sum, confidence, decision)."""
    slope = "--" if observation.slope_sum is None else f"{observation.slope_sum:+.2f}"
    return [
        f"slope sum {slope}",
        confidence_text(observation),
        f"decision {decision}",
    ]


def as_bgr(image: np.ndarray) -> np.ndarray:
    """A BGR uint8 copy of a gray, BGR or BGRA image."""
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    if image.shape[2] == 1:
        return cv2.cvtColor(image[:, :, 0], cv2.COLOR_GRAY2BGR)
    return image.copy()


def enlarged(canvas: np.ndarray, min_rows: int) -> np.ndarray:
    """`canvas` enlarged by the smallest whole factor that gives it at least `min_rows` rows
    (nearest neighbour: each pixel a block, nothing smoothed away), or itself."""
    if canvas.shape[0] >= min_rows:
        return canvas
    scale = math.ceil(min_rows / canvas.shape[0])
    return cv2.resize(canvas, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)


def draw_overlay(
    image: np.ndarray, observation: LaneObservation, debug: DetectionDebug, decision: str,
    min_rows: int = 0,
) -> np.ndarray:
    """A BGR uint8 copy of `image` (the frame the detector analysed, i.e. after undistortion;
    gray or BGR, same size) with the detection and perception's text drawn on it; enlarged
    first to at least `min_rows` rows (`enlarged`), so that the text fits a small frame's
    width (`detect --out` of a 224x224 frame had cut 'confidence 0.00 (lowest lane_width 0.'
    off at its right edge)."""
    canvas = as_bgr(image)
    draw_detection(canvas, observation, debug)
    canvas = enlarged(canvas, min_rows)
    # Capitals 1/30 of the height (16 px at 480 rows), never below 9 px.
    cap = max(9.0, canvas.shape[0] / 30.0)
    put_text_lines(canvas, overlay_text(observation, debug, decision),
                   (round(cap / 2), line_step_px(cap)), cap)
    return canvas


def overlay_text(observation: LaneObservation, debug: DetectionDebug, decision: str) -> list[str]:
    """The overlay's words: `perception_text`, and where Canny's thresholds were raised to keep a
    textured floor's edges within the edge budget (`perception.canny.max_edge_share`), by how
    much: 'Canny x1.44 (textured floor)'."""
    lines = perception_text(observation, decision)
    if debug.edge_threshold_factor > 1.0:
        lines.append(f"Canny x{debug.edge_threshold_factor:.2f} (textured floor)")
    return lines
