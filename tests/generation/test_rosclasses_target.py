"""A target of several RosClasses config files (service.json + topic.json) is ONE input, as in validate/migrate.

`compiler.build` used to compile each file of a target separately, so the two halves of one configuration
generated two different packages of the same name (GEN805) instead of one adaptor with every class.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from click.testing import CliRunner

from td2adaptor.cli.main import cli
from td2adaptor.compiler.build import check, generate, target
from td2adaptor.diagnostics import Severity
from tests.conftest import EXAMPLE, REPO

LEGACY = REPO / "tests" / "data" / "legacy"
CONFIG = [LEGACY / "service.json", LEGACY / "topic.json"]
IFACES = [EXAMPLE / "interfaces"]


def test_gen_then_check_of_service_and_topic_config(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    args = [*map(str, CONFIG), "-I", str(IFACES[0]), "-o", "out", "--partial", "--no-cache"]
    gen = CliRunner().invoke(cli, ["gen", *args])
    assert gen.exit_code == 0, gen.output
    assert "GEN805" not in gen.output
    components = (tmp_path / "out/rclpy/ros_edge_node_adaptor/ros_edge_node_adaptor/components.py").read_text()
    for cls in ("GoToComponent", "PickComponent", "AvailibilityComponent", "Ar_pose_markerComponent", "DoorComponent"):
        assert f"class {cls}" in components, cls
    check = CliRunner().invoke(cli, ["check", *args])
    assert (check.exit_code, check.output) == (0, "td2adaptor check: generated code is current\n")


def test_library_build_merges_config_files_and_points_backend_warnings_into_them(tmp_path: Path) -> None:
    job = target(CONFIG, backends=["mros"], output=tmp_path, interfaces=IFACES, partial=True)
    # the mROS tree is stated to take the RB-1 types' TCPROS headers (MROS914 otherwise)
    job = dataclasses.replace(job, options=(("mros.tcpros_header_max", 8192),))
    outcome = generate([job], use_cache=False)
    assert outcome.ok, [d.message for d in outcome.diagnostics]
    (skipped,) = [d for d in outcome.diagnostics if d.code == "MROS900"]
    assert skipped.severity is Severity.WARNING and "skipped 6 actions bound to services" in skipped.message
    # the warning points at the first service client in service.json, where the user wrote it
    assert Path(str(skipped.file)).resolve() == CONFIG[0]
    assert skipped.pointer == "/RosClasses/0/ServceClients/0" and skipped.line
    assert check([job], use_cache=False).ok


@pytest.mark.parametrize("order", [CONFIG, CONFIG[::-1]])
def test_the_merged_config_is_one_package_whatever_the_order(tmp_path: Path, order: list[Path]) -> None:
    outcome = generate([target(order, backends=["events"], output=tmp_path, interfaces=IFACES)], use_cache=False)
    assert outcome.ok, [d.message for d in outcome.diagnostics]
    folder = tmp_path / "events" / "ros_edge_node_adaptor"  # one package: one folder of the events output
    schemas = sorted(p.name.split(".")[0] for p in (folder / "schemas").glob("*Component.*"))
    assert schemas == [
        "Ar_pose_markerComponent",
        "AvailibilityComponent",
        "DoorComponent",
        "GoToComponent",
        "PickComponent",
    ]


def test_td_targets_still_compile_each_td_alone(tmp_path: Path) -> None:
    """Two TDs of one target are two inputs: the same TD twice generates the same files (no GEN805)."""
    td = EXAMPLE / "td.json"
    job = target([td, td], backends=["events"], output=tmp_path, interfaces=IFACES, partial=True)
    outcome = generate([job], use_cache=False)
    assert outcome.ok, [d.message for d in outcome.diagnostics]


DOOR = REPO / "examples" / "warehouse" / "door.td.json"


@pytest.mark.parametrize(
    "order", [[*CONFIG, DOOR], [CONFIG[0], DOOR, CONFIG[1]]], ids=["configs_then_td", "td_between_configs"]
)
def test_config_files_and_a_td_in_one_target_make_two_packages(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, order: list[Path]
) -> None:
    """All RosClasses files of a target are one input wherever they stand, and each TD is its own: the
    migrating user's service.json + topic.json + door TD generate both adaptors into one output."""
    monkeypatch.chdir(tmp_path)
    args = [*map(str, order), "-I", str(IFACES[0]), "-b", "rclpy", "-o", "out", "--partial", "--no-cache"]
    gen = CliRunner().invoke(cli, ["gen", *args])
    assert gen.exit_code == 0, gen.output
    assert "GEN805" not in gen.output
    packages = sorted(p.name for p in (tmp_path / "out" / "rclpy").iterdir() if p.is_dir())
    assert packages == ["ros_edge_node_adaptor", "warehouse_door_adaptor"]
    components = (tmp_path / "out/rclpy/ros_edge_node_adaptor/ros_edge_node_adaptor/components.py").read_text()
    assert "class GoToComponent" in components and "class DoorComponent" in components
    check = CliRunner().invoke(cli, ["check", *args])
    assert (check.exit_code, check.output) == (0, "td2adaptor check: generated code is current\n")


def test_a_collision_between_inputs_is_located_at_a_file(tmp_path: Path) -> None:
    job = target([*CONFIG, DOOR], backends=["events"], output=tmp_path, interfaces=IFACES, package_name="same")
    outcome = generate([job], use_cache=False)
    assert not outcome.ok
    collisions = [d for d in outcome.diagnostics if d.code == "GEN805"]
    assert collisions
    assert {d.file for d in collisions} == {str(DOOR)}, "at the input that collided, never <input>"
    readme = tmp_path / "events" / "same" / "README.md"
    assert any(
        d.message == f"two inputs generate different {readme} (the other: {CONFIG[0]}, {CONFIG[1]})" for d in collisions
    )
