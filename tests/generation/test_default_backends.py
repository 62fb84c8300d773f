"""`gen td.json` with no --backend makes every backend that can represent the TD and says what it skipped;
a backend named explicitly (or --strict) still fails. validate and gen agree on what is an error."""

from __future__ import annotations

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
