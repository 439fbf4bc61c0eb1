"""The debug overlay: what the detector saw, drawn on a copy of the frame.

Draws the ROI outline, every Hough segment faintly, the tape partners thinly, the chosen edges
bold, and a text block with the slope sum, the confidence (with its lowest component) and the
decision. Only for `lanewarden detect --out`, recordings and diagnosis: never called from the
detector's hot path, and it never changes the observation.
"""

from __future__ import annotations

import cv2
import numpy as np

from lanewarden.perception.detector import DetectionDebug
from lanewarden.perception.observation import LaneObservation

_ROI = (255, 200, 0)
_SEGMENT = (0, 200, 255)
_PARTNER = (200, 120, 255)
_LEFT = (0, 255, 0)
_RIGHT = (255, 0, 255)
_TEXT = (255, 255, 255)


def draw_overlay(
    image: np.ndarray, observation: LaneObservation, debug: DetectionDebug, decision: str
) -> np.ndarray:
    """A BGR uint8 copy of `image` (the frame the detector analysed, i.e. after undistortion;
    gray or BGR, same size) with the detection drawn on it."""
    if image.ndim == 2:
        canvas = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    elif image.shape[2] == 4:
        canvas = cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    elif image.shape[2] == 1:
        canvas = cv2.cvtColor(image[:, :, 0], cv2.COLOR_GRAY2BGR)
    else:
        canvas = image.copy()
    height, width = canvas.shape[:2]
    scale = max(1, round(height / 240))

    cv2.polylines(canvas, [debug.roi_polygon_px], True, _ROI, 1, cv2.LINE_AA)
    faint = canvas.copy()
    for x1, y1, x2, y2 in debug.segments:
        cv2.line(faint, (int(x1), int(y1)), (int(x2), int(y2)), _SEGMENT, 1, cv2.LINE_AA)
    cv2.addWeighted(faint, 0.55, canvas, 0.45, 0.0, dst=canvas)

    lines = debug.lines
    for choice in (debug.left, debug.right):
        if choice is not None and choice.partner is not None:
            k = choice.partner
            cv2.line(
                canvas,
                (round(lines.near_x[k]), round(lines.near_y[k])),
                (round(lines.far_x[k]), round(lines.far_y[k])),
                _PARTNER,
                scale,
                cv2.LINE_AA,
            )
    for edge, colour in ((observation.left, _LEFT), (observation.right, _RIGHT)):
        if edge is not None:
            cv2.line(
                canvas,
                (round(edge.x1), round(edge.y1)),
                (round(edge.x2), round(edge.y2)),
                colour,
                2 * scale + 1,
                cv2.LINE_AA,
            )

    slope = "--" if observation.slope_sum is None else f"{observation.slope_sum:+.2f}"
    lowest = min(observation.components.items(), key=lambda kv: kv[1], default=None)
    low_text = "" if lowest is None else f" (lowest {lowest[0]} {lowest[1]:.2f})"
    text = [
        f"slope sum {slope}",
        f"confidence {observation.confidence:.2f}{low_text}",
        f"decision {decision}",
    ]
    font_scale = max(0.28, height / 900)
    thickness = 1 if height < 400 else 2
    line_height = round(30 * font_scale) + 2
    for i, line in enumerate(text):
        origin = (3, line_height * (i + 1))
        cv2.putText(canvas, line, origin, cv2.FONT_HERSHEY_SIMPLEX, font_scale, (0, 0, 0),
                    thickness + 2, cv2.LINE_AA)
        cv2.putText(canvas, line, origin, cv2.FONT_HERSHEY_SIMPLEX, font_scale, _TEXT, thickness,
                    cv2.LINE_AA)
    return canvas
