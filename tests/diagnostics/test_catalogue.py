"""The diagnostic catalogue: exactly the codes the source reports, severities as reported, docs current."""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity, catalogue
from td2adaptor.diagnostics.catalogue import CATALOGUE, STAGES, lookup, meanings, stage_of
from td2adaptor.diagnostics.docs import DEFAULT_PATH, main, render
from tests.conftest import REPO

PACKAGE = REPO / "td2adaptor"
CODE = re.compile(r"[A-Z]{2,4}[0-9]{3}")
CATALOGUE_FILE = Path(catalogue.__file__).resolve()
# calls whose first code argument is followed by the severity in their name or as an argument
_BY_NAME = {"error": Severity.ERROR, "warning": Severity.WARNING, "info": Severity.INFO, "warn": Severity.WARNING}


def _sources() -> Iterator[tuple[Path, ast.Module]]:
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.resolve() != CATALOGUE_FILE:
            yield path, ast.parse(path.read_text(encoding="utf-8"), str(path))


def _code_literals(tree: ast.AST) -> Iterator[ast.Constant]:
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and CODE.fullmatch(node.value):
            yield node


def _stated_severity(call: ast.Call) -> Severity | None:
    """The severity a diagnostic call states: by method name (`diags.warning`) or a `Severity.X` argument."""
    name = call.func.attr if isinstance(call.func, ast.Attribute) else getattr(call.func, "id", "")
    if name in _BY_NAME:
        return _BY_NAME[name]
    for arg in [*call.args, *(k.value for k in call.keywords)]:
        if isinstance(arg, ast.Attribute) and isinstance(arg.value, ast.Name) and arg.value.id == "Severity":
            return Severity[arg.attr]
    return None


def test_catalogue_lists_exactly_the_codes_the_source_reports() -> None:
    used = {str(node.value) for _, tree in _sources() for node in _code_literals(tree)}
    assert sorted(used - set(CATALOGUE)) == [], "reported but not in the catalogue"
    assert sorted(set(CATALOGUE) - used) == [], "in the catalogue but never reported"


def test_reported_severities_are_catalogued() -> None:
    wrong = []
    checked = 0
    for path, tree in _sources():
        for call in (n for n in ast.walk(tree) if isinstance(n, ast.Call)):
            codes = [a.value for a in call.args if isinstance(a, ast.Constant) and isinstance(a.value, str)]
            codes = [c for c in codes if CODE.fullmatch(c)]
            if not codes:
                continue
            severity = _stated_severity(call)
            checked += severity is not None
            if severity is not None and severity not in lookup(codes[0]).severities:
                wrong.append(f"{path.relative_to(REPO)}:{call.lineno} {codes[0]} {severity.value}")
    assert wrong == []
    assert checked > 150, "the scan no longer sees the diagnostic calls"


@pytest.mark.parametrize("entry", CATALOGUE.values(), ids=list(CATALOGUE))
def test_entries_are_well_formed(entry: catalogue.Entry) -> None:
    assert CODE.fullmatch(entry.code) and entry.code.startswith(stage_of(entry.code).prefix)
    assert entry.meaning and "\n" not in entry.meaning and not entry.meaning.endswith(".")
    assert entry.severities and len(set(entry.severities)) == len(entry.severities)
    assert (entry.when is not None) == (len(entry.severities) > 1), "say when a code changes severity"
    assert entry.hint is None or (entry.hint and "\n" not in entry.hint)


def test_stages_and_views() -> None:
    assert len({s.prefix for s in STAGES}) == len(STAGES)
    assert all(any(stage_of(c) is s for c in CATALOGUE) for s in STAGES), "a stage without codes"
    assert set(meanings("TD25")) == {"TD251", "TD252", "TD253"}
    assert lookup("mros900").code == "MROS900"
    with pytest.raises(KeyError, match="not in td2adaptor.diagnostics.catalogue"):
        lookup("TD999")


def test_unknown_codes_are_refused() -> None:
    diags = Diagnostics()
    for report in (diags.error, diags.warning, diags.info):
        with pytest.raises(ValueError, match="'TD999' is not in td2adaptor.diagnostics.catalogue"):
            report("TD999", "a message")
    with pytest.raises(ValueError, match="not in td2adaptor.diagnostics.catalogue"):
        diags.append(Diagnostic("XY123", Severity.ERROR, "a message"))
    assert len(diags) == 0
    diags.warning("TD002", "input starts with a byte order mark")
    assert diags.codes() == ["TD002"]


def test_docs_are_current(capsys: pytest.CaptureFixture[str]) -> None:
    assert DEFAULT_PATH == REPO / "docs" / "diagnostics.md"
    assert main(["--check"]) == 0, "run: python -m td2adaptor.diagnostics.docs"
    text = render()
    assert all(f"| `{code}` |" in text for code in CATALOGUE)
    assert text.count("\n## ") == len(STAGES)


def test_docs_check_reports_a_stale_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "diagnostics.md"
    assert main(["--check", "--output", str(out)]) == 1
    assert "is not current" in capsys.readouterr().err
    assert main(["--output", str(out)]) == 0 and out.read_text(encoding="utf-8") == render()
    assert main(["--check", "--output", str(out)]) == 0
