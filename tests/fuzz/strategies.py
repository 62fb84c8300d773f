"""Hypothesis strategies for TDs in the td2adaptor binding (valid by construction) and a gen round trip.

Shared by tests/generation/test_fuzz_gen.py (a small sample in CI) and bench/fuzz.py (10,000 cases).
"""

from __future__ import annotations

import ast
import io
import json
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

import td2adaptor
from td2adaptor.backends.registry import available
from td2adaptor.compiler.build import generate_trees
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.lowering.rosnames import identifier_problem

SERVICES = ["std_srvs/srv/Trigger", "std_srvs/srv/SetBool", "std_srvs/srv/Empty"]
MESSAGES = [
    "std_msgs/msg/Float64",
    "std_msgs/msg/String",
    "std_msgs/msg/Bool",
    "std_msgs/msg/Int32",
    "geometry_msgs/msg/Pose2D",
    "geometry_msgs/msg/Twist",
    "sensor_msgs/msg/BatteryState",
]

_letters = st.sampled_from("abcdefghijklmnopqrstuvwxyz")
identifiers = st.builds(
    lambda first, rest: first + rest,
    _letters,
    st.text("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789", max_size=10),
).filter(lambda s: identifier_problem(s) is None)
class_names = identifiers.map(lambda s: s[:1].upper() + s[1:] + "Component").filter(
    lambda s: identifier_problem(s) is None
)
ros_tokens = st.builds(
    lambda a, b: a + b,
    _letters,
    st.text("abcdefghijklmnopqrstuvwxyz0123456789", max_size=8).filter(lambda s: "__" not in s),
)
ros_names = st.builds(
    lambda ns, parts: ("/{{robotName}}/" if ns else "/") + "/".join(parts),
    st.booleans(),
    st.lists(ros_tokens, min_size=1, max_size=3),
)
free_text = st.text(max_size=40)


@st.composite
def binding_tds(draw: st.DrawFn) -> dict[str, Any]:
    """A TD in the binding with 1..8 affordances over 1..3 components; names unique, types known."""
    components = draw(st.lists(class_names, min_size=1, max_size=3, unique=True))
    names = draw(st.lists(identifiers, min_size=1, max_size=8, unique=True))
    actions: dict[str, Any] = {}
    properties: dict[str, Any] = {}
    used_ros: set[str] = set()
    for name in names:
        ros = draw(ros_names.filter(lambda n: n not in used_ros))
        used_ros.add(ros)
        rel = ros.removeprefix("/{{robotName}}/") if ros.startswith("/{{robotName}}/") else ros
        form: dict[str, Any] = {"href": "ros:" + rel, "rosv:name": ros}
        aff: dict[str, Any] = {"rosv:component": draw(st.sampled_from(components))}
        if draw(st.booleans()):
            aff["description"] = draw(free_text)
        if draw(st.booleans()):
            aff["title"] = draw(free_text)
        if draw(st.booleans()):
            form.update({"op": "invokeaction", "rosv:type": draw(st.sampled_from(SERVICES))})
            aff["forms"] = [form]
            actions[name] = aff
        else:
            publisher = draw(st.booleans())
            form.update(
                {
                    "op": ["writeproperty"] if publisher else ["readproperty", "observeproperty"],
                    "rosv:type": draw(st.sampled_from(MESSAGES)),
                }
            )
            if draw(st.booleans()):
                form["rosv:qos"] = {
                    "reliability": draw(st.sampled_from(["reliable", "best_effort"])),
                    "depth": draw(st.integers(1, 100)),
                }
            if publisher and draw(st.booleans()):
                form["rosv:latch"] = True
            aff["forms"] = [form]
            aff["writeOnly" if publisher else "readOnly"] = True
            properties[name] = aff
    td: dict[str, Any] = {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "title": draw(st.sampled_from(["Robot", "Fuzz bot", "Arm 7", "Ünïcode robot"])),
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
    }
    if properties:
        td["properties"] = properties
    if actions:
        td["actions"] = actions
    return td


def round_trip(td: dict[str, Any], interfaces: list[Path] | None = None, *, expect_valid: bool = True) -> None:
    """Compile and generate every backend in memory; every generated file must parse."""
    result = td2adaptor.compile("-", stdin=io.BytesIO(json.dumps(td).encode()), interfaces=interfaces or [])
    if result.model is None:
        errors = [(d.code, d.message) for d in result.diagnostics if d.severity is Severity.ERROR]
        assert not expect_valid, errors
        assert errors
        return
    diags = Diagnostics()
    # an mROS tree with generous buffers: upstream's 512-byte TCPROS buffer refuses most real types (MROS914)
    tree_limits = (("mros.tcpros_header_max", 1 << 20), ("mros.xmlrpc_packet_max", 1 << 20))
    trees = generate_trees(result.model, available(), diags, partial=True, backend_options=tree_limits)
    assert trees is not None, [d.message for d in diags if d.severity is Severity.ERROR]
    for tree in trees.values():
        for rel, data in tree:
            if rel.endswith((".py", ".pyi")):
                ast.parse(data.decode("utf-8"), rel)
            elif rel.endswith(".xml"):
                ET.fromstring(data)
            elif rel.endswith((".json", ".jsonld")):
                json.loads(data)
