"""generated/<backend>/ holds the RB-1 example's output; regenerating must reproduce it byte for byte.

The example is configured in pyproject.toml ([tool.td2adaptor]); this checks it through `check`, the CLI's
own comparison. Refresh it with every other golden after an intended change, then review `git diff`:
    .venv/bin/python -m tests.golden --refresh
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from td2adaptor.backends.registry import available
from td2adaptor.compiler.build import check
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation import targets as config
from tests.conftest import REPO
from tests.golden.goldens import ADVICE

GOLDEN = REPO / "generated"


def _targets(backend: str) -> list[config.Target]:
    diags = Diagnostics()
    loaded = config.load(REPO / "pyproject.toml", diags)
    assert loaded is not None, [d.message for d in diags]
    return [replace(t, backends=(backend,)) for t in loaded.targets]


@pytest.mark.parametrize("backend", available())
def test_golden_files_are_current(backend: str) -> None:
    outcome = check(_targets(backend), use_cache=False)
    errors = [d.message for d in outcome.diagnostics if d.severity is Severity.ERROR]
    assert not errors
    assert outcome.ok, f"stale: {outcome.stale[:20]} — {ADVICE}"


def test_every_backend_has_golden_files() -> None:
    present = sorted(p.name for p in GOLDEN.iterdir() if p.is_dir()) if GOLDEN.is_dir() else []
    assert present == sorted(available())
