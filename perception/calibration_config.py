"""Calibration quality gates: the calibration section of the one validated config
(placeholder owned by the calibration work)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class CalibrationConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
