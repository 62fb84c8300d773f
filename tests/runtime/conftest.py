"""Fixtures of the edge-node tests."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.runtime.broker import Mosquitto


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Mosquitto]:
    """A real mosquitto of the test's own (test_mqtt.py overrides it with every broker it runs against)."""
    b = Mosquitto(tmp_path / "broker")
    b.start()
    yield b
    b.stop()
