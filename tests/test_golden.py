"""generated/<backend>/ holds the RB-1 example's output; regenerating must reproduce it byte for byte.

Refresh after an intended change (then review `git diff generated/`):
    .venv/bin/td2adaptor gen examples/robotnik_rb1/td.json -I examples/robotnik_rb1/interfaces -o generated
"""

from __future__ import annotations

import pytest

import td2adaptor
from td2adaptor.backends import available
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.emit import MANIFEST
from td2adaptor.generate import generate_trees

from .conftest import EXAMPLE, REPO

GOLDEN = REPO / "generated"


@pytest.mark.parametrize("backend", available())
def test_golden_files_are_current(backend: str) -> None:
    result = td2adaptor.compile(EXAMPLE / "td.json", interfaces=[EXAMPLE / "interfaces"])
    assert result.model is not None
    diags = Diagnostics()
    trees = generate_trees(result.model, [backend], diags)
    assert trees is not None, [d.message for d in diags if d.severity is Severity.ERROR]
    tree = trees[backend]
    root = GOLDEN / backend
    on_disk = {p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file() and p.name != MANIFEST}
    missing = sorted(set(tree.files) - on_disk)
    extra = sorted(on_disk - set(tree.files))
    changed = sorted(rel for rel, data in tree if rel in on_disk and (root / rel).read_bytes() != data)
    hint = "regenerate with the command in this module's docstring and review the diff"
    assert not (missing or extra or changed), f"missing {missing}, extra {extra}, changed {changed}: {hint}"


def test_every_backend_has_golden_files() -> None:
    assert sorted(p.name for p in GOLDEN.iterdir() if p.is_dir()) == sorted(available())
