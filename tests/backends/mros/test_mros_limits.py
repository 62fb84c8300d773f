"""mROS's protocol buffers: the sizes the generator computes, the diagnostics and the README's limits.

The oracle for the TCPROS header sizes is real ROS 1: Debian's rospy builds the connection headers a rospy
publisher answers with and a rospy subscriber connects with (`TCPROSPub`/`TCPROSSub.get_header_fields`,
encoded by `rosgraph.network.encode_ros_handshake_header`), for the RB-1 message classes genpy generated.
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from td2adaptor.backends.mros import generator as mros
from td2adaptor.backends.mros import limits
from td2adaptor.cli.main import cli
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.backend import GenOptions
from tests.backends.mros import apps
from tests.conftest import EXAMPLE
from tests.ros1 import harness
from tests.tools import require_ok

RB1 = EXAMPLE / "td.json"
#: Debian's ROS 1 packages install the .msg files of the standard interfaces here (share/<pkg>/msg/)
DEBIAN_MSGS = Path("/usr/share")
#: (module, class, type) of the RB-1 types checked against rospy: the subscribed ones and a small published one
TYPES = [
    ("robot_local_control_msgs.msg", "Status", "robot_local_control_msgs/msg/Status"),
    ("ar_track_alvar_msgs.msg", "AlvarMarkers", "ar_track_alvar_msgs/msg/AlvarMarkers"),
    ("std_msgs.msg", "String", "std_msgs/msg/String"),
]
_ROSPY = """
import importlib, json, sys
import rosgraph.network
from rospy.impl.tcpros_pubsub import TCPROSPub, TCPROSSub
out = []
for module, cls, topic in json.loads(sys.argv[1]):
    msg = getattr(importlib.import_module(module), cls)
    pub = rosgraph.network.encode_ros_handshake_header(TCPROSPub(topic, msg).get_header_fields())
    sub = rosgraph.network.encode_ros_handshake_header(TCPROSSub(topic, msg).get_header_fields())
    out.append({"reply": len(pub) - 4, "request": len(sub) - 4, "definition": msg._full_text, "md5": msg._md5sum})
print(json.dumps(out))
"""


def test_header_sizes_are_what_rospy_sends(tmp_path: Path) -> None:
    require_ok(harness.ros1_problem())
    topic = "/rb1_base/robot_local_control/state"
    args = json.dumps([(module, cls, topic) for module, cls, _ in TYPES])
    env = harness.ros_env("http://127.0.0.1:1", tmp_path, harness.interfaces_dir())
    proc = subprocess.run(
        [harness.SYSTEM_PYTHON, "-c", _ROSPY, args], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    if not (DEBIAN_MSGS / "std_msgs" / "msg" / "Header.msg").is_file():
        pytest.skip(f"Debian's ROS 1 message files are not in {DEBIAN_MSGS} (.ci/setup-ros1.sh)")
    # with the .msg files the ROS 1 side was generated from (comments included) the sizes are exact
    table = apps.compile_td(RB1, [apps.RB1_INTERFACES, DEBIAN_MSGS]).ros1
    for (_, _, type_name), got in zip(TYPES, json.loads(proc.stdout), strict=True):
        definition, estimated = limits.full_definition(table, type_name)
        md5 = table.ros1_digest(type_name).md5
        assert (definition, md5, estimated) == (got["definition"], got["md5"], ())
        ros1 = type_name.replace("/msg/", "/")
        # rospy's caller id before init_node is /unnamed
        fields = (topic, ros1, md5, definition, "/unnamed")
        assert limits.header_size(limits.publisher_reply(*fields)) == got["reply"]
        assert limits.header_size(limits.subscriber_request(*fields)) == got["request"]


def _plan_sizes(extra: tuple[tuple[str, Any], ...] = apps.TREE_LIMITS) -> dict[str, limits.TopicSizes]:
    made = mros.plan(apps.rb1().model, GenOptions(partial=True, extra=extra), Diagnostics())
    assert made is not None
    return {s.prop: s for s in made.context["sizes"]}


def test_upstream_limits_are_errors_with_the_fix() -> None:
    app = apps.generate(RB1, [apps.RB1_INTERFACES], tree_limits=False)
    errors = app.diags.errors()
    assert [(d.code, d.pointer) for d in errors] == [
        ("MROS914", "/properties/availability"),
        ("MROS914", "/properties/poseMarker"),
    ]
    sizes = _plan_sizes()
    status = sizes["availability"]
    assert f"has at least {status.tcpros} bytes (its message definition alone {status.definition};" in errors[0].message
    assert "a peer node name of up to 64 characters" in errors[0].message
    assert "MROS_PACKET_MAXSIZE_RES_TCPROS = 512 bytes of upstream mROS" in errors[0].message
    need = max(s.tcpros for s in sizes.values())
    for d in errors:
        assert f"to at least {need}, then state it: --option mros.tcpros_header_max={need}" in (d.hint or "")
    assert status.tcpros > 5000 and sizes["poseMarker"].tcpros > 1000 and sizes["door"].tcpros < 512
    # the sizes count the definition once, the peer name and the longest robot namespace in full; the types
    # of the built-in store (no .msg file) without comments: a lower bound, said so
    text, estimated = limits.full_definition(app.model.ros1, "robot_local_control_msgs/msg/Status")
    assert status.definition == len(text.encode()) and "# " in text  # the example's .msg comments count
    assert (
        status.estimated
        == tuple(n.replace("/msg/", "/") for n in estimated)
        == ("std_msgs/Header", "geometry_msgs/Pose2D")
    )
    assert (
        "has at least" in errors[0].message
        and "std_msgs/Header, geometry_msgs/Pose2D counted without comments" in errors[0].message
    )
    longer = _plan_sizes((*apps.TREE_LIMITS, ("mros.peer_name_max", 100)))
    assert longer["availability"].tcpros == status.tcpros + 36


def test_a_stated_limit_is_checked_too() -> None:
    app = apps.generate(RB1, [apps.RB1_INTERFACES], tree_limits=False, extra=(("mros.tcpros_header_max", 2048),))
    errors = app.diags.errors()
    assert [(d.code, d.pointer) for d in errors] == [("MROS914", "/properties/availability")]
    assert "the stated mros.tcpros_header_max of 2048 bytes" in errors[0].message
    # published topics: a rospy subscriber's header, into the publisher's buffer
    tiny = apps.generate(RB1, [apps.RB1_INTERFACES], extra=(("mros.tcpros_header_max", 64),))
    assert {d.code for d in tiny.diags.errors()} == {"MROS914", "MROS915"}
    door = next(d for d in tiny.diags.errors() if d.code == "MROS915")
    assert door.pointer == "/properties/door" and "MROS_PACKET_MAXSIZE_REQ_TCPROS" in (door.hint or "")
    # XML-RPC requests
    small = apps.generate(RB1, [apps.RB1_INTERFACES], extra=(("mros.xmlrpc_packet_max", 400),))
    xml = [d for d in small.diags.errors() if d.code == "MROS916"]
    assert xml and all("would never register" in d.message for d in xml)
    need = max(s.xmlrpc for s in _plan_sizes().values())
    assert f"--option mros.xmlrpc_packet_max={need}" in (xml[0].hint or "")


def test_a_stated_limit_that_only_covers_a_lower_bound_is_a_warning() -> None:
    """Types counted without comments give a lower bound: a stated limit under twice it may be overrun by a real
    peer (the RB-1 Status: 5,881 counted, 7,228 sent by Noetic's rospy), so MROS917 says so; twice it is trusted."""
    status = _plan_sizes()["availability"]
    assert status.estimated and status.tcpros < 8192 < 2 * status.tcpros
    app = apps.generate(RB1, [apps.RB1_INTERFACES], extra=(("mros.tcpros_header_max", 8192),))
    (warning,) = [d for d in app.diags if d.code == "MROS917"]
    assert warning.pointer == "/properties/availability" and f"at least {status.tcpros} bytes" in warning.message
    assert "std_msgs/Header, geometry_msgs/Pose2D" in warning.message and "-I" in (warning.hint or "")
    roomy = apps.generate(RB1, [apps.RB1_INTERFACES], extra=(("mros.tcpros_header_max", 2 * status.tcpros),))
    assert "MROS917" not in {d.code for d in roomy.diags}
    # the error's hint says to count exactly before raising the buffer
    refused = apps.generate(RB1, [apps.RB1_INTERFACES], tree_limits=False)
    assert all("pass the .msg files" in (d.hint or "") for d in refused.diags.errors())


def test_the_cli_refuses_and_the_readme_lists_the_limits(tmp_path: Path) -> None:
    base = ["gen", str(RB1), "-I", str(apps.RB1_INTERFACES), "-b", "mros", "--partial", "--no-cache"]
    refused = CliRunner().invoke(cli, [*base, "-o", str(tmp_path / "no")])
    assert refused.exit_code != 0 and "error MROS914" in refused.output
    assert not (tmp_path / "no" / "mros" / "robotnik_rb_1_adaptor" / "app.cpp").exists()
    ok = CliRunner().invoke(cli, [*base, "-o", str(tmp_path / "ok"), "--option", "mros.tcpros_header_max=6000"])
    assert ok.exit_code == 0, ok.output
    readme = (tmp_path / "ok" / "mros" / "robotnik_rb_1_adaptor" / "README.md").read_text()
    sizes = _plan_sizes()
    row = re.search(
        r"\| `availability` \| [^|]+ \| subscriber \| at least (\d+) bytes \| at least (\d+) bytes \| (\d+) bytes \|",
        readme,
    )
    assert row is not None
    assert [int(g) for g in row.groups()] == [
        sizes["availability"].tcpros,
        sizes["availability"].definition,
        sizes["availability"].xmlrpc,
    ]
    need = max(s.tcpros for s in sizes.values())
    assert f"| 512 | {need} | 6000 (stated: mros.tcpros_header_max) |" in readme
