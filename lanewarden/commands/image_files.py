"""Image files named on the command line: decoding one, expanding a glob or a folder.

File I/O only; a file that cannot be used is reported as a reason string for the caller's
one-line error, never as a traceback.
"""

from __future__ import annotations

import glob
from pathlib import Path

import cv2
import numpy as np

IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm"}


def read_image(path: Path, flags: int = cv2.IMREAD_COLOR) -> tuple[np.ndarray | None, str]:
    """Decode an image file: (image, "") or (None, why it cannot be used)."""
    try:
        data = np.fromfile(str(path), dtype=np.uint8)
    except OSError as exc:
        return None, f"cannot read file ({exc.strerror or exc})"
    if data.size == 0:
        return None, "empty file, not an image"
    try:
        image = cv2.imdecode(data, flags)
    except cv2.error:
        image = None
    if image is None or image.size == 0:
        return None, "not a readable image"
    return image, ""


def expand_images(pattern: str) -> list[Path]:
    """Files matching a glob (or every file in a folder), sorted; folders are skipped."""
    base = Path(pattern).expanduser()
    if base.is_dir():
        candidates = [p for p in base.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES]
    else:
        candidates = [Path(p) for p in glob.glob(str(base), recursive=True)]
    return sorted(p for p in candidates if not p.is_dir())
