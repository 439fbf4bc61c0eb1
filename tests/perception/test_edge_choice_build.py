"""The hot path's builders of frozen records make what the dataclasses' own constructors make.

`edge_choice._side_choice_of` and `confidence.edge_evidence` write the fields straight into the
instance (a frozen dataclass's `__init__` costs several times as much); a field added to either
dataclass and not to its builder would leave it out, which these catch."""

from __future__ import annotations

import dataclasses
import pickle

from lanewarden.perception.confidence import EdgeEvidence, edge_evidence
from lanewarden.perception.edge_choice import SideChoice, _side_choice_of


def _values(cls: type) -> list[object]:
    return [f"value of {f.name}" for f in dataclasses.fields(cls)]


def test_side_choice_of_builds_a_side_choice() -> None:
    values = _values(SideChoice)
    built = _side_choice_of(*values)  # type: ignore[arg-type]
    expected = SideChoice(*values)  # type: ignore[arg-type]
    assert type(built) is SideChoice
    assert built == expected and hash(built) == hash(expected)
    assert vars(built) == vars(expected)
    assert pickle.loads(pickle.dumps(built)) == expected


def test_edge_evidence_builds_edge_evidence() -> None:
    values = _values(EdgeEvidence)
    built = edge_evidence(*values)  # type: ignore[arg-type]
    expected = EdgeEvidence(*values)  # type: ignore[arg-type]
    assert type(built) is EdgeEvidence
    assert built == expected and hash(built) == hash(expected)
    assert vars(built) == vars(expected)
    assert pickle.loads(pickle.dumps(built)) == expected


def test_the_built_records_stay_frozen() -> None:
    built = _side_choice_of(*_values(SideChoice))  # type: ignore[arg-type]
    try:
        built.x1 = 0.0  # type: ignore[misc]
    except dataclasses.FrozenInstanceError:
        pass
    else:
        raise AssertionError("a built SideChoice took a new value")
