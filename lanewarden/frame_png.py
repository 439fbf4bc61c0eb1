"""A lossless PNG of one gray camera frame, cheap enough to record 30 frames a second on a Pi.

The recording stores each frame as perception consumes it (by default the prepared image of
`perception.detector.LaneDetector.prepare`, 8-bit gray; or the camera's gray frame,
`perception_gray`) in a standard PNG that any viewer decodes (Foxglove and
Lichtblick show it, OpenCV reads it back bit for bit). What makes it cheap is the choice of the
two steps a PNG writer takes, not a new format:

- the filter, one for every row, computed with one numpy subtraction: SUB (each byte minus its
  left neighbour) for a camera's gray frame, UP (minus the byte above) for perception's prepared
  image (blurred: UP leaves 5-10 % less than SUB there, while SUB leaves 5 % less than UP on
  the unblurred frame; AVG and PAETH gain at most 2 % more, and PAETH takes three times the
  CPU in numpy). On a
  camera frame a filter turns smooth gradients and sensor noise into small residuals, which is
  most of what any PNG filter can gain here;
- the deflate: ISA-L (python-isal) at level 1 instead of zlib. libpng with zlib at its cheapest
  setting (OpenCV's IMWRITE_PNG_COMPRESSION 1) spends three to four times the CPU on a 640x480
  gray frame, for a file about 5 % larger (benchmarks/recording_cost.py).

The container is PNG's own: signature, IHDR (8-bit gray), one IDAT, IEND, each chunk with its
CRC-32. Pure bytes in, bytes out: no file, no thread, no clock.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
from isal import isal_zlib

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: ISA-L's level 1: its fastest level that still matches strings (level 0 is Huffman only and
#: about 45 % larger on camera frames).
DEFLATE_LEVEL = 1
#: PNG filter types (PNG specification, 9.2).
FILTER_SUB = 1
FILTER_UP = 2
_COLOR_GRAY = 0


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(
        ">I", zlib.crc32(body, zlib.crc32(kind)))


def gray_png(image: np.ndarray, png_filter: int = FILTER_SUB) -> bytes:
    """The PNG file of an HxW uint8 image (8-bit gray, no interlace), lossless; every row
    filtered with `png_filter` (FILTER_SUB or FILTER_UP)."""
    if image.ndim != 2 or image.dtype != np.uint8 or image.size == 0:
        raise ValueError(f"gray_png: expected an HxW uint8 image, got {image.dtype} "
                         f"{image.shape}")
    height, width = image.shape
    rows = np.empty((height, width + 1), np.uint8)
    rows[:, 0] = png_filter
    if png_filter == FILTER_SUB:
        rows[:, 1] = image[:, 0]
        np.subtract(image[:, 1:], image[:, :-1], out=rows[:, 2:])  # modulo 256, as PNG wants
    elif png_filter == FILTER_UP:
        rows[0, 1:] = image[0]
        np.subtract(image[1:], image[:-1], out=rows[1:, 1:])
    else:
        raise ValueError(f"gray_png: png_filter = {png_filter}: expected {FILTER_SUB} (SUB) or "
                         f"{FILTER_UP} (UP)")
    header = struct.pack(">IIBBBBB", width, height, 8, _COLOR_GRAY, 0, 0, 0)
    return b"".join((PNG_SIGNATURE, _chunk(b"IHDR", header),
                     _chunk(b"IDAT", isal_zlib.compress(rows, DEFLATE_LEVEL)),
                     _chunk(b"IEND", b"")))
