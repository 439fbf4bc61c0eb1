"""Outputs are never written through what already has their name (`lanewarden.output_files`):
a link left in an output folder is replaced, not followed (`detect --out` and `undistort` had
overwritten a file outside their folder through one); a FIFO is refused, never opened
(`calibrate --ros`, `calibrate ground`'s check picture and `detect --out` hung on one); a device
is refused, never replaced (`calibrate --out /dev/null`, run as root, had made the system's
/dev/null a regular file). Found by an attacker's review, 2026-12-07."""

from __future__ import annotations

import os
import stat
from dataclasses import replace
from pathlib import Path

import pytest

from lanewarden.cli import main
from lanewarden.output_files import replace_file
from lanewarden.perception.calibration import save_calibration
from lanewarden.perception.errors import PerceptionError
from lanewarden.scenarios.camera import CameraModel
from tests.calibration.test_calibrate_cli import _one_error_line

TAKEN = "exists as a FIFO, socket or device, not a file: choose another name"
RENDERED = Path(__file__).resolve().parents[1] / "data" / "survey" / "rendered" / "lane"


def _device(path: Path) -> Path:
    """A character device like /dev/null at `path` (skips where this user may not make one)."""
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except PermissionError:
        pytest.skip("making a device node needs root")
    return path


def test_a_link_at_the_name_is_replaced_and_what_it_pointed_to_is_kept(tmp_path: Path) -> None:
    outside = tmp_path / "outside.txt"
    outside.write_text("keep", encoding="utf-8")
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.png").symlink_to(outside)
    replace_file(out / "a.png", b"new")
    assert outside.read_text(encoding="utf-8") == "keep"
    assert not (out / "a.png").is_symlink()
    assert (out / "a.png").read_bytes() == b"new"
    assert [p.name for p in out.iterdir()] == ["a.png"]  # nothing half-written left beside it


def test_a_fifo_or_a_device_at_the_name_is_refused_and_left_as_it_is(tmp_path: Path) -> None:
    fifo = tmp_path / "f.yaml"
    os.mkfifo(fifo)
    with pytest.raises(OSError) as err:
        replace_file(fifo, b"x")  # opening it for writing would wait for a reader
    assert err.value.strerror == TAKEN
    assert stat.S_ISFIFO(fifo.lstat().st_mode)
    device = _device(tmp_path / "null")
    with pytest.raises(OSError) as err:
        replace_file(device, b"x")
    assert err.value.strerror == TAKEN
    assert stat.S_ISCHR(device.lstat().st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.yaml", "null"]


def test_a_calibration_is_never_moved_over_a_device(tmp_path: Path) -> None:
    device = _device(tmp_path / "null")
    with pytest.raises(PerceptionError) as err:
        save_calibration(CameraModel().calibration(), device)
    assert str(err.value) == f"{device}: cannot write calibration file ({TAKEN})"
    assert stat.S_ISCHR(device.lstat().st_mode)


@pytest.mark.parametrize("taken", ["g.yaml", "g.ros.yaml", "g.ground-check.png"])
def test_calibrate_ground_refuses_a_fifo_at_any_of_its_outputs_before_writing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], taken: str) -> None:
    intrinsics = tmp_path / "camera.yaml"
    save_calibration(replace(CameraModel().calibration(), ground=None), intrinsics)
    out = tmp_path / "out"
    out.mkdir()
    os.mkfifo(out / taken)
    code = main(["calibrate", "ground", "--calibration", str(intrinsics), "--height-m", "0.2",
                 "--pitch-deg", "30", "--out", str(out / "g.yaml"), "--ros"])
    flag = {"g.yaml": "--out", "g.ros.yaml": "--ros", "g.ground-check.png": "--check-image"}
    assert code == 2
    assert _one_error_line(capsys.readouterr().err) == (
        f"lanewarden: error: {flag[taken]} '{out / taken}': {TAKEN}")
    assert [p.name for p in out.iterdir()] == [taken]


def test_detect_replaces_a_link_named_like_its_picture_not_what_it_points_to(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    outside = tmp_path / "victim.png"
    outside.write_bytes(b"keep")
    out = tmp_path / "det"
    out.mkdir()
    (out / "straight_detect.png").symlink_to(outside)
    assert main(["detect", str(RENDERED / "straight.jpg"), "--out", str(out)]) == 0
    capsys.readouterr()
    assert outside.read_bytes() == b"keep"
    picture = out / "straight_detect.png"
    assert not picture.is_symlink() and picture.read_bytes().startswith(b"\x89PNG")
