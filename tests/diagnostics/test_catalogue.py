"""The diagnostic catalogue: exactly the codes the source reports, severities as reported, docs current; a
backend's own codes (declared in its folder, registered on import) are part of it."""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from td2adaptor.backends import registry
from td2adaptor.cli.docs import DEFAULT_PATH, documented, main
from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity, catalogue
from td2adaptor.diagnostics.catalogue import CATALOGUE, STAGES, Entry, Stage, lookup, meanings, register, stage_of
from td2adaptor.diagnostics.docs import render
from tests.conftest import REPO

#: td2adaptor's own codes: the pipeline's and those of the backends it ships (a plug-in a test installed may
#: have added its own to this process's catalogue; tests/backends/toy checks those)
DOCUMENTED = documented()
OWN = {code: entry for code, entry in CATALOGUE.items() if entry.stage in DOCUMENTED}

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
    """Every code written in the source, but where a backend declares its codes (`Entry("MROS900", ...)`)."""
    declared = {
        id(node.args[0])
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "Entry" and node.args
    }
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and CODE.fullmatch(node.value):
            if id(node) not in declared:
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
    assert sorted(used - set(OWN)) == [], "reported but not in the catalogue"
    assert sorted(set(OWN) - used) == [], "in the catalogue but never reported"


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


@pytest.mark.parametrize("entry", OWN.values(), ids=list(OWN))
def test_entries_are_well_formed(entry: catalogue.Entry) -> None:
    assert CODE.fullmatch(entry.code) and entry.code.startswith(stage_of(entry.code).prefix)
    assert entry.meaning and "\n" not in entry.meaning and not entry.meaning.endswith(".")
    assert entry.severities and len(set(entry.severities)) == len(entry.severities)
    assert (entry.when is not None) == (len(entry.severities) > 1), "say when a code changes severity"
    assert entry.hint is None or (entry.hint and "\n" not in entry.hint)


def test_stages_and_views() -> None:
    stages = documented()
    assert len({s.prefix for s in stages}) == len(stages)
    assert all(any(stage_of(c) is s for c in OWN) for s in stages), "a stage without codes"
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
    assert main(["--check"]) == 0, "run: python -m td2adaptor.cli.docs"
    text = render(documented())
    assert all(f"| `{code}` |" in text for code in OWN)
    assert text.count("\n## ") == len(documented())


def test_docs_check_reports_a_stale_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "diagnostics.md"
    assert main(["--check", "--output", str(out)]) == 1
    assert "is not current" in capsys.readouterr().err
    assert main(["--output", str(out)]) == 0 and out.read_text(encoding="utf-8") == render(documented())
    assert main(["--check", "--output", str(out)]) == 0


def test_a_backend_declares_its_own_codes_in_its_folder() -> None:
    """The catalogue's module names no backend; the mROS codes are the mros backend's, registered on import."""
    assert not any(s.backend for s in STAGES) and not any(s.prefix.startswith("MROS") for s in STAGES)
    (mros,) = registry.diagnostic_stages(["mros"])
    assert mros.backend == "mros" and lookup("MROS900").stage is mros and mros in documented()
    assert "MROS9" not in (REPO / "td2adaptor" / "diagnostics" / "catalogue.py").read_text(encoding="utf-8")


def test_registering_a_stage_is_checked() -> None:
    """A backend's stage names its backend, has codes, keeps to its prefix and clashes with nothing."""
    warn = (Severity.WARNING,)
    cases = {
        "names its backend": (Stage("QQ1", "q", "q"), (Entry("QQ100", warn, "m"),)),
        "has no codes": (Stage("QQ1", "q", "q", backend="q"), ()),
        "overlaps 'TD0'": (Stage("TD", "q", "q", backend="q"), (Entry("TD099", warn, "m"),)),
        "does not start with the prefix": (Stage("QQ1", "q", "q", backend="q"), (Entry("QQ200", warn, "m"),)),
    }
    for problem, (stage, entries) in cases.items():
        with pytest.raises(ValueError, match=problem):
            register(stage, entries)
    assert not any(c.startswith("QQ") for c in CATALOGUE)
    (mros,) = registry.diagnostic_stages(["mros"])
    assert register(mros, tuple(e for c, e in CATALOGUE.items() if c.startswith("MROS"))) is mros  # again: no-op
