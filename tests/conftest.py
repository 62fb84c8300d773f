"""Shared test fixtures: repository paths and the reference material beside the repo."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

# Tests never read or write the user's cache; the result cache gets its own tests.
os.environ["TD2ADAPTOR_CACHE_DIR"] = tempfile.mkdtemp(prefix="td2adaptor-test-cache-")

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
EXAMPLE = REPO / "examples" / "robotnik_rb1"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.fail(f"reference material not found at {SHARED}")
    return SHARED
