"""perception.max_image_pixels: image files are judged from their header before decoding, camera
sources by their frame size when opened, and oversized live frames end the delivery."""

from __future__ import annotations

import struct
import time
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.camera_source import CameraFrameSource, CameraLost, open_camera
from lanewarden.cli import main
from lanewarden.errors import UsageError
from lanewarden.image_files import read_image
from tests.test_hostile_inputs import big_png


def test_image_size_is_judged_from_the_header(tmp_path: Path) -> None:
    wide = tmp_path / "wide.png"
    wide.write_bytes(big_png(8000, 2000))  # 16 Mpx, 2 kB on disk
    expected = (None, "image is 8000x2000 = 16000000 pixels, more than "
                      "perception.max_image_pixels (1000000)")
    assert read_image(wide, max_pixels=1_000_000) == expected
    # the same header with junk for pixel data: only a header read can tell its size
    header_only = tmp_path / "header-only.png"
    junk = b"not zlib data"
    idat = struct.pack(">I", len(junk)) + b"IDAT" + junk + struct.pack(
        ">I", zlib.crc32(b"IDAT" + junk) & 0xFFFFFFFF)
    header_only.write_bytes(wide.read_bytes()[:33] + idat)  # signature + IHDR + IDAT
    assert read_image(header_only, max_pixels=1_000_000) == expected
    assert read_image(header_only, max_pixels=20_000_000) == (None, "not a readable image")


def test_images_within_the_limit_decode(tmp_path: Path) -> None:
    path = tmp_path / "small.jpg"
    cv2.imwrite(str(path), np.full((48, 64, 3), 128, np.uint8))
    image, why = read_image(path, max_pixels=64 * 48)
    assert why == "" and image is not None and image.shape == (48, 64, 3)
    assert read_image(path, max_pixels=64 * 48 - 1) == (
        None, "image is 64x48 = 3072 pixels, more than perception.max_image_pixels (3071)")


def radiance_hdr(width: int, height: int) -> bytes:
    """A valid Radiance HDR image (a format OpenCV decodes and Pillow cannot open), run-length
    encoded: about 400 bytes a row of 1000 pixels, decoded to 12 kB of floats."""
    row = bytearray(b"\x02\x02" + struct.pack(">H", width))
    for component in range(4):  # R, G, B, then the shared exponent
        left = width
        while left:
            run = min(127, left)
            row += bytes([128 + run, 128 if component == 3 else 100])
            left -= run
    return (b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {height} +X {width}\n".encode()
            + bytes(row) * height)


def test_an_image_whose_size_its_header_does_not_tell_is_not_decoded(tmp_path: Path) -> None:
    """OpenCV decodes Radiance HDR, which Pillow cannot open, so its size was only checked
    once decoded: 9 MB of run-length encoded rows (12000x12000) took 1.7 GB in `detect` and in
    `replay` of a folder, a format-1 run or a run.mcap holding it."""
    path = tmp_path / "small.hdr"
    path.write_bytes(cv2.imencode(".hdr", np.zeros((8, 8, 3), np.float32))[1].tobytes())
    assert read_image(path, cv2.IMREAD_UNCHANGED) == (None, "not a readable image")
    path.write_bytes(radiance_hdr(120, 90))
    assert read_image(path) == (None, "not a readable image")


@pytest.fixture
def sequence(tmp_path: Path) -> str:
    for index in range(3):
        cv2.imwrite(str(tmp_path / f"f_{index}.png"), np.zeros((120, 160), np.uint8))
    return str(tmp_path / "f_%d.png")


def test_a_camera_source_with_frames_too_large_is_refused_when_opened(sequence: str) -> None:
    with pytest.raises(UsageError) as err:
        open_camera(sequence, max_pixels=160 * 120 - 1)
    assert str(err.value) == (f"--camera '{sequence}': image is 160x120 = 19200 pixels, more "
                              "than perception.max_image_pixels (19199)")
    open_camera(sequence, max_pixels=160 * 120).release()


def test_an_oversized_live_frame_ends_the_delivery(sequence: str) -> None:
    frames = CameraFrameSource(open_camera(sequence), time.monotonic, max_pixels=100)
    try:
        deadline = time.monotonic() + 10.0
        while frames.error is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert frames.error == ("camera frame refused: image is 160x120 = 19200 pixels, more "
                                "than perception.max_image_pixels (100)")
        with pytest.raises(CameraLost, match="camera frame refused"):  # the loop: CAMERA_ERROR
            frames.read(time.monotonic())
    finally:
        frames.close()


def test_run_refuses_an_oversized_camera_before_the_base(
    sequence: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "small.yaml"
    config.write_text("perception:\n  max_image_pixels: 4096\n")
    assert main(["run", "--camera", sequence, "--port", str(tmp_path / "no-port"), "--config",
                 str(config), "--duration", "1"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"lanewarden: error: --camera '{sequence}': image is 160x120 = 19200 pixels, more than "
        "perception.max_image_pixels (4096)"
    ]


def test_a_truncated_png_gets_one_line_not_opencvs_warning_too(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """OpenCV warns on stderr ("[ WARN:0@...] ... PNG input buffer is incomplete") while it
    decodes a cut-off PNG; the command's own line is the only one."""
    whole = tmp_path / "whole.png"
    cv2.imwrite(str(whole), np.full((120, 160, 3), 128, np.uint8))
    # a picture with detail, cut inside its pixel data: libpng itself printed "libpng error:
    # PNG input buffer is incomplete" (OpenCV's log level does not reach it)
    detailed = tmp_path / "detailed.png"
    cv2.imwrite(str(detailed), np.random.default_rng(7).integers(0, 255, (120, 160, 3),
                                                                 dtype=np.uint8))
    for source, keep in ((whole, 200), (detailed, detailed.stat().st_size // 2)):
        cut = tmp_path / f"cut-{source.name}"
        cut.write_bytes(source.read_bytes()[:keep])
        assert main(["detect", str(cut)]) == 2
        err = capfd.readouterr().err.strip().splitlines()
        assert err == [f"lanewarden: error: 1 of 1 images not analysed: {cut}: not a readable "
                       "image"]


def test_a_truncated_ppm_gets_one_line_not_opencvs_error_too(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """OpenCV logged its own error ("[ERROR:0@...] ... imdecode_('') ... Unexpected end of
    input stream") and a blank line before the command's one line (a PPM cut short: `detect`,
    and a replay of a folder of frames or a format-1 run)."""
    cut = tmp_path / "cut.ppm"
    cut.write_bytes(b"P3 30 30 255\n" + b"0 " * 100)
    assert main(["detect", str(cut)]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert err == [f"lanewarden: error: 1 of 1 images not analysed: {cut}: not a readable image"]


def _progressive_jpeg(extra_scans: int) -> bytes:
    """A 300x300 progressive JPEG (Pillow writes 6 scans), its last scan repeated
    `extra_scans` times before the end marker."""
    import io

    from PIL import Image

    noise = np.random.default_rng(0).integers(0, 255, (300, 300), dtype=np.uint8)
    encoded = io.BytesIO()
    Image.fromarray(noise).save(encoded, "JPEG", progressive=True, quality=80)
    data = encoded.getvalue()
    last = data.rindex(b"\xff\xda")
    return data[:-2] + data[last:-2] * extra_scans + b"\xff\xd9"


def test_a_jpeg_of_more_scans_than_any_camera_writes_is_not_decoded(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Each scan is a pass over the whole image and OpenCV decodes as many as a file holds: a
    2 MB file of 100 000 tiny scans over 9 Mpx took 92 s in `detect` (an attacker's review).
    Beyond 100 scans a JPEG is refused from its bytes; a camera's progressive JPEG decodes."""
    usual = tmp_path / "usual.jpg"
    usual.write_bytes(_progressive_jpeg(0))
    image, why = read_image(usual)
    assert why == "" and image is not None and image.shape[:2] == (300, 300)
    bomb = tmp_path / "bomb.jpg"
    bomb.write_bytes(_progressive_jpeg(150))
    assert read_image(bomb) == (None, "a JPEG of 156 scans, more than any camera writes (at "
                                      "most 100 are decoded)")
    assert main(["detect", str(bomb)]) == 2
    assert capsys.readouterr().err == (f"lanewarden: error: 1 of 1 images not analysed: {bomb}: a "
                                       "JPEG of 156 scans, more than any camera writes (at most "
                                       "100 are decoded)\n")
