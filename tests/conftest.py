"""Shared test set-up: repository paths (the W3C reference data beside the repo: tests/wot_corpus.py)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from hypothesis import settings

# Property tests draw the same examples in every run (derandomize): a suite that passes must pass again; an
# exploring run is `pytest --hypothesis-profile explore` (random draws, as many as each test asks for).
settings.register_profile("default", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile("default")

# Tests never read or write the user's cache; the result cache gets its own tests.
os.environ["TD2ADAPTOR_CACHE_DIR"] = tempfile.mkdtemp(prefix="td2adaptor-test-cache-")

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "robotnik_rb1"
