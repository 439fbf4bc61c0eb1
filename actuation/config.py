"""Actuation's section of the one validated config (placeholder owned by the actuation work)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class ActuationConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
