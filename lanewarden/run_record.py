"""A recorded step: what the control loop received and decided, as one JSON object, and the strict
reading of it back.

A recorded step is the step's `StepRecord.as_json()` (the same fields as `sim`'s run.jsonl, for
plots and reading) plus `"input"`: everything the loop took in from outside during that step, at
full precision, so `lanewarden replay` can feed it back on a fake clock and get the same steps
again (openpilot's process replay records at the same kind of boundary):

- `t`: the step's `now`;
- `frame`: `[index, time_s]` of the newest frame the source returned (None: none), or
  `frame_error`: `[exception type, message]` when the source raised;
- `feedback`: the base's feedback (`received_at_s`, bits, battery, odometry, and `stop_latched`
  when the base's own safety monitor held a stop), or `feedback_error`;
- `send_errors`: how many sends to the base failed during the step;
- `requests`: the operator requests the controller saw this step (`start`, `resume`, `stop`);
- `command`: the command the controller decided, `[linear, angular]` unrounded;
- at the step a frame was new (format 3): `frame_fingerprint`, the supervisor's fingerprint of
  the camera's frame (`supervisor.watchdog.frame_fingerprint`, hex), which its repeated and
  frozen image checks compare; a replay from recorded images that are not the camera's own
  (perception's prepared input, or the gray version of a colour frame) compares these instead,
  so it decides exactly as the run did; and `frame_refused`: `[exception type, message]` when
  perception could not prepare the frame (no image is recorded for it; replay raises the same).

Formats 2 and 3 keep each step in `run.mcap` (the `record` field of a `/lanewarden/step`
message, see lanewarden/run_mcap.py); format 3 (today's) adds the two frame fields above and, by
default, records perception's prepared input instead of the camera's gray frame; format 1 kept
the steps as the lines of `run.jsonl`.
`read_step` checks every field a replay uses (types, finite numbers, known requests) and says
which one is wrong in one line (`StepError`); `StepTimes` checks that step times increase within
a bounded duration. A recording is input like any other file: nothing in it may crash the reader
or make it run for long.

Pure data and (de)serialisation: no files, no threads, no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from lanewarden.actuation.base import BaseFeedback, Pose2D
from lanewarden.documents import shown_value
from lanewarden.supervisor.loop import StepRecord

#: Bump when a recorded step's meaning or the run folder's layout changes; replay reads the
#: formats in READABLE_FORMATS and refuses others.
FORMAT_VERSION = 3
READABLE_FORMATS = (1, 2, FORMAT_VERSION)
REQUESTS = ("start", "resume", "stop")
#: The longest run a recording may span (step times, first to last). A real run ends with its
#: battery long before; a longer span is a damaged or forged recording.
MAX_RUN_DURATION_S = 24 * 3600.0
#: Most steps a replay reads (about 9 hours at 30 Hz): a replay holds every step in memory.
MAX_STEPS = 1_000_000
#: Longest recorded step in bytes of JSON (a real one is about 1.5 kB).
MAX_STEP_BYTES = 64 * 1024
#: Farthest a base's odometry may say it went from where it started, metres.
MAX_ODOMETRY_M = 100_000.0
#: Longest text kept from a recorded exception message.
MAX_TEXT_CHARS = 2000
#: A recorded frame fingerprint: hex digits of `supervisor.watchdog.frame_fingerprint`'s 16 bytes.
FINGERPRINT_HEX = 32


class StepError(ValueError):
    """A recorded step that cannot be replayed: `str()` is `field = value: expected ...`."""


@dataclass(frozen=True)
class StepInput:
    """What came into the loop from outside during one step (see the module docstring)."""

    t: float
    frame: tuple[int, float] | None = None
    frame_error: tuple[str, str] | None = None
    feedback: BaseFeedback | None = None
    feedback_error: tuple[str, str] | None = None
    send_errors: int = 0
    requests: tuple[str, ...] = ()
    command: tuple[float, float] = (0.0, 0.0)
    frame_fingerprint: str | None = None
    frame_refused: tuple[str, str] | None = None


@dataclass(frozen=True)
class RecordedStep:
    """What a recorded step says the loop did, as replay compares it (frame, state, events, halt
    reason; the command is the input's, unrounded)."""

    frame_index: int | None
    state: str
    events: tuple[str, ...]
    halt_reason: str | None


def feedback_as_json(feedback: BaseFeedback) -> dict[str, Any]:
    pose = feedback.odometry
    return {
        "received_at_s": feedback.received_at_s,
        "bumper": feedback.bumper,
        "wheel_drop": feedback.wheel_drop,
        "cliff": feedback.cliff,
        "buttons": feedback.buttons,
        "battery_v": feedback.battery_v,
        "odometry": [pose.x_m, pose.y_m, pose.theta_rad],
        **({} if feedback.stop_latched is None else {"stop_latched": feedback.stop_latched}),
    }


def step_line(record: StepRecord, step_input: StepInput) -> dict[str, Any]:
    """One recorded step (a JSON-ready dict)."""
    line = record.as_json()
    inp: dict[str, Any] = {"t": step_input.t}
    inp["frame"] = None if step_input.frame is None else list(step_input.frame)
    if step_input.frame_error is not None:
        inp["frame_error"] = list(step_input.frame_error)
    inp["feedback"] = (None if step_input.feedback is None
                       else feedback_as_json(step_input.feedback))
    if step_input.feedback_error is not None:
        inp["feedback_error"] = list(step_input.feedback_error)
    if step_input.send_errors:
        inp["send_errors"] = step_input.send_errors
    if step_input.requests:
        inp["requests"] = list(step_input.requests)
    inp["command"] = list(step_input.command)
    if step_input.frame_fingerprint is not None:
        inp["frame_fingerprint"] = step_input.frame_fingerprint
    if step_input.frame_refused is not None:
        inp["frame_refused"] = list(step_input.frame_refused)
    line["input"] = inp
    return line


# ---- reading a step back, strictly -------------------------------------------------------------
def _bad(field: str, value: object, expected: str) -> StepError:
    return StepError(f"{field} = {shown_value(value)}: expected {expected}")


def _mapping(data: Any, field: str) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise _bad(field, data, "a mapping")
    return data


def _number(data: dict[str, Any], key: str, field: str, *, optional: bool = False) -> float | None:
    value = data.get(key)
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise _bad(field, value, "a finite number" + (" or null" if optional else ""))
    return float(value)


def _integer(data: dict[str, Any], key: str, field: str, low: int, high: int,
             default: int | None = None) -> int:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise _bad(field, value, f"an integer from {low} to {high}")
    return value


def _text(value: object, field: str, *, optional: bool = False) -> str | None:
    if value is None and optional:
        return None
    if not isinstance(value, str) or len(value) > MAX_TEXT_CHARS:
        raise _bad(field, value, f"a text of at most {MAX_TEXT_CHARS} characters"
                   + (" or null" if optional else ""))
    return value


def _pair(data: dict[str, Any], key: str, field: str) -> tuple[str, str] | None:
    value = data.get(key)
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != 2:
        raise _bad(field, value, "[exception type, message]")
    return str(_text(value[0], f"{field}[0]")), str(_text(value[1], f"{field}[1]"))


def _numbers(value: object, count: int, field: str) -> list[float]:
    if not isinstance(value, list) or len(value) != count:
        raise _bad(field, value, f"a list of {count} finite numbers")
    return [float(_number({"v": v}, "v", f"{field}[{i}]") or 0.0) for i, v in enumerate(value)]


def feedback_from_json(value: object) -> BaseFeedback | None:
    """A recorded step's `input.feedback` (None for null); StepError naming the field."""
    if value is None:
        return None
    data = _mapping(value, "input.feedback")
    x, y, theta = _numbers(data.get("odometry"), 3, "input.feedback.odometry")
    if max(abs(x), abs(y)) > MAX_ODOMETRY_M:
        raise _bad("input.feedback.odometry", [x, y, theta],
                   f"x and y within {MAX_ODOMETRY_M:.0f} m of where the base started")
    return BaseFeedback(
        received_at_s=_number(data, "received_at_s", "input.feedback.received_at_s",
                              optional=True),
        bumper=_integer(data, "bumper", "input.feedback.bumper", 0, 255),
        wheel_drop=_integer(data, "wheel_drop", "input.feedback.wheel_drop", 0, 255),
        cliff=_integer(data, "cliff", "input.feedback.cliff", 0, 255),
        buttons=_integer(data, "buttons", "input.feedback.buttons", 0, 255),
        battery_v=_number(data, "battery_v", "input.feedback.battery_v", optional=True),
        odometry=Pose2D(x, y, theta),
        stop_latched=_text(data.get("stop_latched"), "input.feedback.stop_latched",
                           optional=True),
    )


def _frame(value: object) -> tuple[int, float] | None:
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != 2:
        raise _bad("input.frame", value, "[index, time_s] or null")
    index = _integer({"i": value[0]}, "i", "input.frame[0]", 0, 2**32 - 1)
    time_s = _number({"t": value[1]}, "t", "input.frame[1]")
    assert time_s is not None
    return index, time_s


def _fingerprint(value: object) -> str | None:
    if value is None:
        return None
    if not (isinstance(value, str) and len(value) == FINGERPRINT_HEX
            and all(c in "0123456789abcdef" for c in value)):
        raise _bad("input.frame_fingerprint", value,
                   f"{FINGERPRINT_HEX} lowercase hexadecimal digits or null")
    return value


def read_step(line: object) -> tuple[StepInput, RecordedStep]:
    """A recorded step's input and what it says the loop did; StepError naming the first field
    that is missing or of the wrong type (one line)."""
    data = _mapping(line, "(the step)")
    inp = _mapping(data.get("input"), "input")
    t = _number(inp, "t", "input.t")
    assert t is not None
    requests = inp.get("requests", [])
    if not isinstance(requests, list) or not all(r in REQUESTS for r in requests):
        raise _bad("input.requests", requests, f"a list of {', '.join(REQUESTS)}")
    command = _numbers(inp.get("command", [0.0, 0.0]), 2, "input.command")
    step_input = StepInput(
        t=t,
        frame=_frame(inp.get("frame")),
        frame_error=_pair(inp, "frame_error", "input.frame_error"),
        feedback=feedback_from_json(inp.get("feedback")),
        feedback_error=_pair(inp, "feedback_error", "input.feedback_error"),
        send_errors=_integer(inp, "send_errors", "input.send_errors", 0, 1000, default=0),
        requests=tuple(requests),
        command=(command[0], command[1]),
        frame_fingerprint=_fingerprint(inp.get("frame_fingerprint")),
        frame_refused=_pair(inp, "frame_refused", "input.frame_refused"),
    )
    frame_index = data.get("frame_index")
    if frame_index is not None:
        frame_index = _integer(data, "frame_index", "frame_index", 0, 2**32 - 1)
    events = data.get("events")
    if not isinstance(events, list):
        raise _bad("events", events, "a list of event names")
    recorded = RecordedStep(
        frame_index=frame_index,
        state=str(_text(data.get("state"), "state")),
        events=tuple(str(_text(e, f"events[{i}]")) for i, e in enumerate(events)),
        halt_reason=_text(data.get("halt_reason"), "halt_reason", optional=True),
    )
    return step_input, recorded


class StepTimes:
    """Checks, step after step, that step times increase and stay within MAX_RUN_DURATION_S of
    the first (`check` returns the problem, '' when none)."""

    def __init__(self) -> None:
        self.first: float | None = None
        self.last: float | None = None

    def check(self, t: float) -> str:
        if self.first is None:
            self.first = self.last = t
            return ""
        assert self.last is not None
        if t <= self.last:
            return (f"input.t = {t!r}: expected a time after the previous step's "
                    f"({self.last!r}); step times must increase")
        if t - self.first > MAX_RUN_DURATION_S:
            span = t - self.first  # (a forged 1e300 had been printed as its 301 digits)
            shown = f"{span:.1f}" if span < 1e9 else f"{span:.3g}"
            return (f"input.t = {t!r}: {shown} s after the first step, more than a recording "
                    f"may span ({MAX_RUN_DURATION_S:.0f} s)")
        self.last = t
        return ""
