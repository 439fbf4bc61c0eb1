"""Reading image files for the CLI (`detect`, `undistort`, `calibrate`), with a pixel limit checked
before decoding: a small file can decode to gigabytes (a 1 MB PNG of 20000x20000 pixels does).

The size is read from the file's header with Pillow (it parses only the header on open; PNG, JPEG,
BMP, TIFF, WebP, PNM, ...); OpenCV then decodes. A format Pillow does not know is not decoded
(OpenCV would decode Radiance HDR, whose size only its decoder reads). Returns the reason an
image cannot be used rather than raising, so a command can report every bad file in one line.
Never prints. `write_image` writes one (`detect --out`, `sim --camera-out`, `calibrate capture`).
"""

from __future__ import annotations

import glob
import io
import re
import stat
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import IO

import cv2
import numpy as np
from PIL import Image, UnidentifiedImageError

from lanewarden.documents import NOT_A_REGULAR_FILE, dangling_link, is_special_file
from lanewarden.output_files import replace_file
from lanewarden.perception.config import PerceptionConfig

#: File name endings read as images (a folder or glob of frames, a survey's class folders).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm")
#: Files named as videos: a photo command given one says which commands read videos.
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".h264")
#: What a photo command adds when it was given a video (`read_image`).
VIDEO_HINT = ("a video: `lanewarden replay` and `lanewarden survey --labels FILE` read videos, "
              "`lanewarden run --camera` plays one")

#: The config key of the limit, named in the messages.
LIMIT_KEY = "perception.max_image_pixels"


def too_many_pixels(width: int, height: int, max_pixels: int) -> str:
    """'' when a width x height image is within `max_pixels`, else why it is refused."""
    if width * height <= max_pixels:
        return ""
    return (f"image is {width}x{height} = {width * height} pixels, more than "
            f"{LIMIT_KEY} ({max_pixels})")


def _opened_size(path: Path | IO[bytes]) -> tuple[int, int] | None:
    """(width, height) from the file's header, without decoding; None when Pillow cannot tell
    (a format it does not read, a damaged header). Raises Pillow's DecompressionBombError."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as image:
                return int(image.size[0]), int(image.size[1])
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError):
        return None


def header_facts(path: Path | IO[bytes], max_pixels: int) -> tuple[tuple[int, int] | None, str]:
    """From one read of the image file's header, without decoding it: its (width, height) or
    None when Pillow cannot tell, and why it is too large ('' when within the limit or unknown:
    `decode_image` then refuses it) or, never opened, a FIFO or device (opening a FIFO waits
    for a writer)."""
    if isinstance(path, Path) and is_special_file(path):
        return None, NOT_A_REGULAR_FILE
    try:
        size = _opened_size(path)
    except Image.DecompressionBombError as exc:
        # Pillow's own limit, far above the largest max_image_pixels allowed; its message
        # ("Image size (10000000000 pixels) exceeds limit of ...") has the count, not the sides
        count = re.search(r"\((\d+) pixels\)", str(exc))
        pixels = f"{count.group(1)} pixels" if count else "more pixels than Pillow opens"
        return None, f"image has {pixels}, more than {LIMIT_KEY} ({max_pixels})"
    return size, "" if size is None else too_many_pixels(size[0], size[1], max_pixels)


def header_problem(path: Path | IO[bytes], max_pixels: int) -> str:
    """Why the image file (a path, or an open binary file such as `io.BytesIO(data)`) is too
    large, judged from its header without decoding it; '' when it is within the limit or its
    format is not one Pillow reads (`decode_image` then refuses it)."""
    return header_facts(path, max_pixels)[1]


#: The pixel limit when a command has no config to take `perception.max_image_pixels` from: its
#: default.
DEFAULT_MAX_PIXELS: int = PerceptionConfig.model_fields["max_image_pixels"].default
#: An image file may hold at most this many bytes per allowed pixel (plus a megabyte of
#: headers and metadata): an uncompressed 4-channel 16-bit frame is 8; more is not an image
#: within the limit, whatever its header says (a sparse file of gigabytes behind a 1x1 header).
MAX_BYTES_PER_PIXEL = 8


def file_problem(path: Path) -> str:
    """Why `path` is not a file that can be read whole without waiting ('' when it is one):
    missing, a folder, a FIFO or a device (reading those waits for a writer or never ends)."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:  # (a link to nothing says so: a new user read 'no such file'
        return dangling_link(path) or "no such file"  # of a photo they could see listed)
    except OSError as exc:
        return f"cannot read file ({exc.strerror or exc})"
    if stat.S_ISDIR(mode):
        return "is a folder, not an image file"
    if not stat.S_ISREG(mode):
        return NOT_A_REGULAR_FILE
    return ""


def write_image(path: Path, image: np.ndarray, params: Sequence[int] = ()) -> None:
    """Write `image` to `path` in the format its suffix names (OpenCV's encoder, `params` as
    cv2.imwrite takes them). Raises OSError with the reason: cv2.imwrite answers a full disk
    with False alone, and libpng prints "libpng error: Write Error" on the terminal beside the
    command's one line. Encoded in memory, written by Python: the OSError's `strerror` says
    why ("No space left on device"). Never written through what is at `path`
    (`output_files.replace_file`: a link there is replaced, a FIFO or device refused)."""
    ok, data = cv2.imencode(path.suffix, image, list(params))
    if not ok:
        raise OSError(f"OpenCV cannot encode a {image.dtype} {image.shape} image as "
                      f"{path.suffix or 'a file without a suffix'}")
    replace_file(path, data.data)


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_damage(data: bytes | np.ndarray) -> str:
    """Why PNG `data` is cut short or damaged (a chunk's CRC), '' when whole or not a PNG.
    Pillow walks the chunks without decoding; OpenCV's libpng would print its own 'libpng
    error: ...' line on stderr for such a file, beside the command's one line."""
    raw = data.tobytes() if isinstance(data, np.ndarray) else data
    if not raw.startswith(PNG_SIGNATURE):
        return ""
    try:
        with Image.open(io.BytesIO(raw)) as image:
            image.verify()
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        return f"a cut-off or damaged PNG ({str(exc)[:80] or type(exc).__name__})"
    return ""


def read_image(
    path: Path, flags: int = cv2.IMREAD_COLOR, max_pixels: int = DEFAULT_MAX_PIXELS
) -> tuple[np.ndarray | None, str]:
    """Decode an image file: (image, "") or (None, why it cannot be used). An image with more
    than `max_pixels` pixels is refused, from its header before decoding (`decode_image`); so
    is a file larger than any image within the limit, before it is read, and anything but a
    regular file. A file named as a video that is refused says which commands read videos
    (`VIDEO_HINT`: a new user's `detect tub.mp4` got "not a readable image" alone)."""
    image, why = _read_image(path, flags, max_pixels)
    if image is None and path.suffix.lower() in VIDEO_SUFFIXES:
        why = f"{why} ({VIDEO_HINT})"
    return image, why


def _read_image(path: Path, flags: int, max_pixels: int) -> tuple[np.ndarray | None, str]:
    if why := file_problem(path):
        return None, why
    if why := header_problem(path, max_pixels):
        return None, why
    limit = MAX_BYTES_PER_PIXEL * max_pixels + (1 << 20)
    try:
        with path.open("rb") as stream:
            data = stream.read(limit + 1)
    except OSError as exc:
        return None, f"cannot read file ({exc.strerror or exc})"
    if len(data) > limit:
        return None, (f"file is larger than {limit} bytes, more than any image within "
                      f"{LIMIT_KEY} ({max_pixels}) holds")
    return decode_image(data, flags, max_pixels)


def decode_image(data: bytes, flags: int, max_pixels: int) -> tuple[np.ndarray | None, str]:
    """Decode an encoded image (a file's bytes): (image, "") or (None, why not). Its size is
    read from its header first (Pillow), and what Pillow cannot size is not decoded, garbage or
    a format it does not know: OpenCV decodes a few of those, and a Radiance HDR file of 9 MB
    had decoded to 1.7 GB of floats before its size could be checked."""
    if not data:
        return None, "empty file, not an image"
    if png_damage(data):
        return None, "not a readable image"
    size, why = header_facts(io.BytesIO(data), max_pixels)
    if why:
        return None, why
    if size is None:
        return None, "not a readable image"
    if why := jpeg_scans_problem(data):
        return None, why
    # OpenCV's own log line for what it cannot decode (a PPM cut short: "[ERROR:0@...]
    # imdecode_ ... Unexpected end of input stream") would stand beside the caller's one line
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        image = cv2.imdecode(np.frombuffer(data, np.uint8), flags)
    except cv2.error:
        image = None
    finally:
        cv2.utils.logging.setLogLevel(level)
    if image is None or image.size == 0:
        return None, "not a readable image"
    if why := too_many_pixels(image.shape[1], image.shape[0], max_pixels):
        return None, why
    return image, ""


#: A JPEG's scans beyond which it is refused before decoding: a camera's baseline JPEG has
#: one, a progressive one about ten. Each scan is a pass over the whole image, and OpenCV's
#: decoder reads as many as the file holds: a 2 MB file of 100 000 tiny scans over a 9 Mpx
#: image took 92 s to decode (an attacker's review).
MAX_JPEG_SCANS = 100


def jpeg_scans_problem(data: bytes) -> str:
    """Why a JPEG's bytes are refused for their number of scans ('' when not a JPEG or within
    MAX_JPEG_SCANS). Its scans are counted by their start marker (FF DA): inside the coded data
    an FF byte is always followed by 00 or a restart marker, so only a scan's start (or a byte
    pair in a metadata segment, which can only add to the count) reads so."""
    if not data.startswith(b"\xff\xd8"):
        return ""
    scans = data.count(b"\xff\xda")
    if scans > MAX_JPEG_SCANS:
        return (f"a JPEG of {scans} scans, more than any camera writes (at most "
                f"{MAX_JPEG_SCANS} are decoded)")
    return ""


#: How a photo is decoded to be shown or undistorted as it is (`undistort`): upright as its EXIF
#: orientation says, as `detect`, `calibrate` and `survey` decode it (so a calibration made from
#: phone photos is for the size they are undistorted at), a gray one gray, 16 bits kept.
#: (IMREAD_UNCHANGED would keep an alpha channel but ignores the EXIF orientation.)
AS_SHOWN = cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH
#: Said of a photo whose decoded size is not its header's: OpenCV turns a JPEG as its EXIF
#: orientation says (a phone's photo held upright); its header gives the size as stored.
TURNED = "turned upright by its EXIF orientation"


def is_turned(path: Path, image: np.ndarray) -> bool:
    """Is `image`, decoded from `path`, of another size than the file's header gives?"""
    header, _ = header_facts(path, image.size + 1)
    return header not in (None, (image.shape[1], image.shape[0]))


def expand_images(pattern: str) -> list[Path]:
    """Files matching a glob (or every file in a folder), sorted; folders are skipped."""
    base = Path(pattern).expanduser()
    if base.is_dir():
        candidates = [p for p in base.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES]
    else:
        candidates = [Path(p) for p in glob.glob(str(base), recursive=True)]
    return sorted(p for p in candidates if not p.is_dir())


def same_output_name(names: Sequence[str], written: str) -> str:
    """'' when each image's output (`written`, e.g. '{stem}_detect.png') has its own name, else
    why not: two inputs of one stem (a/good.png and a/good.jpg, x/good.png and x/sub/good.png)
    would write one file, the second over the first."""
    first: dict[str, str] = {}
    for name in names:
        target = written.format(stem=Path(name).stem)
        if target in first and first[target] != name:
            return (f"{first[target]} and {name} would both write {target}; give the images "
                    "different names, or run them in turn with different --out folders")
        first[target] = name
    return ""
