"""Shared test set-up: repository paths (the W3C reference data beside the repo: tests/wot_corpus.py)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

# Tests never read or write the user's cache; the result cache gets its own tests.
os.environ["TD2ADAPTOR_CACHE_DIR"] = tempfile.mkdtemp(prefix="td2adaptor-test-cache-")

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "robotnik_rb1"
