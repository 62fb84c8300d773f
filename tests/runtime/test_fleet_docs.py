"""docs/fleet.md documents every runtime setting, with its environment variable, and its example loads."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from td2adaptor.runtime.config import RuntimeConfig, from_env, load_fleet
from tests.conftest import REPO

DOC = (REPO / "docs" / "fleet.md").read_text(encoding="utf-8")


def test_every_setting_is_a_row_with_its_environment_variable() -> None:
    rows = dict(re.findall(r"^\| `(\w+)` \|[^|]*\| `(TD2ADAPTOR_\w+)`", DOC, re.MULTILINE))
    assert sorted(rows) == sorted(f.name for f in dataclasses.fields(RuntimeConfig))
    for name, variable in rows.items():
        boolean = str(RuntimeConfig.__dataclass_fields__[name].type).startswith("bool")
        value = "1" if name in ("robot", "namespace") else "true" if boolean else "7"
        assert name in from_env({variable: value}), (name, variable)


def test_the_example_fleet_loads(tmp_path: Path) -> None:
    example = re.search(r"```yaml\n(.*?)```", DOC, re.DOTALL)
    assert example is not None
    path = tmp_path / "fleet.yaml"
    path.write_text(example.group(1))
    configs = load_fleet(path, env={})
    assert [(c.robot, c.ros_namespace, c.property_period) for c in configs] == [
        ("rb1_base_a", "rb1_base_a", 1.0),
        ("rb1_base_b", "rb1_base_b", 1.0),
        ("cart_bot", "rb1_base_c", 0.0),
    ]
    assert all(c.bus == "mqtt://broker.local:8883" and c.poll_period == 0.2 for c in configs)
    (only,) = load_fleet(path, env={}, overrides={"robot": "rb1_base_b"})
    assert only.robot == "rb1_base_b"


def test_an_empty_variable_is_unset(tmp_path: Path) -> None:
    path = tmp_path / "robot.yaml"
    path.write_text("robot: rb1\nbus: mqtt://broker:1883\ncall_timeout: 3\nallow_insecure: true\n")
    empty = {
        "TD2ADAPTOR_BUS": "",
        "TD2ADAPTOR_CALL_TIMEOUT": "",
        "TD2ADAPTOR_ALLOW_INSECURE": "",
        "TD2ADAPTOR_NAMESPACE": "",
    }
    assert from_env(empty) == {}
    config = load_fleet(path, env=empty)[0]
    assert (config.bus, config.call_timeout, config.allow_insecure, config.ros_namespace) == (
        "mqtt://broker:1883",
        3.0,
        True,
        "rb1",
    )
