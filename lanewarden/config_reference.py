"""The configuration reference (docs/configuration.md), generated from the config models.

Each layer documents its keys where they are defined (`Field(description=...)`); this module walks
the assembled `LanewardenConfig` and writes one table per section, so the reference cannot drift
from the code. A test regenerates it and fails when the committed file is stale.
"""

from __future__ import annotations

import json
from collections.abc import Iterator

from pydantic import BaseModel

from lanewarden.config import LanewardenConfig

HEADER = """# Configuration reference

Generated from the config models by `python -m lanewarden.config_reference > docs/configuration.md`
(a test fails when this file is stale). Every key is optional; a YAML file only needs the keys it
changes. Units are in the names (`_s` seconds, `_m` metres, `_px` pixels, `_norm` fractions of the
image size, `_frac_of_width`/`_frac_of_height` fractions of the image width/height).
`lanewarden config show` prints the effective values.
"""


def _format_default(value: object) -> str:
    text = json.dumps(value, default=str)
    return f"`{text}`"


def config_keys(model: BaseModel, prefix: str = "") -> Iterator[tuple[str, object, str]]:
    """(dotted key, default, description) for every leaf key, in declaration order."""
    for name, field in type(model).model_fields.items():
        value = getattr(model, name)
        key = f"{prefix}{name}"
        if isinstance(value, BaseModel):
            yield from config_keys(value, f"{key}.")
        else:
            dumped = model.model_dump(mode="json", include={name})[name]
            yield key, dumped, (field.description or "").strip()


def render_reference(config: LanewardenConfig | None = None) -> str:
    config = config or LanewardenConfig()
    lines = [HEADER]
    for section in type(config).model_fields:
        model = getattr(config, section)
        summary = (type(model).__doc__ or "").strip().split("\n\n")[0]
        lines.append(f"## `{section}`\n")
        if summary:
            lines.append(" ".join(summary.split()) + "\n")
        lines.append("| key | default | meaning |")
        lines.append("|---|---|---|")
        for key, default, description in config_keys(model, f"{section}."):
            lines.append(f"| `{key}` | {_format_default(default)} | {description} |")
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    print(render_reference(), end="")
