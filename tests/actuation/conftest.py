"""Fixtures for the actuation tests: the pty stand-in Kobuki."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.actuation.kobuki_standin import KobukiStandIn


@pytest.fixture
def standin() -> Iterator[KobukiStandIn]:
    with KobukiStandIn() as base:
        yield base
