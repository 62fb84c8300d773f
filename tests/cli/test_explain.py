"""`td2adaptor explain CODE`: the catalogue entry as text or JSON; unknown codes are a usage error."""

from __future__ import annotations

import json

from click.testing import CliRunner

from td2adaptor.cli.common import EXIT_USAGE
from td2adaptor.cli.main import cli
from td2adaptor.diagnostics.catalogue import lookup


def test_explain_prints_the_catalogue_entry() -> None:
    result = CliRunner().invoke(cli, ["explain", "TD000", "mros900"])
    assert result.exit_code == 0, result.output
    first, second = result.output.strip().split("\n\n")
    assert first.startswith(f"TD000 (error): {lookup('TD000').meaning}")
    assert "stage: TD0xx Reading the input" in first and "hint: check the path" in first
    assert second.startswith(
        "MROS900 (error; warning under --partial, which skips the actions: one warning lists them): "
    )


def test_explain_json() -> None:
    result = CliRunner().invoke(cli, ["explain", "--format", "json", "TM311"])
    assert result.exit_code == 0, result.output
    [entry] = json.loads(result.output)
    assert entry["code"] == "TM311" and entry["severities"] == ["error", "warning"]
    assert entry["meaning"] == lookup("TM311").meaning and entry["stage"] == "Thing Models"


def test_explain_unknown_code() -> None:
    result = CliRunner().invoke(cli, ["explain", "TD000", "XX999"])
    assert result.exit_code == EXIT_USAGE
    assert "unknown diagnostic code(s): XX999" in result.output
