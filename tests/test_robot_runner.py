"""`lanewarden run` end to end: a rendered image sequence as the camera, the Kobuki stand-in on a
pseudo-terminal as the base. Checks the wiring and the safety order of start-up and shutdown, not
timing: the run lasts a fixed wall-clock duration because the runner is the one real-time part."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.cli import main
from lanewarden.perception.calibration import CameraCalibration, save_calibration
from tests.actuation.kobuki_standin import STOP_PACKET, KobukiStandIn
from tests.perception.synthetic import STRAIGHT, render


@pytest.fixture
def camera_sequence(tmp_path: Path) -> str:
    folder = tmp_path / "camera"
    folder.mkdir()
    for index in range(45):  # 1.5 s at 30 Hz, fresh sensor noise in each frame (not frozen)
        image = render(replace(STRAIGHT, seed=index), 640, 480)
        cv2.imwrite(str(folder / f"frame_{index:03d}.png"), image)
    return str(folder / "frame_%03d.png")


def test_run_engages_on_a_clean_lane_and_ends_with_stop(
    camera_sequence: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "run" / "run.jsonl"
    with KobukiStandIn() as base:
        code = main(["run", "--camera", camera_sequence, "--port", base.port,
                     "--duration", "1.0", "--record", str(log.parent)])
        assert code == 0, capsys.readouterr().err
        assert base.wait_for(lambda packets: any(p.packet == STOP_PACKET for p in packets), 5.0)
        controls = base.base_controls()
    assert controls, "the stand-in never received a base-control packet"
    assert controls[-1][1] == (0, 0), "the last command on the wire must be stop"
    records = [json.loads(line) for line in log.read_text().splitlines()]
    assert records, "no per-frame record was written"
    assert records[-1]["state"] == "HALT"
    assert records[-1]["command"] == {"linear_m_s": 0.0, "angular_rad_s": 0.0}
    assert any(r["observation"] is not None for r in records), "perception never ran"
    moving = [r for r in records if r["command"]["linear_m_s"] > 0]
    assert moving and all(r["state"] != "HALT" for r in moving), "it never engaged on a clean lane"
    assert "final state HALT" in capsys.readouterr().out


def test_calibration_for_another_camera_refuses_before_the_base_is_touched(
    camera_sequence: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    calibration = tmp_path / "other-camera.yaml"
    k = np.array([[500.0, 0, 400], [0, 500.0, 300], [0, 0, 1]])
    save_calibration(CameraCalibration(k, np.zeros(5), (800, 600)), calibration)
    with KobukiStandIn() as base:
        code = main(["run", "--camera", camera_sequence, "--port", base.port,
                     "--calibration", str(calibration), "--duration", "1.0",
                     "--record", str(tmp_path / "run")])
        received = base.snapshot()
    err = capsys.readouterr().err
    assert code != 0
    assert "refusing to engage" in err and str(calibration) in err
    assert len(err.strip().splitlines()) == 1
    assert received == [], "nothing may reach the base when the calibration is refused"


def test_unopenable_camera_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "no-such-video.mp4"
    code = main(["run", "--camera", str(missing), "--port", str(tmp_path / "no-port"),
                 "--duration", "1.0"])
    err = capsys.readouterr().err
    assert code != 0
    assert str(missing) in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
