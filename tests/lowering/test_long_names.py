"""A `rosv:type` too long to name a file (its definition `Name.msg` could exist on no file system) is an error
with its reason, in validate and gen alike: it used to end in an internal error (`File name too long`) while the
hint looked for the installed definition."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from td2adaptor.cli.main import cli
from tests.lowering.test_distros import topic_td


@pytest.mark.parametrize(
    ("type_name", "said"),
    [
        ("std_msgs/msg/" + "A" * 260, "its file AAAAAAAAAAAA….msg would have a name of 264 characters"),
        ("a" * 256 + "/msg/Float32", "its package name has 256 characters"),
        ("std_msgs/msg/" + "B" * 251, None),  # B...B.msg has 255 characters: it fits, an unknown type
    ],
)
@pytest.mark.parametrize("command", ["validate", "gen"])
def test_a_type_name_too_long_for_a_file_is_an_error(
    tmp_path: Path, command: str, type_name: str, said: str | None
) -> None:
    td = tmp_path / "td.json"
    td.write_text(json.dumps(topic_td("Long", type_name, "level")), encoding="utf-8")
    args = [command, str(td), "--no-cache", *(["-o", str(tmp_path / "out")] if command == "gen" else [])]
    result = CliRunner().invoke(cli, args)
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert result.exit_code == 1, result.output
    assert "internal error" not in result.output and "File name too long" not in result.output
    if said is None:
        assert "ROS433" not in result.output and "error ROS423" in result.output
        return
    (line,) = [line for line in result.output.splitlines() if " error " in line]
    assert "error ROS433: property 'level': type " in line and said in line
    assert line.endswith("at /properties/level/forms/0/rosv:type")
    assert type_name not in result.output  # shortened: the message stays readable
