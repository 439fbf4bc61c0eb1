"""What the live page's buttons are told (`OperatorPanel.started` / `armed`, in every status) and
that every operator request is announced the same way when it is made, whoever made it (keys,
the Kobuki's buttons, the page): the page's Stop included.

The page's rule (static/live.html, docs/operator.md): Start while nothing was started; Resume when
halted after the start with no start/resume waiting; Stop when moving or something is waiting."""

from __future__ import annotations

from lanewarden.actuation.base import BaseFeedback
from lanewarden.operator import (
    ButtonEdges,
    OperatorPanel,
    OperatorRequest,
    apply_buttons,
    halting_events,
)
from lanewarden.supervisor.events import Event


class Loop:
    def __init__(self) -> None:
        self.calls: list[str] = []

    def start(self, now: float) -> None:
        self.calls.append("start")

    def resume(self, now: float) -> None:
        self.calls.append("resume")

    def operator_stop(self, now: float) -> None:
        self.calls.append("stop")


def panel(**options: bool) -> tuple[OperatorPanel, list[str]]:
    said: list[str] = []

    def notify(request: OperatorRequest) -> None:
        said.append(f"{request.kind} requested ({request.source})")

    return OperatorPanel(Loop(), clock=lambda: 1.0, notify=notify, **options), said


def test_every_request_is_announced_when_it_is_made() -> None:
    p, said = panel()
    p.start("the run command")
    p.stop("page")
    p.resume("page")
    p.stop("key")
    edges = ButtonEdges()
    for buttons in (0, 2, 0, 1):
        apply_buttons(edges, BaseFeedback(received_at_s=0.0, buttons=buttons), p)
    assert said == ["start requested (the run command)", "stop requested (page)",
                    "resume requested (page)", "stop requested (key)",
                    "stop requested (button B1)", "resume requested (button B0)"]
    p.deliver(2.0)
    assert len(said) == 6, "delivering does not announce again"


def test_started_and_armed_follow_the_supervisor_latch() -> None:
    p, _ = panel()
    assert (p.started, p.armed) == (False, False), "Start enabled, Stop and Resume not"
    p.start("the run command")
    assert (p.started, p.armed) == (True, True), "queued: waiting to engage"
    p.deliver(1.0)
    p.observe("HALT", ())
    assert p.armed, "delivered, still halted: waiting for confident frames"
    p.observe("FOLLOW", ())
    assert not p.armed, "engaged: nothing waits (Stop is enabled because it moves)"
    p.observe("HALT", ("LANE_LOST",))
    assert not p.armed, "halted: Resume enabled"
    p.resume("page")
    p.deliver(2.0)
    p.observe("HALT", ("FRAME_LATE",))
    assert p.armed, "a warning or degrade event does not disarm"
    p.observe("HALT", ("OPERATOR_STOP",))
    assert not p.armed, "a new halting event disarms, as the supervisor's latch does"
    p.resume("page")
    p.deliver(3.0)
    p.observe("HALT", ("BUMPER",))
    assert not p.armed, "a request in the step of a hazard is undone by it"
    assert p.started


def test_a_lane_loss_rearms_itself_when_the_supervisor_does() -> None:
    p, _ = panel(auto_resume_after_lane_loss=True)
    p.start("key")
    p.deliver(1.0)
    p.observe("FOLLOW", ())
    p.observe("HALT", ("LANE_LOST",))
    assert p.armed, "auto_resume_after_lane_loss: it may engage again by itself (Stop enabled)"
    p.observe("HALT", ("BUMPER", "LANE_LOST"))
    assert not p.armed, "no other halt is forgiven"


def test_halting_events() -> None:
    assert halting_events(("LANE_LOST", "FRAME_LATE", "BATTERY_LOW", "OPERATOR_STOP",
                           "NOT_AN_EVENT")) == {Event.LANE_LOST, Event.OPERATOR_STOP}
