"""Perception's section of the one validated config. Every default lives here, with units in names.

(Placeholder owned by the perception work: fields are added there.)
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class PerceptionConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
