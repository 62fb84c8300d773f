"""Thing Descriptions of the mROS test applications and their generation (in memory and on disk)."""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import td2adaptor
from td2adaptor.backends.mros import generator as backend
from td2adaptor.backends.mros import lint as mros_lint
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.model import Model
from tests.conftest import EXAMPLE

HERE = Path(__file__).resolve().parent
INTERFACES = HERE / "interfaces"
KEYWORD_INTERFACES = HERE / "interfaces_keywords"
RB1_INTERFACES = EXAMPLE / "interfaces"
#: the limits the tests' mROS tree is stated to have (test_mros_real_tree.py raises the tree's constants to them):
#: a ROS 1 publisher's TCPROS header for robot_local_control_msgs/Status has 7.2 KB, upstream's buffer 512 B
TREE_LIMITS: tuple[tuple[str, Any], ...] = (("mros.tcpros_header_max", 8192),)
CONTEXT = ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"]


def prop(component: str, ros_name: str, ros_type: str, *, publish: bool = False, **extra: Any) -> dict[str, Any]:
    """A TD property bound to a topic (subscribed unless `publish`)."""
    rel = ros_name.removeprefix("/{{robotName}}/")
    form = {
        "href": "ros:" + rel,
        "op": ["writeproperty"] if publish else ["readproperty", "observeproperty"],
        "rosv:name": ros_name,
        "rosv:type": ros_type,
    }
    return {"rosv:component": component, "writeOnly" if publish else "readOnly": True, "forms": [form], **extra}


def thing(title: str, properties: dict[str, Any], actions: dict[str, Any] | None = None) -> dict[str, Any]:
    td: dict[str, Any] = {
        "@context": CONTEXT,
        "@type": "Thing",
        "title": title,
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "properties": properties,
    }
    if actions:
        td["actions"] = actions
    return td


def features_td() -> dict[str, Any]:
    """Every field kind, published and subscribed, components with one and with several subscriptions."""
    m = "td2a_test_msgs/msg/"
    return thing(
        "Feature bot",
        {
            "prims": prop("FeatureComponent", "/{{robotName}}/prims", m + "Primitives"),
            "arrays": prop("FeatureComponent", "/{{robotName}}/arrays", m + "Arrays"),
            "nested": prop("FeatureComponent", "/nested", m + "Nested", description="Nested */ messages ??/"),
            "nestedOut": prop("FeatureComponent", "/nested_out", m + "Nested", publish=True),
            "emptyOut": prop("PubComponent", "/{{robotName}}/empty", m + "Empty", publish=True),
            "stamp": prop("PubComponent", "stamp", "std_msgs/msg/Header", publish=True),
            "status": prop(
                "StatusComponent", "/{{robotName}}/robot_local_control/state", "robot_local_control_msgs/msg/Status"
            ),
            "markers": prop("MarkerComponent", "/{{robotName}}/ar_pose_marker", "ar_track_alvar_msgs/msg/AlvarMarkers"),
            "loop": prop("LoopComponent", "/loop", m + "Inner"),
            "loopOut": prop("LoopComponent", "/loop", m + "Inner", publish=True),
        },
    )


def keywords_td() -> dict[str, Any]:
    """Message, field, constant and package names C++ cannot use as they are."""
    return thing(
        "Keyword bot",
        {
            "kw": prop("KeywordComponent", "/kw", "td2a_kw_msgs/msg/Keywords"),
            "rate": prop("KeywordComponent", "/rate", "ros/msg/Rate", publish=True),
        },
    )


@dataclass
class App:
    model: Model
    tree: GeneratedTree
    diags: Diagnostics
    root: str  # the application directory inside the tree

    def text(self, rel: str) -> str:
        return self.tree.files[self.root + rel].decode("utf-8")


def compile_td(td: dict[str, Any] | Path, interfaces: list[Path]) -> Model:
    source = td if isinstance(td, Path) else "-"
    stdin = None if isinstance(td, Path) else io.BytesIO(json.dumps(td).encode())
    result = td2adaptor.compile(source, stdin=stdin, interfaces=interfaces)
    assert result.model is not None, [(d.code, d.message) for d in result.diagnostics if d.severity is Severity.ERROR]
    return result.model


def generate(
    td: dict[str, Any] | Path,
    interfaces: list[Path],
    *,
    partial: bool = True,
    extra: tuple[tuple[str, Any], ...] = (),
    tree_limits: bool = True,
) -> App:
    """The application of `td`; the options `extra` come after `TREE_LIMITS` (unless not `tree_limits`)."""
    model = compile_td(td, interfaces)
    diags = Diagnostics()
    options = (*TREE_LIMITS, *extra) if tree_limits else extra
    tree = backend.generate(model, GenOptions(partial=partial, extra=options), diags)
    return App(model, tree, diags, model.package_name + "/")


def rb1(partial: bool = True) -> App:
    return generate(EXAMPLE / "td.json", [RB1_INTERFACES], partial=partial)


def features() -> App:
    return generate(features_td(), [INTERFACES, RB1_INTERFACES])


def write(app: App, dest: Path) -> Path:
    """Write the application directory under dest, plus the kernel_cfg.h the TOPPERS configurator would make."""
    for rel, data in app.tree:
        path = dest / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    root = dest / app.root
    (root / "kernel_cfg.h").write_text(mros_lint.kernel_cfg_h((root / "app.cfg").read_text()))
    return root
