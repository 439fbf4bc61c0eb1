"""The composition root: one stack for `run` and `sim`, with the gate between every controller and
the base, and the decision rule using the supervisor's thresholds."""

from __future__ import annotations

import pytest

from lanewarden.actuation.base import STOP
from lanewarden.actuation.sim_base import SimBase
from lanewarden.assembly import DetectionTap, build_stack, decision_rule
from lanewarden.config import config_from_mapping
from lanewarden.perception.observation import LaneObservation
from lanewarden.supervisor.controller import SupervisedController
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.lecture import LectureController
from lanewarden.supervisor.loop import StepRecord
from tests.supervisor.rig import DT, LEFT_EDGE, RIGHT_EDGE, ScriptedCamera


@pytest.mark.parametrize(("name", "kind"), [("supervised", SupervisedController),
                                            ("lecture", LectureController)])
def test_every_controller_comes_wrapped_in_the_gate(name: str, kind: type) -> None:
    stack = build_stack(config_from_mapping({}), controller=name)
    assert isinstance(stack.controller, kind)
    assert stack.gate.controller is stack.controller
    assert stack.tap is None


def test_connect_builds_the_loop_that_sends_only_the_gates_output() -> None:
    records: list[StepRecord] = []
    stack = build_stack(config_from_mapping({}), controller="lecture", debug_tap=True)
    base = SimBase()
    loop = stack.connect(ScriptedCamera(size=(320, 240)), base, records.append)
    for k in range(5):  # not started: the lecture would drive, the gate holds it
        loop.step(k * DT)
    assert base.commanded == STOP and [r.state for r in records] == ["HALT"] * 5
    assert isinstance(stack.tap, DetectionTap) and stack.tap.last is not None  # real detector ran


def test_unknown_controller_is_one_line() -> None:
    with pytest.raises(SupervisorError, match="--controller: unknown controller 'pid'"):
        build_stack(config_from_mapping({}), controller="pid")


def test_the_decision_uses_the_supervisors_thresholds() -> None:
    config = config_from_mapping(
        {"supervisor": {"confidence_usable_min": 0.4, "turn_enter_slope_sum": 3.0,
                        "turn_exit_slope_sum": 2.0}})  # fmt: skip
    decide = decision_rule(config)

    def obs(slope_sum: float, confidence: float) -> LaneObservation:
        return LaneObservation(0, 0.0, LEFT_EDGE, RIGHT_EDGE, slope_sum, confidence)

    assert [decide(obs(3.5, 0.5)), decide(obs(-3.5, 0.5)), decide(obs(2.9, 0.5)),
            decide(obs(3.5, 0.39))] == ["left", "right", "straight", "none"]  # fmt: skip


def test_scenarios_never_import_the_cli_side_at_run_time() -> None:
    """The simulator receives `build_stack`; scenarios/ imports lanewarden's CLI side (assembly,
    commands, cli, runner) only for type checking."""
    import ast
    from pathlib import Path

    import lanewarden.scenarios as scenarios

    cli_side = ("lanewarden.assembly", "lanewarden.commands", "lanewarden.cli", "lanewarden.runner")
    offenders = []
    for path in sorted(Path(scenarios.__file__).parent.glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        type_only = {id(node) for block in ast.walk(tree) if isinstance(block, ast.If)
                     and ast.unparse(block.test) == "TYPE_CHECKING"
                     for node in ast.walk(block)}  # fmt: skip
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and id(node) not in type_only:
                if (node.module or "").startswith(cli_side):
                    offenders.append(f"{path.name}: {node.module}")
    assert offenders == []
