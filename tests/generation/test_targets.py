"""One `targets()` for the CLI and the library: the same options override the project configuration the
same way, whichever door a user comes in by."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

import td2adaptor
from td2adaptor.backends import registry
from td2adaptor.cli.main import cli
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.targets import Options, Target, targets
from tests.conftest import EXAMPLE


@pytest.fixture(autouse=True)
def dummy_backend(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(registry.modules(), "dummy", "tests.generation.dummy_backend")


@pytest.fixture
def project(tmp_path: Path) -> Path:
    shutil.copytree(EXAMPLE, tmp_path / "rb1", ignore=shutil.ignore_patterns("sim"))
    (tmp_path / "extra").mkdir()
    (tmp_path / "td2adaptor.toml").write_text(
        'output = "out"\n\n[[target]]\ntds = ["rb1/td.json"]\nbackends = ["dummy"]\ninterfaces = ["rb1/interfaces"]\n'
        'values = { robotName = "a", other = 1 }\npackage-name = "configured_pkg"\n'
    )
    return tmp_path


def test_options_override_the_configuration(project: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(project)
    diags = Diagnostics()
    (kept,) = targets([], Options(), diags) or []
    assert kept == Target(
        tds=(Path("rb1/td.json"),),
        backends=("dummy",),
        output=Path("out"),
        interfaces=(Path("rb1/interfaces"),),
        values=(("other", 1), ("robotName", "a")),
        package_name="configured_pkg",
    )
    options = Options(
        backends=("all",),
        output=Path("elsewhere"),
        interfaces=(Path("extra"), Path("rb1/interfaces")),
        values=(("robotName", "b"),),
        package_name="given_pkg",
        partial=True,
        strict=True,
    )
    (changed,) = targets([], options, diags) or []
    assert changed == Target(
        tds=(Path("rb1/td.json"),),
        backends=("all",),
        output=Path("elsewhere"),
        interfaces=(Path("rb1/interfaces"), Path("extra")),  # added, not repeated
        values=(("other", 1), ("robotName", "b")),  # merged, the option wins
        package_name="given_pkg",
        partial=True,
        strict=True,
    )
    assert not list(diags)


def test_tds_given_use_the_options_and_defaults(project: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(project)
    (target,) = targets(["rb1/td.json"], Options(), Diagnostics()) or []
    assert (target.backends, target.output, target.package_name) == (("all",), Path("generated"), None)


def test_no_configuration_is_one_diagnostic(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    diags = Diagnostics()
    assert targets([], Options(), diags) is None
    assert [d.code for d in diags] == ["CFG907"]
    outcome = td2adaptor.generate()
    assert not outcome.ok and [d.code for d in outcome.diagnostics] == ["CFG907"]


def _files(root: Path) -> list[str]:
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file())


def test_cli_and_library_apply_options_to_the_configuration_alike(
    project: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(project)
    result = CliRunner().invoke(cli, ["gen", "--package-name", "given_pkg", "-o", "by_cli"])
    assert result.exit_code == 0, result.output
    outcome = td2adaptor.generate(package_name="given_pkg", output="by_api", config="td2adaptor.toml")
    assert outcome.ok, [d.message for d in outcome.diagnostics]
    assert not (project / "out").exists()  # neither fell back to the configured output
    by_cli, by_api = _files(project / "by_cli"), _files(project / "by_api")
    assert by_cli == by_api and "dummy/given_pkg/index.txt" in by_cli
    assert td2adaptor.check(package_name="given_pkg", output="by_cli").ok
    assert not td2adaptor.check(output="by_cli").ok  # the configured package name is not what is on disk
