"""Simulation section of the one validated config (placeholder owned by the scenarios work)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class SimulationConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
