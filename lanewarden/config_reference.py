"""The configuration reference (docs/configuration.md), generated from the config models.

Each layer documents its keys where they are defined (`Field(description=...)`); this module walks
the assembled `LanewardenConfig` and writes one table per section, so the reference cannot drift
from the code. A test regenerates it and fails when the committed file is stale.
"""

from __future__ import annotations

import json
from collections.abc import Iterator

from pydantic import BaseModel

from lanewarden.config import LanewardenConfig, walk_config

HEADER = """# Configuration reference

Generated from the config models by `python -m lanewarden.config_reference > docs/configuration.md`
(a test fails when this file is stale). Every key is optional; a YAML file only needs the keys it
changes. Units are in the names (`_s` seconds, `_m` metres, `_px` pixels, `_norm` fractions of the
image size, `_frac_of_width`/`_frac_of_height` fractions of the image width/height).
`lanewarden config show` prints the effective values. Every number must be finite and within the
range in the "allowed" column (a value outside it, `.inf` or `.nan` is refused at start-up with
one line naming the key and the range): the upper bounds are what a safe robot never needs to
exceed.
"""


def _format_default(value: object) -> str:
    text = json.dumps(value, default=str)
    return f"`{text}`"


def config_keys(model: BaseModel) -> Iterator[tuple[str, object, str]]:
    """(dotted key, default, description) for every leaf key, in declaration order."""
    for node in walk_config(model):
        if not node.is_section:
            yield ".".join(node.path), node.value, node.description


def render_reference(config: LanewardenConfig | None = None) -> str:
    config = config or LanewardenConfig()
    lines = [HEADER]
    for node in walk_config(config):
        if node.is_section and len(node.path) == 1:
            if len(lines) > 1:
                lines.append("")
            lines.append(f"## `{node.path[0]}`\n")
            if node.description:
                lines.append(node.description + "\n")
            lines.append("| key | default | allowed | meaning |")
            lines.append("|---|---|---|---|")
        elif not node.is_section:
            key = ".".join(node.path)
            allowed = f"`{node.allowed}`" if node.allowed else ""
            lines.append(
                f"| `{key}` | {_format_default(node.value)} | {allowed} | {node.description} |"
            )
    lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    print(render_reference(), end="")
