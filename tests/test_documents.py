"""The YAML document reader's limits (lanewarden/documents.py), in-process and fast: size, nesting
depth and alias expansion are judged on the event stream before anything is built."""

from __future__ import annotations

from pathlib import Path

import pytest

from lanewarden.documents import (
    CONFIG_SECTIONS,
    MAX_DOCUMENT_BYTES,
    level_marks,
    nesting_depth,
    parse_yaml_text,
    read_yaml_document,
    shorten,
    shown_value,
)


class Refused(Exception):
    pass


def bomb(levels: int, fan: int) -> str:
    lines = [f"l0: &l0 [{', '.join(['x'] * fan)}]"]
    for level in range(1, levels):
        lines.append(f"l{level}: &l{level} [{', '.join([f'*l{level - 1}'] * fan)}]")
    return "\n".join(lines) + "\n"


def nested_mappings(depth: int) -> str:
    return "".join(f"{'  ' * level}k{level}:\n" for level in range(depth - 1)) + (
        f"{'  ' * (depth - 1)}leaf: 1\n")


def test_a_few_aliases_are_fine() -> None:
    text = "base: &b {speed: 0.2, gain: 1.0}\none: *b\ntwo: *b\n"
    assert parse_yaml_text(text, "t.yaml", Refused) == {
        "base": {"speed": 0.2, "gain": 1.0}, "one": {"speed": 0.2, "gain": 1.0},
        "two": {"speed": 0.2, "gain": 1.0},
    }


def test_alias_expansion_is_counted_with_what_the_alias_points_to() -> None:
    # 3 levels of 40: 40 + 40*40 + 40*40*40 = 65,640 expanded strings plus 1,641 lists: accepted
    assert len(parse_yaml_text(bomb(3, 40), "t.yaml", Refused)["l2"]) == 40
    # 4 levels of 18: 18^4 = 104,976 strings: refused, although the file has only 54 aliases
    with pytest.raises(Refused) as err:
        parse_yaml_text(bomb(4, 18), "t.yaml", Refused)
    assert str(err.value) == ("t.yaml: expands to more than 100000 values (aliases count as what "
                              "they point to), refusing to read it")


def test_nesting_depth_is_capped_before_anything_is_built() -> None:
    assert parse_yaml_text(nested_mappings(32), "t.yaml", Refused)["k0"]["k1"] is not None
    with pytest.raises(Refused) as err:
        parse_yaml_text(nested_mappings(33), "t.yaml", Refused)
    assert str(err.value) == "t.yaml: nested deeper than 32 levels, refusing to read it"


def test_file_size_is_capped_without_reading_past_it(tmp_path: Path) -> None:
    exact = tmp_path / "exact.yaml"
    exact.write_bytes(b"#" * (MAX_DOCUMENT_BYTES - 1) + b"\n")
    assert read_yaml_document(exact, "config", Refused) is None
    over = tmp_path / "over.yaml"
    with over.open("wb") as sparse:  # 1 GB, sparse: only 1 MB + 1 byte of it is read
        sparse.truncate(1 << 30)
    with pytest.raises(Refused) as err:
        read_yaml_document(over, "config", Refused)
    assert str(err.value) == f"{over}: config file is larger than 1000 kB, refusing to read it"
    with pytest.raises(Refused) as err:  # endless, and a device: refused before any read
        read_yaml_document("/dev/zero", "config", Refused)
    assert str(err.value) == ("/dev/zero: not a regular file (a FIFO, socket or device), "
                              "expected a config YAML file")


def test_bad_yaml_and_bad_bytes_are_one_line(tmp_path: Path) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text("a: [1, 2\n")
    with pytest.raises(Refused, match=r"broken.yaml: not valid YAML at line 2, column 1: "):
        read_yaml_document(broken, "config", Refused)
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"\xff\xfe\x00junk")
    with pytest.raises(Refused, match=r"binary.yaml: cannot read config file \(not UTF-8 text"):
        read_yaml_document(binary, "config", Refused)


def test_values_in_messages_are_short() -> None:
    assert shorten("x" * 100) == "x" * 59 + "…"
    assert shorten("short") == "short"
    assert shown_value(list(range(10**6))) == "a list of 1000000 items"
    assert shown_value({"a": 1}) == "a mapping"
    assert shown_value("y" * 1000).startswith("'yyy") and len(shown_value("y" * 1000)) <= 60
    assert shown_value([[[[[1]]]]]) == "[[[...]]]"



def test_a_document_of_another_kind_lists_ten_problems_not_all(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A password-like file named as a config echoed all its lines, one unknown key each."""
    from lanewarden.cli import main

    other = tmp_path / "passwd.yaml"
    other.write_text("".join(f"user{i}: x:{i}:{i}::/home/u:/bin/sh\n" for i in range(27)))
    assert main(["config", "show", "--config", str(other)]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 11
    assert lines[-1] == f"lanewarden: error: {other}: ... and 17 more problems"


def test_nesting_depth_counts_brackets_and_xml_elements_not_quoted_text() -> None:
    """Read before OpenCV's FileStorage parses a calibration (it recursed once per level and
    crashed the process on 40 000 of them)."""
    assert nesting_depth("a: " + "[" * 40) == 40
    assert nesting_depth("a: {b: [1, {c: [2]}]}") == 4
    assert nesting_depth("note: \"[[[[[[\"\nother: '{{{{'\n") == 1  # two top-level keys
    assert nesting_depth('<?xml version="1.0"?>\n<opencv_storage>\n<camera_matrix '
                         'type_id="opencv-matrix"><rows>3</rows><data>1 0 0</data>'
                         "</camera_matrix><empty/></opencv_storage>\n") == 3
    assert nesting_depth("%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n"
                         "   data: [ 500., 0., 320. ]\n# a comment\nimage_width: 640\n") == 2
    # what a scan could be fooled by, each of which had crashed OpenCV's parser anyway (a
    # reviewer's bypasses): closers before the openers, compact block sequences
    assert nesting_depth("# " + "]" * 50 + "\na: " + "[" * 40) == 40
    assert nesting_depth("a:\n  " + "- " * 40 + "1\n") == 42  # a, its line, 40 dashes
    # ... and what bounds them, whatever the scan: the characters that open a level
    assert level_marks("a: [ x'y, " + "[" * 40 + " 'z") == 41
    assert level_marks("<?xml?><a><!-- </ --><b/></a>") == 10  # six <, four -
    # block levels: each line one deeper (a 1 MB file holds 1 400; walking the calibration's
    # nodes then raised a RecursionError, a traceback)
    assert nesting_depth("".join(" " * k + "a:\n" for k in range(40)) + " " * 40 + "1\n") == 41


def test_the_config_sections_other_files_are_told_apart_by_are_the_configs() -> None:
    """`CONFIG_SECTIONS` (this leaf module cannot import lanewarden.config) names every
    top-level section of the config: a section added to the config without it would let a
    config given as a scenario, a campaign spec or a calibration that holds only that section
    pass for one, with a 'missing' or 'unknown key' line of each key."""
    from lanewarden.config import LanewardenConfig

    assert CONFIG_SECTIONS == tuple(LanewardenConfig.model_fields)
