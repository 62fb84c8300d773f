"""`td2adaptor scaffold ros2` on the second example robot (examples/nav_base, real rclpy ActionServers on ROS 2
Jazzy): its three ROS actions scaffold to TD actions, its std_srvs services and topics to actions and
properties, with the ROS names, types and data schemas of the hand-written example TD; the result validates
and passes the W3C TD schema.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.examples.nav_base import EXAMPLE, INTERFACES
from tests.ros2 import env
from tests.ros2.common import Process
from tests.scaffold.common import compiled_errors, scaffold, w3c_errors, without_texts

pytest_plugins = ["tests.ros2.fixtures", "tests.examples.nav_base_fixtures"]  # ros2_domain, nav_prefix

ROBOT = "scaf_nav"


@pytest.fixture(scope="module")
def nav_robot(nav_prefix: Path) -> Iterator[Process]:
    args = [sys.executable, "-m", "examples.nav_base.sim.ros2", "--prefix", str(nav_prefix), "--namespace", ROBOT]
    process = Process([*args, "--run-for", "600"], env.child_env([nav_prefix]))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=60)
        yield process
    finally:
        process.stop()


def _endpoints(doc: dict[str, Any]) -> dict[str, tuple[str, str, str, Any, Any]]:
    """ROS name (robot namespace left out) → (section, interface, type, input/value schema, output schema)."""
    out = {}
    for section in ("actions", "properties"):
        for aff in doc.get(section, {}).values():
            form = aff["forms"][0]
            name = form["rosv:name"].replace("{{robotName}}", "").replace(f"/{ROBOT}/", "/")
            if section == "properties":
                schema: Any = {k: aff.get(k) for k in ("type", "properties")}
                out[name] = (section, form.get("rosv:interface", "topic"), form["rosv:type"], schema, None)
            else:
                out[name] = (section, form.get("rosv:interface", "service"), form["rosv:type"], aff.get("input"),
                             aff.get("output"))  # fmt: skip
    return {k: (s, i, t, without_texts(a), without_texts(b)) for k, (s, i, t, a, b) in out.items()}


def test_the_nav_base_robot_scaffolds_to_its_example_td(nav_robot: Process, tmp_path: Path) -> None:
    done = scaffold(["ros2", "-I", str(INTERFACES), "--node", f"/{ROBOT}/nav_base_sim", "--title", "Nav Base"],
                    tmp_path / "td.json")  # fmt: skip
    assert done.code == 0, done.stderr
    doc = done.doc
    assert doc is not None
    import json

    example = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    mine, theirs = _endpoints(doc), _endpoints(example)
    # the intended difference (docs/scaffold.md): BatteryState's POWER_SUPPLY_* constants give enums the
    # example's hand-written schema does not have
    battery = mine["//battery_state"][3]["properties"]
    for field in ("power_supply_status", "power_supply_health", "power_supply_technology"):
        assert battery[field].pop("enum"), field
    assert sorted(mine) == sorted(theirs)
    kinds = sorted(i for _, i, *_ in mine.values())
    assert kinds.count("action") == 3  # NavigateToPose, DockRobot, UndockRobot: ROS actions as TD actions
    for name, (section, interface, rostype, first, second) in theirs.items():
        assert mine[name][:3] == (section, interface, rostype), name
        assert mine[name][3:] == (first, second), name
    assert compiled_errors(doc, tmp_path, [INTERFACES]) == []
    assert w3c_errors(doc) == []
