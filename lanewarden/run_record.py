"""The recorded run's per-step lines: what the control loop received and decided, in JSON.

A line of a run folder's `run.jsonl` is the step's `StepRecord.as_json()` (the same fields as
`sim`'s run.jsonl, for plots and reading) plus `"input"`: everything the loop took in from outside
during that step, at full precision, so `lanewarden replay` can feed it back on a fake clock and
get the same steps again (openpilot's process replay records at the same kind of boundary):

- `t`: the step's `now`;
- `frame`: `[index, time_s]` of the newest frame the source returned (None: none), or
  `frame_error`: `[exception type, message]` when the source raised;
- `feedback`: the base's feedback (`received_at_s`, bits, battery, odometry, and `stop_latched`
  when the base's own safety monitor held a stop), or `feedback_error`;
- `send_errors`: how many sends to the base failed during the step;
- `requests`: the operator requests the controller saw this step (`start`, `resume`, `stop`);
- `command`: the command the controller decided, `[linear, angular]` unrounded.

Pure data and (de)serialisation: no files, no threads, no clock.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from lanewarden.actuation.base import BaseFeedback, Pose2D, VelocityCommand
from lanewarden.supervisor.loop import StepRecord

#: Bump when a line's meaning changes; replay refuses formats it does not know.
FORMAT_VERSION = 1
REQUESTS = ("start", "resume", "stop")


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


def feedback_from_json(data: dict[str, Any]) -> BaseFeedback:
    x, y, theta = data["odometry"]
    latched = data.get("stop_latched")
    if latched is not None and not isinstance(latched, str):
        raise TypeError(f"stop_latched is {latched!r}: expected a string or nothing")
    return BaseFeedback(
        received_at_s=data["received_at_s"],
        bumper=int(data["bumper"]),
        wheel_drop=int(data["wheel_drop"]),
        cliff=int(data["cliff"]),
        buttons=int(data["buttons"]),
        battery_v=data["battery_v"],
        odometry=Pose2D(float(x), float(y), float(theta)),
        stop_latched=latched,
    )


def step_line(record: StepRecord, step_input: StepInput) -> dict[str, Any]:
    """One line of a run folder's run.jsonl (a JSON-ready dict)."""
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
    line["input"] = inp
    return line


def _pair(value: Any) -> tuple[str, str] | None:
    return None if value is None else (str(value[0]), str(value[1]))


def step_input_from_line(line: dict[str, Any]) -> StepInput:
    """The `input` of one recorded line; KeyError/TypeError/ValueError on a malformed one."""
    inp = line["input"]
    frame = inp.get("frame")
    feedback = inp.get("feedback")
    command = inp.get("command", [0.0, 0.0])
    requests = tuple(str(r) for r in inp.get("requests", ()))
    unknown = [r for r in requests if r not in REQUESTS]
    if unknown:
        raise ValueError(f"unknown operator request {unknown[0]!r}")
    return StepInput(
        t=float(inp["t"]),
        frame=None if frame is None else (int(frame[0]), float(frame[1])),
        frame_error=_pair(inp.get("frame_error")),
        feedback=None if feedback is None else feedback_from_json(feedback),
        feedback_error=_pair(inp.get("feedback_error")),
        send_errors=int(inp.get("send_errors", 0)),
        requests=requests,
        command=(float(command[0]), float(command[1])),
    )


def command_of(step_input: StepInput) -> VelocityCommand:
    return VelocityCommand(*step_input.command)
