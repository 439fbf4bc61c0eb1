"""Reading a validated YAML document (a config file, a scenario file) safely, with one-line errors.

Shared by the CLI's config loader and the scenario files. Hostile files are refused before they
cost time or memory: a file larger than `MAX_DOCUMENT_BYTES` is not read past that size, and the
YAML event stream is checked BEFORE anything is built from it (PyYAML's composer recurses once per
nesting level, and its loader expands aliases into shared objects that every later walk, e.g.
pydantic's validation, visits in full): nesting deeper than `MAX_NESTING_DEPTH` and documents that
expand (aliases counted with the size of what they point to) to more than `MAX_EXPANDED_NODES`
values are refused. Pydantic validation errors become one line each, naming the file, the dotted
key, the bad value (cut to `MAX_SHOWN_CHARS`) and what was expected: the allowed range of a
numeric key, or "did you mean ...?" for an unknown key.

A leaf module: it imports no layer (perception, supervisor, actuation, scenarios), so every layer
may use it. Raises the caller's own exception type, so each layer keeps its own error hierarchy.
Never prints.
"""

from __future__ import annotations

import difflib
import enum
import json
import os
import re
import reprlib
import stat
import types
import typing
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import annotated_types
import yaml
from pydantic import BaseModel, ValidationError, ValidationInfo, field_validator
from pydantic.fields import FieldInfo

from lanewarden.wording import shown_name

#: Largest config or scenario file read, bytes (the shipped ones are a few kB).
MAX_DOCUMENT_BYTES = 1_000_000
#: Deepest nesting of mappings and lists (the config tree is 5 deep, a scenario 4).
MAX_NESTING_DEPTH = 32
#: Most values (scalars, mappings, lists) a document may expand to, each alias counted as the
#: size of what it points to: a YAML "billion laughs" is refused instead of expanded.
MAX_EXPANDED_NODES = 100_000
#: Bad values are shown cut to this many characters in error messages.
MAX_SHOWN_CHARS = 60
#: At most this many problems of one document are listed.
MAX_PROBLEM_LINES = 10

#: Why a FIFO, socket or device is refused where a file is expected (reading one waits for a
#: writer, or never ends).
NOT_A_REGULAR_FILE = "not a regular file (a FIFO, socket or device)"
#: The top-level sections of a lanewarden config: `LanewardenConfig`'s fields (this leaf module
#: cannot import the config; tests/test_documents.py keeps the two in step). A file holding one
#: of them, and none of the keys of the file expected, is a config given in the wrong place.
CONFIG_SECTIONS = ("perception", "calibration", "supervisor", "actuation", "simulation",
                   "campaign")

_SAFE_LOADER: type[Any] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def is_special_file(path: Path) -> bool:
    """Does `path` exist as something neither a regular file nor a folder (a FIFO, socket or
    device)? Missing or unreadable: False (opening it then says why)."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def wrong_document(kind: str, signs: Sequence[str], what: str, flag: str,
                   expected: str = "") -> str:
    """The one wording for a lanewarden file given in the place of another: "a lanewarden
    config (it has 'perception:'), not a scenario (give this file to --config)", `expected`
    (what the file given should have been) after a ';' when given."""
    has = " and ".join(f"'{sign}:'" for sign in signs)
    return (f"{kind} (it has {has}), not a {what}{f'; {expected}' if expected else ''} "
            f"(give this file to {flag})")


def config_given_as(keys: Iterable[object], own_keys: Iterable[str], what: str,
                    expected: str = "") -> str:
    """Is a document whose top-level keys are `keys`, read as a `what` (a scenario, a campaign
    spec, a calibration), a lanewarden config? Yes when it holds a config section and none of
    `own_keys` (the keys a `what` may have): `wrong_document`'s line, without the file's name
    (each `what`'s own validation had said 'unknown key' of every section, and 'missing' of
    every required key). '' otherwise: a `what` with a stray section is left to its own
    validation, which names that key. A key that is both a config section and one of
    `own_keys` (a campaign case's `campaign:`) says neither: a config given as a case had been
    taken for a broken case ("not a campaign case")."""
    keys = set(keys)
    if keys & (set(own_keys) - set(CONFIG_SECTIONS)):
        return ""
    section = next((name for name in CONFIG_SECTIONS if name in keys), None)
    if section is None:
        return ""
    return wrong_document("a lanewarden config", [section], what, "--config", expected)


def dangling_link(path: Path) -> str:
    """"a link to 'TARGET', which does not exist" when `path` is a symbolic link to nothing,
    else ''."""
    if path.is_symlink() and not path.exists():
        return f"a link to '{shown_name(os.readlink(path))}', which does not exist"
    return ""


def leads_outside(path: Path, inside: Path) -> bool:
    """Does `path`, its links followed, lie outside the folder `inside` (resolved)? A link loop
    leads nowhere, so not (Path.resolve raises on one; reading the file then says why, in one
    line)."""
    try:
        return not path.resolve().is_relative_to(inside)
    except (OSError, RuntimeError):
        return False


class _Loader(_SAFE_LOADER):  # type: ignore[misc, valid-type]
    """The safe loader (LibYAML's where there is one), refusing a mapping that repeats a key:
    YAML keeps the last one silently, so `lane_lost_halt_s: 0.2` followed further down by
    `lane_lost_halt_s: 0.9` would run with 0.9 while the reader sees 0.2."""

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                repeated = key in seen
                seen.add(key)
            except TypeError:  # an unhashable key: the base class says so
                break
            if repeated:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {shorten(_SHORT.repr(key))} appears twice in one mapping",
                    key_node.start_mark)
        return super().construct_mapping(node, deep)


# YAML 1.1 (PyYAML's) reads a number in exponent form only with a dot and a signed exponent
# (1.0e+3): `1e308`, `2e-2` and `1.0e9` were text, and a numeric key then said "write the number
# without quotes" of a number written without any. Read them as numbers, as YAML 1.2 does.
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"))
_LOADER: type[Any] = _Loader
_SHORT = reprlib.Repr()
_SHORT.maxlevel, _SHORT.maxlist, _SHORT.maxtuple, _SHORT.maxdict = 2, 4, 4, 4
_SHORT.maxstring = _SHORT.maxother = _SHORT.maxlong = MAX_SHOWN_CHARS


class DocumentTooLarge(ValueError):
    """The YAML event stream breaks one of the limits above (the message says which)."""


def shorten(text: str, limit: int = MAX_SHOWN_CHARS) -> str:
    """`text` cut to `limit` characters, ending in '…' when cut."""
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _json_integer(text: str) -> int | float:
    """An integer as `read_json` reads it: beyond 19 digits (past any int64 a recording or a
    campaign writes) as a float, so that a 400-digit integer reads as inf, which every check
    for a finite number refuses (as an int it passed `isinstance(..., int | float)` and then
    `math.isfinite` raised OverflowError: a traceback, an attacker's review)."""
    digits = len(text) - text.startswith("-")
    return int(text) if digits <= 19 else float(text)


def read_json(text: str | bytes) -> Any:
    """`json.loads` for what a file says (a recording, a tub's catalog, a campaign's store):
    integers too long for any field read as floats (`_json_integer`)."""
    return json.loads(text, parse_int=_json_integer)


def shown_value(value: object) -> str:
    """A bad value as it appears in an error line: short, whatever its size."""
    if isinstance(value, Mapping):
        return "a mapping"
    if isinstance(value, bool):  # the file may say yes or on: YAML reads them as true
        return ("true (YAML's reading of true, yes or on)" if value
                else "false (YAML's reading of false, no or off)")
    if isinstance(value, list | tuple) and len(value) > 4:
        return f"a list of {len(value)} items"
    return shorten(_SHORT.repr(value))


def check_event_stream(text: str) -> None:
    """DocumentTooLarge if `text` nests deeper than MAX_NESTING_DEPTH or expands to more than
    MAX_EXPANDED_NODES values. Walks the parser's events only: nothing is built, nothing recurses.
    yaml.YAMLError for text that is not YAML."""
    open_sizes: list[int] = []  # per open mapping/list: values inside it so far (itself included)
    open_anchors: list[str | None] = []
    anchor_sizes: dict[str, int] = {}
    total = 0

    def add(count: int) -> None:
        nonlocal total
        total += count
        if open_sizes:
            open_sizes[-1] += count
        if total > MAX_EXPANDED_NODES:
            raise DocumentTooLarge(
                f"expands to more than {MAX_EXPANDED_NODES} values (aliases count as what they "
                "point to)"
            )

    for event in yaml.parse(text, Loader=_LOADER):
        if isinstance(event, yaml.CollectionStartEvent):
            if len(open_sizes) >= MAX_NESTING_DEPTH:
                raise DocumentTooLarge(f"nested deeper than {MAX_NESTING_DEPTH} levels")
            open_sizes.append(0)
            open_anchors.append(event.anchor)
            add(1)
        elif isinstance(event, yaml.CollectionEndEvent):
            size = open_sizes.pop()
            anchor = open_anchors.pop()
            if open_sizes:
                open_sizes[-1] += size
            if anchor is not None:
                anchor_sizes[anchor] = size
        elif isinstance(event, yaml.ScalarEvent):
            if event.anchor is not None:
                anchor_sizes[event.anchor] = 1
            add(1)
        elif isinstance(event, yaml.AliasEvent):
            add(anchor_sizes.get(event.anchor or "", 1))


#: A quoted string on one line, or one bracket or XML tag that opens or closes a level.
_NESTING_TOKENS = re.compile(r'"[^"\n]*"|\'[^\'\n]*\'|[\[{]|[\]}]|<[A-Za-z_]|</|/>')
#: The characters one of which every nesting level needs, in any of OpenCV's FileStorage
#: formats: a flow list or mapping's `[` or `{`, an XML element's `<`, a block sequence's `-`.
_LEVEL_MARKS = re.compile(r"[\[{<-]")
#: At most this many of them in a file read by a parser that recurses once per level (a
#: calibration holds a few dozen; OpenCV's parser overflowed its stack at 20 000-40 000 levels).
MAX_LEVEL_MARKS = 1000


def nesting_depth(text: str) -> int:
    """How deep `text` nests, read without parsing it, for a parser that recurses once per
    level before it checks anything, as OpenCV's FileStorage does (a 40 kB calibration file of
    40 000 `[` crashed the process with a segmentation fault; 1 400 YAML block levels were a
    RecursionError where the calibration's nodes were walked): flow lists and mappings (`[`,
    `{`) and XML elements (text in quotes on one line skipped; never below the top), and YAML's
    block levels (a line indented deeper than the one it belongs to, each `- ` that opens it),
    whichever is deeper. A scan, not a parse, so a file can hide levels from it that a parser
    sees; `level_marks` bounds those."""
    depth = deepest = 0
    for token in _NESTING_TOKENS.finditer(text):
        mark = token.group()
        if mark in ("[", "{") or (mark[0] == "<" and mark != "</"):
            depth += 1
            deepest = max(deepest, depth)
        elif mark[0] not in "\"'":
            depth = max(depth - 1, 0)
    indents: list[int] = []  # the indentation of each block level open at this line
    for line in text.splitlines():
        content = line.lstrip(" ")
        if not content or content.startswith(("#", "%", "---", "...")):
            continue
        indent = len(line) - len(content)
        while indents and indents[-1] >= indent:
            indents.pop()
        indents.append(indent)
        dashes = len(content) - len(content.lstrip("- "))  # "- - - 1": three levels more
        deepest = max(deepest, len(indents) + content[:dashes].count("-"))
    return deepest


def level_marks(text: str) -> int:
    """How many characters of `text` could each open a nesting level in one of OpenCV's
    FileStorage formats (`_LEVEL_MARKS`): every level needs one, so this bounds the nesting
    whatever a scan is fooled by (quotes, comments, closers)."""
    return len(_LEVEL_MARKS.findall(text))


def _yaml_problem(exc: yaml.YAMLError, text: str) -> str:
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
    problem = getattr(exc, "problem", None) or "invalid YAML"
    # A camera calibration given where YAML is expected: PyYAML stops at the first thing it
    # cannot read, the tag or an escape OpenCV writes and YAML has not (\' in a string).
    if "opencv-matrix" in str(problem) or "!!opencv-matrix" in text:
        return (f"not valid YAML{where}: it holds OpenCV's !!opencv-matrix, as a camera "
                "calibration does (give that file as --calibration)")
    if tag := re.search(r"constructor for the tag '([^']*)'", str(problem)):
        # cut to 60 characters, PyYAML's words had lost the tag's name: "... tag 'tag:yaml.org…"
        name = tag.group(1).replace("tag:yaml.org,2002:", "!!")
        if name == "!!merge":
            return (f"not valid YAML{where}: '<<' (a YAML merge key) is not read here; "
                    "expected the keys written out (an alias, *name, may stand for a whole "
                    "mapping)")
        return (f"not valid YAML{where}: the tag {shorten(name)} is not read here; expected "
                "plain numbers, text, true/false, lists and mappings")
    return f"not valid YAML{where}: {shorten(str(problem))}"


def parse_yaml_text(text: str, source: str, error: type[Exception]) -> Any:
    """Parse YAML text within the limits above; `error(...)` (one line naming `source`) if not."""
    if len(text) > MAX_DOCUMENT_BYTES:
        raise error(f"{source}: larger than {MAX_DOCUMENT_BYTES // 1000} kB, refusing to read it")
    try:
        check_event_stream(text)
        return yaml.load(text, Loader=_LOADER)  # a safe loader (LibYAML or Python)
    except DocumentTooLarge as exc:
        raise error(f"{source}: {exc}, refusing to read it") from None
    except yaml.YAMLError as exc:
        raise error(f"{source}: {_yaml_problem(exc, text)}") from None
    except ValueError as exc:  # e.g. an integer of more digits than Python converts
        raise error(f"{source}: a value YAML cannot read ({shorten(str(exc))})") from None


def read_yaml_document(path: str | Path, what: str, error: type[Exception]) -> Any:
    """Read and parse one YAML file within the limits above; `error(...)` (one line naming the
    file) when it can't be. Never reads more than MAX_DOCUMENT_BYTES + 1 bytes."""
    path = Path(path)
    try:
        if is_special_file(path):
            raise error(f"{path}: {NOT_A_REGULAR_FILE}, expected a {what} YAML file")
        with path.open("rb") as stream:
            data = stream.read(MAX_DOCUMENT_BYTES + 1)
    except FileNotFoundError:
        raise error(f"{path}: {what} file not found") from None
    except IsADirectoryError:
        raise error(f"{path}: is a directory, expected a {what} YAML file") from None
    except OSError as exc:
        raise error(f"{path}: cannot read {what} file ({shorten(str(exc))})") from None
    if len(data) > MAX_DOCUMENT_BYTES:
        raise error(
            f"{path}: {what} file is larger than {MAX_DOCUMENT_BYTES // 1000} kB, refusing to read "
            "it"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: cannot read {what} file (not UTF-8 text: {exc.reason})") from None
    return parse_yaml_text(text, str(path), error)


# --------------------------------------------------------------------- the models' own limits


def _unwrap(annotation: Any) -> list[Any]:
    """The alternatives of an annotation: `X | None` -> [X, None], `X` -> [X]."""
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return list(typing.get_args(annotation))
    return [annotation]


def _submodel(annotation: Any) -> type[BaseModel] | None:
    for option in _unwrap(annotation):
        if isinstance(option, type) and issubclass(option, BaseModel):
            return option
        if typing.get_origin(option) in (list, tuple):
            items = [a for a in typing.get_args(option) if a is not Ellipsis]
            if len(items) == 1 and isinstance(items[0], type) and issubclass(items[0], BaseModel):
                return items[0]
    return None


def _locate(
    model: type[BaseModel], loc: Sequence[str | int]
) -> tuple[type[BaseModel] | None, FieldInfo | None]:
    """The model that holds the last named key of `loc`, and that key's field (None when the key
    is unknown: the model is then where it was looked for)."""
    holder: type[BaseModel] = model
    field: FieldInfo | None = None
    for part in loc:
        if isinstance(part, int):
            continue  # an index into a list of models, or into a tuple of numbers
        if part not in holder.model_fields:
            return holder, None
        field = holder.model_fields[part]
        sub = _submodel(field.annotation)
        if sub is None:
            return holder, field
        holder = sub
    return holder, field


def _number_kind(field: FieldInfo) -> str | None:
    options = [o for o in _unwrap(field.annotation) if o is not type(None)]
    if options == [int]:
        return "an integer"
    if options in ([float], [int, float], [float, int]):
        return "a finite number"
    return None


def _plain(option: Any) -> Any:
    """`Annotated[X, ...]` -> X; anything else as it is."""
    return typing.get_args(option)[0] if typing.get_origin(option) is typing.Annotated else option


def _takes_text(option: Any) -> bool:
    option = _plain(option)
    return option is str or typing.get_origin(option) is typing.Literal or (
        isinstance(option, type) and issubclass(option, (str, enum.Enum, Path)))


#: What a number written in quotes is told (YAML reads it as text).
QUOTED_NUMBER = "text (write the number without quotes)"


def text_kind(value: str) -> str:
    """What a text value is, for a key that wanted a number: a number in quotes
    (`QUOTED_NUMBER`), or just text (a typo such as `0.0l9`: no advice about quotes it does not
    have)."""
    try:
        float(value)
    except ValueError:
        return "text"
    return QUOTED_NUMBER


def _not_true_or_false(value: Any, options: Sequence[Any]) -> str:
    """Why `value` may not stand for true/false of a key that takes only that, or '' when it
    may: pydantic would read `auto_resume_after_lane_loss: "yes"` (quoted, so text to YAML) or
    `: 1` as true, and such a key can let the robot drive off by itself."""
    if isinstance(value, bool) or not options or any(_plain(o) is not bool for o in options):
        return ""
    if isinstance(value, str):
        return "text (write true or false without quotes)"
    if isinstance(value, (int, float)):
        return "a number"
    return ""


def _not_a_number(value: Any, options: Sequence[Any]) -> str:
    """Why `value` may not stand for a number of a key whose annotation has these `options`
    (its alternatives), or '' when it may: true/false is never a number (YAML's `yes` and `on`
    are true too) and text is one only where the key also takes text (`look_ahead_m: auto`)."""
    numeric = [o for o in map(_plain, options) if o in (int, float)]
    if not numeric:
        return ""
    if isinstance(value, bool):
        return "true/false"
    if isinstance(value, str) and not any(_takes_text(o) for o in options):
        return text_kind(value)
    return ""


class DocumentModel(BaseModel):
    """The base of every model read from a YAML document (config, scenario, campaign spec): a
    numeric key refuses true/false and quoted text instead of converting them (pydantic would
    read `lane_lost_halt_s: true` as 1.0 and `engage_confident_frames: yes` as 1), with the
    same one-line error as a value out of range. Numbers inside lists and tuples too. A
    true/false key refuses numbers and text (pydantic would read 1 and "yes" as true)."""

    @field_validator("*", mode="before")
    @classmethod
    def _numbers_are_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        name = info.field_name
        field = cls.model_fields.get(name) if name is not None else None
        if field is None:
            return value
        options = [o for o in _unwrap(field.annotation) if o is not type(None)]
        problem = _not_a_number(value, options)
        if not problem and isinstance(value, (list, tuple)):
            items = [a for o in options if typing.get_origin(_plain(o)) in (list, tuple)
                     for a in typing.get_args(_plain(o)) if a is not Ellipsis]
            problem = next((p for v in value if (p := _not_a_number(v, items))), "")
        if problem:
            kind = _number_kind(field) or "a number"
            allowed = allowed_range(field)
            raise ValueError(f"expected {kind}{f' with {allowed}' if allowed else ''}, "
                             f"not {problem}")
        if flag := _not_true_or_false(value, options):
            raise ValueError(f"expected true or false, not {flag}")
        return value


def _format_bound(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def allowed_range(field: FieldInfo) -> str:
    """The allowed values of a numeric key as text, e.g. '0 < value <= 5'; '' if not numeric."""
    if _number_kind(field) is None:
        return ""
    low = high = ""
    for item in field.metadata:
        if isinstance(item, annotated_types.Gt):
            low = f"{_format_bound(item.gt)} < "
        elif isinstance(item, annotated_types.Ge):
            low = f"{_format_bound(item.ge)} <= "
        elif isinstance(item, annotated_types.Lt):
            high = f" < {_format_bound(item.lt)}"
        elif isinstance(item, annotated_types.Le):
            high = f" <= {_format_bound(item.le)}"
    return f"{low}value{high}" if low or high else ""


_RANGE_ERRORS = {
    "finite_number", "greater_than", "greater_than_equal", "less_than", "less_than_equal",
    "float_parsing", "float_type", "int_parsing", "int_type", "int_from_float",
}


def _did_you_mean(model: type[BaseModel] | None, key: str) -> str:
    """`key` with its last part replaced by the closest known key of `model`, or ''. A section's
    key run together with its section's name (`tape_widht_m` for `tape.width_m`) is found too."""
    if model is None:
        return ""
    *parents, name = key.split(".")
    candidates = {known: known for known in model.model_fields}
    for known, field in model.model_fields.items():
        if (sub := _submodel(field.annotation)) is not None:
            candidates.update({f"{known}_{inner}": f"{known}.{inner}"
                               for inner in sub.model_fields})
    close = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    return ".".join([*parents, candidates[close[0]]]) if close else ""


def describe_validation_error(
    source: str,
    err: Mapping[str, Any],
    model: type[BaseModel] | None = None,
    unknown_key_hint: str = "",
    prefix: Sequence[str | int] = (),
) -> str:
    """One line for one pydantic error of `model`: `source: key = value: what was expected`.

    `prefix` is prepended to the key as shown (e.g. a scenario's `config.` block) but not used to
    look the key up in `model`."""
    loc = tuple(err["loc"])
    # as any name from a file: one line, whatever it holds (a key of ESC, BEL and a newline had
    # set the terminal's title and forged a second error line; one of 900 000 characters was
    # shown whole: an attacker's review)
    key = shorten(shown_name(".".join(str(part) for part in (*prefix, *loc)))) or "(top level)"
    holder, field = _locate(model, loc) if model is not None else (None, None)
    if err["type"] == "extra_forbidden":
        close = _did_you_mean(holder, key)
        hint = f": did you mean '{close}'?" if close else unknown_key_hint
        return f"{source}: unknown key '{key}'{hint}"
    if err["type"] == "missing":  # pydantic's input is then the mapping that lacks the key
        return f"{source}: {key}: missing (a required key)"
    shown = shown_value(err.get("input"))
    message = str(err["msg"])
    if err["type"] == "model_type":  # pydantic names its class: "... instance of TapeConfig"
        message = "expected a mapping of its keys, indented below it"
        if err.get("input") is None:  # `perception:` with every line under it commented out
            shown = "(empty)"
            message += f", or no '{loc[-1]}:' line at all" if loc and isinstance(loc[-1], str) \
                else ""
    if message.startswith("Value error, "):
        message = message[len("Value error, "):]
    message = message[:1].lower() + message[1:]
    if field is not None and loc and isinstance(loc[-1], str) and err["type"] in _RANGE_ERRORS:
        kind, allowed = _number_kind(field), allowed_range(field)
        if kind is not None and allowed:
            message = f"expected {kind} with {allowed}"
    if err["type"] in ("literal_error", "enum") and isinstance(err.get("input"), str):
        # a misspelt name among many ('camera_freez' among 26 fault kinds): the closest first
        named = re.findall(r"'([^']*)'", str((err.get("ctx") or {}).get("expected", "")))
        closest = difflib.get_close_matches(err["input"], named, n=1, cutoff=0.6)
        if closest:
            message = f"did you mean '{closest[0]}'? ({message})"
    if err["type"] == "value_error" and isinstance(err.get("input"), Mapping):
        # a section's own check of several of its keys: the message names them ("perception:
        # edges.look_ahead_m (5) must lie within ..."), "= a mapping" would say nothing
        return f"{source}: {key}: {message}"
    return f"{source}: {key} = {shown}: {message}"


def validation_error_lines(
    source: str,
    exc: ValidationError,
    model: type[BaseModel] | None = None,
    unknown_key_hint: str = "",
    prefix: Sequence[str | int] = (),
) -> str:
    """Every problem of `exc`, one line each, at most MAX_PROBLEM_LINES of them (a file that is
    not this kind of document at all, say a password file named as a scenario, would otherwise
    echo every line of it)."""
    errors = exc.errors()
    lines = [describe_validation_error(source, err, model, unknown_key_hint, prefix)
             for err in errors[:MAX_PROBLEM_LINES]]
    if len(errors) > MAX_PROBLEM_LINES:
        lines.append(f"{source}: ... and {len(errors) - MAX_PROBLEM_LINES} more problems")
    return "\n".join(lines)
