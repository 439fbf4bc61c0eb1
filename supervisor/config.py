"""Supervisor's section of the one validated config (placeholder owned by the supervisor work)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class SupervisorConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
