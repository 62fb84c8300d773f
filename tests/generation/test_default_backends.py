"""`gen td.json` with no --backend makes every backend that can represent the TD and says what it skipped;
a backend named explicitly (or --strict) still fails. validate and gen agree on what is an error."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from td2adaptor.cli.main import cli
from tests.conftest import REPO

TD = str(REPO / "tests" / "golden" / "cases" / "std_robot" / "td.json")  # services: mROS cannot have them


def _gen(tmp_path: Path, *args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, ["gen", TD, "-o", str(tmp_path / "out"), "--no-cache", *args])
    return result.exit_code, result.output


def test_validate_and_the_default_gen_agree(tmp_path: Path) -> None:
    validated = CliRunner().invoke(cli, ["validate", TD, "--no-cache"])
    assert validated.exit_code == 0
    code, out = _gen(tmp_path)
    assert code == 0, out
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["events", "rclpy", "rospy"]
    assert "warning GEN807: mros backend skipped: it cannot represent this TD (MROS900" in out
    assert "-b mros shows every problem" in out


def test_the_same_with_all_named(tmp_path: Path) -> None:
    code, out = _gen(tmp_path, "-b", "all")
    assert code == 0 and "GEN807" in out


def test_a_backend_named_explicitly_still_fails(tmp_path: Path) -> None:
    code, out = _gen(tmp_path, "-b", "mros")
    assert code == 1 and "error MROS900" in out and "GEN807" not in out
    code, out = _gen(tmp_path, "-b", "all", "-b", "mros")
    assert code == 1 and "error MROS900" in out
    assert not (tmp_path / "out").exists()


def test_strict_does_not_skip(tmp_path: Path) -> None:
    code, out = _gen(tmp_path, "--strict")
    assert code == 1 and "MROS900" in out and not (tmp_path / "out").exists()


def test_partial_generates_what_mros_can(tmp_path: Path) -> None:
    # with the mROS tree's TCPROS buffer stated (upstream's 512 bytes cannot take LaserScan's header: MROS914)
    code, out = _gen(tmp_path, "--partial", "--option", "mros.tcpros_header_max=4096")
    assert code == 0 and (tmp_path / "out" / "mros").is_dir() and "GEN807" not in out
    code, out = _gen(tmp_path, "--partial")
    assert code == 0 and "warning GEN807: mros backend skipped" in out and "MROS914" in out


def test_a_backend_refusing_a_valid_td_does_not_call_it_invalid(tmp_path: Path) -> None:
    """The TD is valid (validate says so); `gen -b mros` fails because the backend cannot represent it: the
    verdict says that, not `invalid`, in the text and in JSON (`valid` true, with the verdict)."""
    code, out = _gen(tmp_path, "-b", "mros")
    assert code == 1
    assert out.splitlines()[-1].startswith(
        f"{TD}: valid, but the mros backend cannot generate it: nothing was written (6 errors, "
    ), out
    result = CliRunner().invoke(
        cli, ["gen", TD, "-o", str(tmp_path / "out"), "--no-cache", "-b", "mros", "-b", "rospy"]
    )
    assert "valid, but the mros backend cannot generate it" in result.output  # rospy could: not named
    result = CliRunner().invoke(
        cli, ["gen", TD, "-o", str(tmp_path / "out"), "--no-cache", "-b", "mros", "--format", "json"]
    )
    doc = json.loads(result.stdout)
    assert result.exit_code == 1 and doc["valid"] is True and doc["errors"] == 6
    assert doc["verdict"] == "valid, but the mros backend cannot generate it: nothing was written"
    result = CliRunner().invoke(cli, ["check", TD, "-o", str(tmp_path / "out"), "--no-cache", "-b", "mros"])
    assert (
        result.exit_code == 1 and "td.json: valid, but the mros backend cannot generate it (6 errors" in result.output
    )


def test_an_invalid_td_is_still_invalid(tmp_path: Path) -> None:
    td = json.loads(Path(TD).read_text(encoding="utf-8"))
    td["properties"]["odom"]["forms"][0]["rosv:type"] = "nav_msgs/msg/Odometri"
    (tmp_path / "td.json").write_text(json.dumps(td), encoding="utf-8")
    result = CliRunner().invoke(cli, ["gen", str(tmp_path / "td.json"), "-o", str(tmp_path / "out"), "-b", "mros"])
    assert result.exit_code == 1 and result.output.splitlines()[-1].startswith(f"{tmp_path / 'td.json'}: invalid (")


def test_every_backend_code_names_its_backend() -> None:
    from td2adaptor.cli.generate import _backend_of
    from td2adaptor.diagnostics.catalogue import CATALOGUE

    owners = {code: _backend_of(code) for code in CATALOGUE if code.startswith(("GEN", "MROS"))}
    assert {code for code, owner in owners.items() if owner == "rclpy"} == {"GEN820", "GEN821", "GEN822"}
    assert {code for code, owner in owners.items() if owner == "rospy"} == {"GEN840", "GEN841", "GEN842"}
    assert all(owners[code] == "mros" for code in owners if code.startswith("MROS"))
    assert owners["GEN805"] is None and owners["GEN802"] is None


def test_the_readme_first_command_says_the_configured_skip_once(tmp_path: Path) -> None:
    """The project's own configuration (partial mROS target): the nine skipped services are one line."""
    result = CliRunner().invoke(
        cli, ["gen", "--config", str(REPO / "pyproject.toml"), "-o", str(tmp_path / "out"), "--no-cache"]
    )
    assert result.exit_code == 0, result.output
    skipped = [line for line in result.output.splitlines() if "MROS900" in line]
    assert len(skipped) == 1 and "skipped 9 actions bound to services (--partial; mROS 1 has none)" in skipped[0]
