"""`td2adaptor run` refuses a generated package that was not generated from the TD it is given (issue 34): the
package records its ports and the hash of its model (`ports.py`), the generated port compares them with the TD's
model and `run` says which command makes the package again, with one line and exit 1, no traceback."""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path
from typing import Any

from tests.runtime.edge import RunProcess
from tests.tools import require_module

require_module("rclpy", "the ros2 extra: bash .ci/setup-ros2.sh")

PACKAGE = "stale_bot_adaptor"


def _td() -> dict[str, Any]:
    def prop(name: str) -> dict[str, Any]:
        form = {
            "href": f"ros:{name}",
            "op": ["readproperty", "observeproperty"],
            "rosv:name": f"/{{{{robotName}}}}/{name}",
        }
        return {
            "rosv:component": "TalkComponent",
            "readOnly": True,
            "observable": True,
            "forms": [{**form, "rosv:type": "std_msgs/msg/String"}],
        }

    return {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "title": "Stale Bot",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "properties": {"chatter": prop("chatter")},
    }


def _gen(td: Path, out: Path) -> None:
    from click.testing import CliRunner

    from td2adaptor.cli.main import cli

    result = CliRunner().invoke(cli, ["gen", str(td), "-b", "rclpy", "-o", str(out), "--no-cache"])
    assert result.exit_code == 0, result.output


def test_run_refuses_a_stale_package_and_runs_once_it_is_regenerated(tmp_path: Path) -> None:
    td_path, out = tmp_path / "td.json", tmp_path / "out"
    td_path.write_text(json.dumps(_td()), encoding="utf-8")
    _gen(td_path, out)
    record = (out / "rclpy" / PACKAGE / PACKAGE / "ports.py").read_text(encoding="utf-8")
    assert "MODEL_HASH = " in record and '"chatter",' in record and str(tmp_path) not in record

    changed = copy.deepcopy(_td())
    changed["properties"]["status"] = {**changed["properties"]["chatter"]}
    changed["properties"]["status"]["forms"] = [{**changed["properties"]["chatter"]["forms"][0], "href": "ros:status"}]
    changed["properties"]["status"]["forms"][0]["rosv:name"] = "/{{robotName}}/status"
    td_path.write_text(json.dumps(changed), encoding="utf-8")
    args = [
        str(td_path),
        "--robot",
        "r1",
        "--bus",
        "local",
        "--package-path",
        str(out / "rclpy" / PACKAGE),
        "--no-cache",
    ]

    stale = RunProcess(args)
    try:
        assert stale.proc.wait(120) == 1, stale.output()
        lines = [
            line
            for line in stale.output().splitlines()
            if line.startswith("td2adaptor run:") and "warning:" not in line
        ]
        assert len(lines) == 1, stale.output()
        line = lines[0]
        assert f"the adaptor package {PACKAGE} was not generated from this Thing Description" in line
        assert "only in the TD: TalkComponent.status" in line
        assert f"`td2adaptor gen {td_path} -b rclpy -o DIR`" in line
        assert "Traceback" not in stale.output()
    finally:
        stale.close()

    _gen(td_path, out)  # as the message says
    assert (out / "rclpy" / PACKAGE / PACKAGE / "ports.py").read_text(encoding="utf-8") != record
    fresh = RunProcess(args)
    try:
        fresh.wait_ready(120)
    finally:
        fresh.close()


def test_the_record_is_the_same_byte_for_byte_wherever_and_whenever_it_is_made(tmp_path: Path) -> None:
    for where in ("a", "b/c"):
        folder = tmp_path / where
        folder.mkdir(parents=True)
        (folder / "td.json").write_text(json.dumps(_td()), encoding="utf-8")
        _gen(folder / "td.json", folder / "out")
    first, second = (
        (tmp_path / w / "out" / "rclpy" / PACKAGE / PACKAGE / "ports.py").read_bytes() for w in ("a", "b/c")
    )
    assert first == second
    assert sys.executable  # the record names no interpreter or path either
    assert str(tmp_path).encode() not in first
