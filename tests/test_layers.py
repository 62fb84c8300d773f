"""The pipeline's layering: the stages and the runtime never reach into a backend, generation or the CLI.

The event contract and the exposed TD are consumed by the runtime as well as the events backend, so they live
in `model/`; a stage importing from `backends/` (it happened twice) makes the folder tree lie about the pipeline.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "td2adaptor"
#: what each lower layer must not import (packages above it in the pipeline, or beside it as doors)
FORBIDDEN = ("td2adaptor.backends", "td2adaptor.generation", "td2adaptor.cli")
LAYERS = ("frontend", "rostypes", "lowering", "model", "runtime", "compiler", "diagnostics", "support")


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
    return found


@pytest.mark.parametrize("layer", LAYERS)
def test_a_stage_imports_no_backend_generation_or_cli(layer: str) -> None:
    bad = [
        f"{path.relative_to(PACKAGE.parent)}:{line}: {name}"
        for path in sorted((PACKAGE / layer).rglob("*.py"))
        if "verbatim" not in path.parts
        for line, name in _imports(path)
        if name.startswith(FORBIDDEN)
    ]
    assert bad == []


def test_the_scan_sees_a_forbidden_import(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from td2adaptor.backends.events.generator import dump\n", encoding="utf-8")
    assert _imports(module) == [(2, "td2adaptor.backends.events.generator")]
