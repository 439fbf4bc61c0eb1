"""The slope filter's process noise in closed form equals filterpy's Q_discrete_white_noise."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.common import Q_discrete_white_noise

from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.slope_filter import process_noise


def test_closed_form_matches_the_literal_matrix_and_filterpy() -> None:
    config = SupervisorConfig()
    var = config.slope_sum_accel_std_per_s2**2
    q = process_noise(0.1, config)
    expected = var * np.array([[0.1**4 / 4, 0.1**3 / 2], [0.1**3 / 2, 0.1**2]])
    assert q == pytest.approx(expected, rel=1e-12)
    for dt in (0.0, 1 / 30, 0.25, 2.0):
        assert process_noise(dt, config) == pytest.approx(
            Q_discrete_white_noise(dim=2, dt=dt, var=var), rel=1e-12, abs=1e-15)
