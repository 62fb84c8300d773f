"""ROS 1 actions in the type registry, checked against genaction + genpy output that Debian built: the md5
sums and definitions of an action's seven ROS 1 messages, from an `.action` file and from the typestore.

The `.action` files are rebuilt from the Debian modules' own definition texts (the goal, result and feedback
messages genaction wrote), so nothing here is a hard-coded number.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.rostypes import TypeRegistry
from td2adaptor.rostypes.names import hidden_action_part, ros1_action_messages, ros1_name
from tests.ros1 import harness
from tests.tools import require_ok

#: actions whose genpy modules Debian ships (python3-actionlib, python3-move-base-msgs)
DEBIAN_ACTIONS = ("actionlib/TwoInts", "actionlib/Test", "actionlib/TestRequest", "move_base_msgs/MoveBase")
_SUFFIXES = ("Goal", "Result", "Feedback", "Action", "ActionGoal", "ActionResult", "ActionFeedback")

_DUMP = """
import importlib, json, sys
out = {}
for action in sys.argv[1:]:
    package, name = action.split("/")
    module = importlib.import_module(package + ".msg")
    for suffix in SUFFIXES:
        cls = getattr(module, name + suffix)
        out[cls._type] = [cls._md5sum, cls._full_text]
print(json.dumps(out))
""".replace("SUFFIXES", repr(_SUFFIXES))


@pytest.fixture(scope="module")
def debian() -> dict[str, list[str]]:
    """ROS 1 type → [md5, full text] of every message of DEBIAN_ACTIONS, as Debian's genpy modules have them."""
    require_ok(harness.ros1_problem())
    out = harness.run_system_python(_DUMP, *DEBIAN_ACTIONS)
    assert out.returncode == 0, f"Debian's action messages are not importable (run .ci/setup-ros1.sh):\n{out.stderr}"
    found: dict[str, list[str]] = json.loads(out.stdout)
    return found


def _own_part(full_text: str) -> str:
    """The message's own definition in a genpy full text (before the first dependency), without the comment
    line genaction puts first."""
    own = full_text.split("\n" + "=" * 80 + "\n")[0]
    return "\n".join(line for line in own.splitlines() if not line.startswith("# ====== DO NOT MODIFY"))


_PRIMITIVES = frozenset(
    "bool byte char int8 uint8 int16 uint16 int32 uint32 int64 uint64 float32 float64 string time duration".split()
)


def _strip(text: str, package: str) -> list[str]:
    """Definition lines without comments and blank lines, field types spelled in full (`pkg/Name`), constants
    before fields in each message: genpy keeps the text as written (`Header`, `TwoIntsGoal`, constants anywhere),
    td2adaptor writes it in one canonical form (genmsg's md5 order)."""
    out: list[str] = []
    section: list[str] = []
    for raw in text.splitlines():
        line = " ".join(raw.split("#")[0].split()).replace(" = ", "=")
        if line.startswith("====="):
            out += sorted(section, key=lambda item: "=" not in item) + [line]
            section = []
            continue
        if line.startswith("MSG: "):
            package = line[5:].split("/")[0]
        elif line and "=" not in line:
            ftype, name = line.split(" ")
            base, bracket, rest = ftype.partition("[")
            if base == "Header":
                base = "std_msgs/Header"
            elif "/" not in base and base not in _PRIMITIVES:
                base = f"{package}/{base}"
            line = f"{base}{bracket}{rest} {name}"
        if line:
            section.append(line)
    return out + sorted(section, key=lambda item: "=" not in item)


def _action_folder(tmp_path: Path, debian: dict[str, list[str]]) -> Path:
    """An interface folder with each action's `.action` file, rebuilt from Debian's goal/result/feedback texts."""
    for action in DEBIAN_ACTIONS:
        package, name = action.split("/")
        sections = [_own_part(debian[f"{package}/{name}{part}"][1]) for part in ("Goal", "Result", "Feedback")]
        folder = tmp_path / package / "action"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / f"{name}.action").write_text("\n---\n".join(s.rstrip("\n") for s in sections) + "\n")
    return tmp_path


def _names(action: str) -> dict[str, str]:
    """ROS 1 type (`pkg/NameGoal`) → td2adaptor's canonical name of each of the action's messages."""
    package, name = action.split("/")
    canonical = f"{package}/action/{name}"
    parts = {f"{canonical}_{p}" for p in ("Goal", "Result", "Feedback")} | set(ros1_action_messages(canonical))
    return {ros1_name(n): n for n in parts}


@pytest.mark.parametrize("source", ["action files", "typestore"])
def test_ros1_action_messages_match_debian_genpy(tmp_path: Path, debian: dict[str, list[str]], source: str) -> None:
    diags = Diagnostics()
    folders = [_action_folder(tmp_path, debian)] if source == "action files" else []
    reg = TypeRegistry("ros1", folders, diags)
    assert not diags.has_errors, list(diags)
    # rosbags' Noetic typestore has actionlib's test actions, not move_base_msgs
    actions = DEBIAN_ACTIONS if source == "action files" else [a for a in DEBIAN_ACTIONS if a.startswith("actionlib/")]
    checked = 0
    for action in actions:
        package, name = action.split("/")
        assert reg.resolve(f"{package}/action/{name}") is not None, action
        for ros1, canonical in _names(action).items():
            md5, full_text = debian[ros1]
            text, digest = reg.ros1_definition(canonical)
            assert digest == md5, (source, canonical)
            # the same definitions, dependencies included (genpy keeps comments; td2adaptor writes none)
            assert _strip(text, package) == _strip(full_text, package), (source, canonical)
            checked += 1
    assert checked == 7 * len(actions) >= 21


def test_action_file_origin_and_typestore_agree_on_derived_names(tmp_path: Path) -> None:
    folder = tmp_path / "demo_msgs" / "action"
    folder.mkdir(parents=True)
    (folder / "Count.action").write_text("int32 to\n---\nint32 reached\n---\nint32 now\n")
    reg = TypeRegistry("ros1", [tmp_path])
    assert "demo_msgs/action/Count" in reg.known_names("action")
    assert {"demo_msgs/msg/CountAction", "demo_msgs/msg/CountActionGoal"} <= set(reg.known_names("msg"))
    table = reg.table(["demo_msgs/msg/CountActionFeedback"])
    assert [m.name for m in table.messages][:2] == ["demo_msgs/msg/CountActionFeedback", "std_msgs/msg/Header"]
    assert "demo_msgs/action/Count_Feedback" in [m.name for m in table.messages]
    # ROS 2 has no such messages: its actions travel on hidden services and a feedback topic instead
    assert TypeRegistry("ros2", [tmp_path]).resolve("demo_msgs/msg/CountActionGoal") is None


@pytest.mark.parametrize(
    ("raw", "expected"),
    [
        ("test_msgs/srv/Fibonacci_SendGoal", ("test_msgs/action/Fibonacci", "SendGoal")),
        ("test_msgs/action/Fibonacci_GetResult", ("test_msgs/action/Fibonacci", "GetResult")),
        ("test_msgs/action/Fibonacci_SendGoal_Request", ("test_msgs/action/Fibonacci", "SendGoal")),
        ("test_msgs/msg/Fibonacci_FeedbackMessage", ("test_msgs/action/Fibonacci", "FeedbackMessage")),
        ("test_msgs/Fibonacci_FeedbackMessage", ("test_msgs/action/Fibonacci", "FeedbackMessage")),
        ("test_msgs/srv/Fibonacci", None),
        ("test_msgs/action/Fibonacci_Goal", None),
    ],
)
def test_hidden_action_parts_name_their_action(raw: str, expected: tuple[str, str] | None) -> None:
    assert hidden_action_part(raw) == expected
