"""mROS capacities are settable (globally and per field) from the CLI, the project configuration and the
library, and a subscriber sized below what robots usually publish is a warning, not a silent info."""

from __future__ import annotations

import re
from pathlib import Path

from click.testing import CliRunner

import td2adaptor
from td2adaptor.cli.main import cli
from tests.conftest import REPO

TD = REPO / "tests" / "golden" / "cases" / "std_robot" / "td.json"  # scan: sensor_msgs/msg/LaserScan
RANGES = "mros.capacity.sensor_msgs/msg/LaserScan.ranges"
INTENSITIES = "mros.capacity.sensor_msgs/msg/LaserScan.intensities"
#: the case's mROS tree limit (its TCPROS headers need more than upstream's 512 bytes, MROS914)
TCPROS = "mros.tcpros_header_max"


def _pool_block(out: Path) -> int:
    config = (out / "mros" / "diffbot_adaptor" / "mros_config" / "mros_usr_config.h").read_text()
    # the pool for data received from other nodes: its largest block fits the largest subscribed message
    return max(int(n) for n in re.findall(r"ROS_OUTER_TOPIC_PUBLISHER_MEMPOOL\d_SIZE\s+(\d+)U", config))


def _gen(out: Path, *args: str) -> tuple[int, str]:
    result = CliRunner().invoke(
        cli,
        ["gen", str(TD), "-b", "mros", "--partial", "-o", str(out), "--no-cache", "--option", f"{TCPROS}=2048", *args],
    )
    return result.exit_code, result.output


def test_a_laser_scan_at_the_default_capacity_is_a_warning(tmp_path: Path) -> None:
    code, out = _gen(tmp_path / "out")
    assert code == 0
    assert "warning MROS913" in out and "LaserScan.ranges (8 of usually 720+)" in out
    assert f"--option {RANGES}=720" in out


def test_per_field_capacities_from_the_cli_size_the_pool(tmp_path: Path) -> None:
    _gen(tmp_path / "default")
    code, out = _gen(tmp_path / "sized", "--option", f"{RANGES}=720", "--option", f"{INTENSITIES}=720")
    assert code == 0 and "MROS913" not in out, out
    # a scan of 720 ranges and 720 intensities (float32) now fits the receive pool; at the default it did not
    assert _pool_block(tmp_path / "default") < 2 * 720 * 4 <= _pool_block(tmp_path / "sized")


def test_the_library_and_the_project_configuration_take_them_too(tmp_path: Path) -> None:
    outcome = td2adaptor.generate(
        TD,
        backends=["mros"],
        partial=True,
        output=tmp_path / "lib",
        options={RANGES: 720, INTENSITIES: 720, TCPROS: 2048},
    )
    assert outcome.ok and not [d for d in outcome.diagnostics if d.code == "MROS913"]
    (tmp_path / "td2adaptor.toml").write_text(
        f'[[target]]\ntds = ["{TD}"]\nbackends = ["mros"]\npartial = true\noutput = "cfg"\n'
        f'options = {{ "{RANGES}" = 720, "{INTENSITIES}" = 720, "{TCPROS}" = 2048 }}\n'
    )
    configured = td2adaptor.generate(config=tmp_path / "td2adaptor.toml")
    assert configured.ok
    lib = (tmp_path / "lib" / "mros" / "diffbot_adaptor" / "mros_config" / "mros_usr_config.h").read_bytes()
    assert lib == (tmp_path / "cfg" / "mros" / "diffbot_adaptor" / "mros_config" / "mros_usr_config.h").read_bytes()


def test_bad_capacity_options_are_diagnostics(tmp_path: Path) -> None:
    code, out = _gen(tmp_path / "out", "--option", "mros.capacity.sensor_msgs/msg/LaserScan.nope=5")
    assert code == 1 and "MROS912" in out and "has no field 'nope'" in out
    code, out = _gen(tmp_path / "out", "--option", "mros.capacity.sensor_msgs/msg/LaserScan.angle_min=5")
    assert code == 1 and "not an unbounded string or sequence" in out
    code, out = _gen(tmp_path / "out", "--option", "nobackend.x=1")
    assert code == 1 and "GEN808" in out
    code, out = _gen(tmp_path / "out", "--option", "novalue")
    assert code == 2 and "BACKEND.NAME=VALUE" in out
