"""docs/state-machine.md is generated from the code; this test keeps it from going stale."""

from __future__ import annotations

from lanewarden.supervisor.diagram import (
    DOC_PATH,
    REGENERATE,
    mermaid_diagram,
    state_machine_markdown,
)
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.state_machine import TRANSITIONS, SupervisorState


def test_mermaid_diagram_has_every_state_and_every_transition_row() -> None:
    text = mermaid_diagram()
    assert text.startswith("stateDiagram-v2")
    for state in SupervisorState:
        assert f'state "{state.value}" as {state.value}' in text
    for row in TRANSITIONS:
        sources = row["source"] if isinstance(row["source"], list) else [row["source"]]
        for source in sources:
            assert f"{source.value} --> {row['dest'].value}: tick [{row['conditions']}]" in text
    assert "[*] --> HALT" in text


def test_generated_doc_is_committed_and_current() -> None:
    fresh = state_machine_markdown()
    assert all(f"`{e.value}`" in fresh for e in Event)
    committed = DOC_PATH.read_text(encoding="utf-8") if DOC_PATH.exists() else ""
    if committed != fresh:
        DOC_PATH.write_text(fresh, encoding="utf-8")
    assert committed == fresh, (
        f"{DOC_PATH} was stale and has been regenerated: review and commit it "
        f"(regenerate with {REGENERATE})"
    )
