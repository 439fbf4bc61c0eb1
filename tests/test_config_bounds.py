"""Every numeric config key is finite and bounded: inf, NaN and an absurd value are refused with
one line naming the key and its allowed range. The walk covers every key of every section, so a
key added later without bounds fails here. CLI number flags are finite and bounded too."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import pytest

from lanewarden.cli import main
from lanewarden.config import LanewardenConfig, config_from_mapping, load_config, walk_config
from lanewarden.errors import ConfigError

NUMERIC_KEYS = [
    node.path
    for node in walk_config(LanewardenConfig())
    if not node.is_section and isinstance(node.value, int | float)
    and not isinstance(node.value, bool)
]


def nested(path: tuple[str, ...], value: Any) -> dict[str, Any]:
    data: Any = value
    for part in reversed(path):
        data = {part: data}
    return dict(data)


def refusal(path: tuple[str, ...], value: Any) -> str:
    with pytest.raises(ConfigError) as err:
        config_from_mapping(nested(path, value), "cfg.yaml")
    return str(err.value)


def test_the_walk_sees_every_section() -> None:
    sections = {path[0] for path in NUMERIC_KEYS}
    assert sections == {"perception", "calibration", "supervisor", "actuation", "simulation",
                        "campaign"}
    assert len(NUMERIC_KEYS) >= 120


@pytest.mark.parametrize("path", NUMERIC_KEYS, ids=[".".join(p) for p in NUMERIC_KEYS])
def test_every_numeric_key_refuses_non_finite_and_absurd_values(path: tuple[str, ...]) -> None:
    for value in (math.inf, -math.inf, math.nan, 1e12, -1e12):
        given: Any = int(value) if math.isfinite(value) and _is_int(path) else value
        lines = refusal(path, given).splitlines()
        assert len(lines) == 1, (value, lines)
        assert lines[0].startswith(f"cfg.yaml: {'.'.join(path)} = "), lines[0]
        assert re.search(
            r": expected (a finite number|an integer) with (\S+ <=? )?value <=? \S+$", lines[0]
        ), lines[0]


@pytest.mark.parametrize("path", NUMERIC_KEYS, ids=[".".join(p) for p in NUMERIC_KEYS])
def test_every_numeric_key_refuses_true_false_and_quoted_numbers(path: tuple[str, ...]) -> None:
    """YAML's `true`/`yes`/`on` and a quoted "0.5" are not numbers: pydantic would read them as
    1 and 0.5 (`engage_confident_frames: yes` engaging on one frame), the tool refuses them."""
    for value, why in ((True, "true/false"), (False, "true/false"),
                       ("1", "text (write the number without quotes)"),
                       # a typo is text, but no number in quotes: no advice about quotes
                       ("0.0l9", "text")):
        lines = refusal(path, value).splitlines()
        assert len(lines) == 1, (value, lines)
        assert lines[0].startswith(f"cfg.yaml: {'.'.join(path)} = "), lines[0]
        assert re.search(r": expected (a finite number|an integer)( with .*)?, not "
                         + re.escape(why) + "$", lines[0]), lines[0]


FLAG_KEYS = [node.path for node in walk_config(LanewardenConfig())
             if not node.is_section and isinstance(node.value, bool)]


@pytest.mark.parametrize("path", FLAG_KEYS, ids=[".".join(p) for p in FLAG_KEYS])
def test_every_true_false_key_refuses_numbers_and_text(path: tuple[str, ...]) -> None:
    """pydantic would read 1, 0 and a quoted "yes" or "false" as true and false
    (`auto_resume_after_lane_loss: "yes"`: the robot driving off by itself after a lane-loss
    halt); the tool refuses them, and takes true and false."""
    for value, why in ((1, "a number"), (0, "a number"), (1.0, "a number"),
                       ("yes", "text (write true or false without quotes)"),
                       ("false", "text (write true or false without quotes)")):
        lines = refusal(path, value).splitlines()
        assert len(lines) == 1, (value, lines)
        assert lines[0].startswith(f"cfg.yaml: {'.'.join(path)} = "), lines[0]
        assert lines[0].endswith(f": expected true or false, not {why}"), lines[0]
    for value in (True, False):
        section = config_from_mapping(nested(path, value), "cfg.yaml")
        for part in path:
            section = getattr(section, part)
        assert section is value


def test_the_walk_sees_the_true_false_keys() -> None:
    assert ("supervisor", "auto_resume_after_lane_loss") in FLAG_KEYS


def test_a_true_safety_setting_is_refused_not_read_as_one() -> None:
    assert refusal(("supervisor", "engage_confident_frames"), True) == (
        "cfg.yaml: supervisor.engage_confident_frames = true (YAML's reading of true, yes or "
        "on): expected an integer with 1 <= value <= 300, not true/false")
    assert refusal(("supervisor", "lane_lost_halt_s"), False) == (
        "cfg.yaml: supervisor.lane_lost_halt_s = false (YAML's reading of false, no or off): "
        "expected a finite number with 0 < value <= 1, not true/false")


def test_a_key_that_also_takes_a_word_still_takes_it() -> None:
    config = config_from_mapping({"perception": {"edges": {"look_ahead_m": "auto"}}}, "cfg.yaml")
    assert config.perception.edges.look_ahead_m == "auto"
    assert "look_ahead_m = true (YAML's reading of true, yes or on)" in refusal(
        ("perception", "edges", "look_ahead_m"), True)


def _is_int(path: tuple[str, ...]) -> bool:
    node: Any = LanewardenConfig()
    for part in path:
        node = getattr(node, part)
    return isinstance(node, int)


@pytest.mark.parametrize(
    ("path", "value", "line"),
    [
        (("supervisor", "lane_lost_halt_s"), math.inf,
         "cfg.yaml: supervisor.lane_lost_halt_s = inf: expected a finite number with "
         "0 < value <= 1"),
        (("supervisor", "degraded_budget_m"), 1e308,
         "cfg.yaml: supervisor.degraded_budget_m = 1e+308: expected a finite number with "
         "0 < value <= 2"),
        (("supervisor", "frame_stale_s"), math.nan,
         "cfg.yaml: supervisor.frame_stale_s = nan: expected a finite number with 0 < value <= 1"),
        (("actuation", "heartbeat_timeout_s"), 5.0,
         "cfg.yaml: actuation.heartbeat_timeout_s = 5.0: expected a finite number with "
         "0.02 <= value <= 1"),
        (("perception", "blur", "kernel_px"), 10**12,
         "cfg.yaml: perception.blur.kernel_px = 1000000000000: expected an integer with "
         "1 <= value <= 31"),
        (("perception", "max_image_pixels"), 400_000_000,
         "cfg.yaml: perception.max_image_pixels = 400000000: expected an integer with "
         "4096 <= value <= 50000000"),
        (("simulation", "video", "crf"), -1,
         "cfg.yaml: simulation.video.crf = -1: expected an integer with 0 <= value <= 51"),
    ],
)
def test_refusals_name_the_key_and_the_range(path: tuple[str, ...], value: Any,
                                             line: str) -> None:
    assert refusal(path, value) == line


def test_a_long_bad_value_is_cut() -> None:
    message = refusal(("supervisor", "lane_lost_halt_s"), "x" * 10_000)
    assert len(message) < 200
    assert "supervisor.lane_lost_halt_s = 'xxxx" in message and "…" not in message[:20]


@pytest.mark.parametrize(
    ("data", "line"),
    [
        ({"perception": {"canny": {"low_treshold": 10}}},
         "cfg.yaml: unknown key 'perception.canny.low_treshold': did you mean "
         "'perception.canny.low_threshold'?"),
        ({"supervisr": {}}, "cfg.yaml: unknown key 'supervisr': did you mean 'supervisor'?"),
        # a section's key run together with the section's name (it had got no hint)
        ({"perception": {"tape_widht_m": 0.02}},
         "cfg.yaml: unknown key 'perception.tape_widht_m': did you mean "
         "'perception.tape.width_m'?"),
        ({"supervisor": {"lane_lost_halt": 0.2}},
         "cfg.yaml: unknown key 'supervisor.lane_lost_halt': did you mean "
         "'supervisor.lane_lost_halt_s'?"),
        ({"supervisor": {"zzz": 1}},
         "cfg.yaml: unknown key 'supervisor.zzz' (check the spelling; `lanewarden config show` "
         "lists every key)"),
    ],
)
def test_unknown_keys_get_a_did_you_mean(data: dict[str, Any], line: str) -> None:
    with pytest.raises(ConfigError) as err:
        config_from_mapping(data, "cfg.yaml")
    assert str(err.value) == line


def test_yaml_inf_in_a_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "inf.yaml"
    path.write_text("supervisor:\n  lane_lost_halt_s: .inf\n  degraded_budget_s: .nan\n")
    assert main(["config", "show", "--config", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [
        f"lanewarden: error: {path}: supervisor.lane_lost_halt_s = inf: expected a finite "
        "number with 0 < value <= 1",
        f"lanewarden: error: {path}: supervisor.degraded_budget_s = nan: expected a finite "
        "number with 0 < value <= 10",
    ]


def test_a_number_in_exponent_form_is_a_number(tmp_path: Path) -> None:
    """YAML 1.1 reads `2e-2` (no dot) and `1.0e9` (no sign) as text: the survey's config said
    "... = '2e-2': ... not text (write the number without quotes)" of a number without quotes."""
    path = tmp_path / "exp.yaml"
    path.write_text("perception: {tape: {width_m: 2e-2}, lane: {width_m: 5E-1}}\n")
    config = load_config(path)
    assert (config.perception.tape.width_m, config.perception.lane.width_m) == (0.02, 0.5)
    path.write_text("supervisor: {camera_period_s: 1.0e9}\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value) == (f"{path}: supervisor.camera_period_s = 1000000000.0: expected a "
                              "finite number with 0 < value <= 1")
    path.write_text("perception: {lane: {width_m: '3e-1'}}\n")  # quoted: text, as it says
    with pytest.raises(ConfigError, match="not text"):
        load_config(path)


@pytest.mark.parametrize(("text", "line"), [
    # every key under the section commented out: pydantic's words named its class
    ("perception:\n  # tape: {width_m: 0.019}\n", "perception = (empty): expected a mapping of "
     "its keys, indented below it, or no 'perception:' line at all"),
    ("perception: {tape: wide}\n", "perception.tape = 'wide': expected a mapping of its keys, "
     "indented below it"),
    # PyYAML's words cut to 60 characters had lost the tag: "... for the tag 'tag:yaml.org…"
    ("t: &t {width_m: 0.019}\nperception: {tape: {<<: *t}}\n", "not valid YAML at line 2, "
     "column 21: '<<' (a YAML merge key) is not read here; expected the keys written out"),
    ("!!python/object/apply:os.system ['true']\n", "not valid YAML at line 1, column 1: the tag "
     "!!python/object/apply:os.system is not read here; expected plain numbers"),
])
def test_a_section_or_value_of_the_wrong_shape_says_what_it_wants(tmp_path: Path, text: str,
                                                                  line: str) -> None:
    path = tmp_path / "shape.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value).startswith(f"{path}: {line}")


@pytest.mark.parametrize(
    ("argv", "flag"),
    [
        (["run", "--duration", "nan"], "--duration"),
        (["run", "--duration", "inf"], "--duration"),
        (["run", "--duration", "1e9"], "--duration"),
        (["calibrate", "--images", "x", "--pattern", "9x6", "--square", "1e9", "--out", "c.yaml"],
         "--square"),
        (["calibrate", "--images", "x", "--pattern", "9x6", "--square", "inf", "--out", "c.yaml"],
         "--square"),
        (["calibrate", "capture", "--camera", "0", "--pattern", "9x6", "--out", "d",
          "--count", "1000000"], "--count"),
        (["base", "drive", "--linear", "0.1", "--duration", "inf"], "--duration"),
        (["base", "drive", "--linear", "nan", "--duration", "1"], "--linear"),
        (["sim", "--scenario", "straight", "--seed", "-1"], "--seed"),
        (["demo", "--seed", "1e30"], "--seed"),
    ],
)
def test_cli_numbers_are_finite_and_bounded(argv: list[str], flag: str,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"'{flag}'" in err[0], err


def test_a_quoted_look_ahead_is_text_as_every_quoted_number_is(tmp_path: Path) -> None:
    """`look_ahead_m: "0.40"` was accepted (the union of a distance and `auto` took the text
    for a number) where `width_m: "0.048"` is refused; a misspelt auto is not called a number."""
    path = tmp_path / "quoted.yaml"
    path.write_text('perception: {edges: {look_ahead_m: "0.40"}}\n')
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value) == (f"{path}: perception.edges.look_ahead_m = '0.40': expected a "
                              "distance in metres above 0 and at most 10, or auto; not text "
                              "(write the number without quotes)")
    path.write_text("perception: {edges: {look_ahead_m: aut}}\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value) == (f"{path}: perception.edges.look_ahead_m = 'aut': expected a "
                              "distance in metres above 0 and at most 10, or auto")
    path.write_text("perception: {edges: {look_ahead_m: 0.40}}\n")
    assert load_config(path).perception.edges.look_ahead_m == 0.4


def test_a_sections_own_check_names_the_section_and_its_keys(tmp_path: Path) -> None:
    """A check across a section's keys had read "perception = a mapping: edges.look_ahead_m
    ..." (the section's whole value shown as "a mapping")."""
    path = tmp_path / "far.yaml"
    path.write_text("perception: {edges: {look_ahead_m: 5}}\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(err.value) == (f"{path}: perception: edges.look_ahead_m (5) must lie within the "
                              "region of interest, roi.near_m (0) to roi.far_m (1.6)")


@pytest.mark.parametrize(("key", "refused", "accepted"), [("theta_deg", 0.2, 0.25),
                                                          ("rho_px", 0.4, 0.5)])
def test_hough_resolutions_are_bounded_below_by_the_accumulator_they_make(
        key: str, refused: float, accepted: float) -> None:
    """HoughLinesP's accumulator has 180/theta_deg x about 2 (width + height)/rho_px cells:
    theta_deg 0.0002 took one 320x240 photo past 8 GB (a hostile config, or a recording's
    config.yaml given to replay), 1e-7 crashed OpenCV's allocator with a traceback. At the
    bounds, a 1920x1080 frame's accumulator is 720 x 12 000 cells, 35 MB."""
    assert refusal(("perception", "hough", key), refused) == (
        f"cfg.yaml: perception.hough.{key} = {refused}: expected a finite number with "
        f"{accepted} <= value <= 10")
    config = config_from_mapping(nested(("perception", "hough", key), accepted), "cfg.yaml")
    assert getattr(config.perception.hough, key) == accepted


def test_the_simulated_base_integration_step_is_bounded_below() -> None:
    """1e-9 s made the 20 s `straight` scenario take about a quarter of an hour, printing
    nothing for its first minute (an attacker's review)."""
    assert refusal(("actuation", "sim", "integration_step_s"), 1e-9) == (
        "cfg.yaml: actuation.sim.integration_step_s = 1e-09: expected a finite number with "
        "0.0001 <= value <= 0.05")
