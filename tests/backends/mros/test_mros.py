"""The mROS backend's generation (no compiler needed): golden files, diagnostics, limits, pools, names.

Compiling and running the output: test_mros_compile.py; the wire format: test_mros_wire.py.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.backends.mros import generator as mros
from td2adaptor.backends.mros import lint as mros_lint
from td2adaptor.backends.mros.types import comment, macro_like
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GenOptions
from td2adaptor.model import FieldType, MessageField
from tests.backends.mros import apps
from tests.conftest import EXAMPLE, REPO


def _codes(diags: Diagnostics, severity: Severity | None = None) -> list[str]:
    return [d.code for d in diags if severity is None or d.severity is severity]


def test_rb1_diagnostics_with_partial() -> None:
    app = apps.rb1()
    assert not app.diags.has_errors
    # a configured partial target skips the nine services on every run: one warning that lists them
    (skipped,) = [d for d in app.diags if d.code == "MROS900"]
    services = [s.name for c in app.model.components for s in c.services]
    assert skipped.severity is Severity.WARNING and skipped.pointer == f"/actions/{services[0]}"
    assert skipped.message == (
        f"mros backend: skipped 9 actions bound to services (--partial; mROS 1 has none): {', '.join(services)} "
        "(the package README lists them)"
    )
    # + the Status header counted without its std_msgs/geometry_msgs comments, within the stated 8192 bytes but
    # not twice that (MROS917), + the latched door
    assert _codes(app.diags, Severity.WARNING) == ["MROS900", "MROS917", "MROS906"]
    assert _codes(app.diags, Severity.INFO) == ["MROS911", "MROS911"]  # unbounded Status and AlvarMarkers
    readme = app.text("README.md")
    assert all(f"`{s.name}`" in readme for c in app.model.components for s in c.services)


def test_actions_are_errors_without_partial() -> None:
    app = apps.rb1(partial=False)
    errors = app.diags.errors()
    assert [d.code for d in errors] == ["MROS900"] * 9
    assert {d.message.split("'")[1] for d in errors} == {s.name for c in app.model.components for s in c.services}
    assert all("--partial" in (d.hint or "") for d in errors)


def test_task_configuration_is_consistent_and_the_lint_catches_drift() -> None:
    for app in (apps.rb1(), apps.features()):
        files = {rel: app.text(rel) for rel in mros_lint.CHECKED}
        assert mros_lint.problems(files) == []
        conf = mros_lint.parse(*(files[r] for r in mros_lint.CHECKED))
        assert conf.cfg_semaphores == ("TD2A_LOCK_SEM",)
    files = {rel: apps.rb1().text(rel) for rel in mros_lint.CHECKED}
    broken = dict(files, **{"app.cfg": files["app.cfg"].replace("CRE_TSK(TD2A_SUB_TASK", "CRE_TSK(OTHER_TASK")})
    assert any("mros_usr_task_table" in p for p in mros_lint.problems(broken))
    broken = dict(
        files, **{mros_lint.USR_CONFIG_H: re.sub(r"TASK_NUM +2", "TASK_NUM 3", files[mros_lint.USR_CONFIG_H])}
    )
    assert any("MROS_USR_TASK_NUM is 3" in p for p in mros_lint.problems(broken))
    broken = dict(files, **{"app.h": files["app.h"].replace("td2a_sub_task", "td2a_other_task")})
    assert any("app.h" in p for p in mros_lint.problems(broken))
    assert mros_lint.problems({}) == [f"missing {p}" for p in mros_lint.CHECKED]
    kernel_cfg = mros_lint.kernel_cfg_h(files["app.cfg"])
    assert "#define TD2A_PUB_TASK 1" in kernel_cfg and "#define TD2A_LOCK_SEM 1" in kernel_cfg


def _usr_config(app: apps.App) -> dict[str, int]:
    out = {}
    for line in app.text(mros_lint.USR_CONFIG_H).splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "#define" and parts[2].rstrip("U").isdigit():
            out[parts[1]] = int(parts[2].rstrip("U"))
    return out


def test_pools_fit_the_bounded_messages() -> None:
    conf = _usr_config(apps.rb1())
    # published: std_msgs/Float64 (8 bytes + 4): the default classes; received: Status up to 4798 + 4 bytes
    assert [conf[f"ROS_INNER_TOPIC_PUBLISHER_MEMPOOL{i}_SIZE"] for i in (1, 2, 3)] == [256, 512, 1024]
    assert [conf[f"ROS_OUTER_TOPIC_PUBLISHER_MEMPOOL{i}_SIZE"] for i in (1, 2, 3)] == [256, 512, 4864]
    assert conf["ROS_OUTER_TOPIC_PUBLISHER_MEMPOOL3_QUELEN"] == 4 and conf["MROS_USR_TASK_NUM"] == 2
    # capacities are options; a bound beyond the largest allowed block is an error naming the property
    small = apps.generate(EXAMPLE / "td.json", [apps.RB1_INTERFACES], extra=(("mros.string_capacity", 8),))
    sized = next(d.message for d in small.diags if d.code == "MROS911")
    assert "sized for 1102 bytes (strings of 8 bytes, sequences of 8 elements)" in sized  # was 4798
    capped = apps.generate(EXAMPLE / "td.json", [apps.RB1_INTERFACES], extra=(("mros.max_pool_block", 2048),))
    assert [(d.code, d.pointer) for d in capped.diags.errors()] == [("MROS910", "/properties/availability")]


def test_fixed_size_messages_skip_the_runtime_size_check() -> None:
    rb1 = apps.rb1()
    assert "does not fit the publish pool" not in rb1.text("app.cpp")  # Float64: 8 bytes, always fits
    features = apps.features()
    assert features.text("app.cpp").count("does not fit the publish pool") == 3  # Nested, Header, Inner
    assert "#define PUB_MSG_MAX_SIZE 3524" in features.text("include/msg_max_size.h")


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ((("mros.rate_hz", 0),), "mros.rate_hz must be an integer in 1..1000"),
        ((("mros.rate_hz", True),), "mros.rate_hz must be an integer"),
        ((("mros.unknown", 1),), "unknown option 'mros.unknown'"),
    ],
)
def test_bad_options(extra: tuple[tuple[str, Any], ...], message: str) -> None:
    app = apps.generate(EXAMPLE / "td.json", [apps.RB1_INTERFACES], extra=extra)
    assert any(d.code == "MROS912" and message in d.message for d in app.diags.errors())


def test_options_reach_the_output() -> None:
    app = apps.generate(EXAMPLE / "td.json", [apps.RB1_INTERFACES], extra=(("mros.rate_hz", 50), ("other.x", 1)))
    assert not app.diags.has_errors
    assert "#define TD2A_PUBLISH_RATE_HZ 50\n" in app.text("include/td2a_config.h")


def test_name_limits(tmp_path: Path) -> None:
    # node names: <package without _adaptor>_pub/_sub, or td2a_pub/_sub with a warning when too long
    long_title = apps.thing("A very long robot title", {"p": apps.prop("PComponent", "/p", "std_msgs/msg/Bool")})
    app = apps.generate(long_title, [])
    assert [d.code for d in app.diags if d.severity is Severity.WARNING] == ["MROS901"]
    assert '#define TD2A_SUB_NODE_NAME "td2a_sub"' in app.text("include/td2a_config.h")
    # topics: 48 characters (without a namespace); namespaced ones leave room for it
    path = "a" * 47
    props = {
        "fits": apps.prop("AComponent", "/" + path, "std_msgs/msg/Bool"),
        "tooLong": apps.prop("AComponent", "/" + path + "bc", "std_msgs/msg/Bool"),
        "noRoom": apps.prop("AComponent", "/{{robotName}}/" + "b" * 47, "std_msgs/msg/Bool"),
    }
    app = apps.generate(apps.thing("Names", props), [])
    assert [(d.code, d.pointer) for d in app.diags.errors()] == [("MROS902", "/properties/tooLong")]
    assert "MROS903" in _codes(app.diags, Severity.WARNING)
    props = {"ok": apps.prop("AComponent", "/{{robotName}}/" + "b" * 20, "std_msgs/msg/Bool")}
    app = apps.generate(apps.thing("Names", props), [])
    assert "#define TD2A_ROBOT_NAMESPACE_MAXLEN 26\n" in app.text("include/td2a_config.h")
    # type names: pkg/Type at most 49 characters
    pkg = tmp_path / ("p" * 40) / "msg"
    pkg.mkdir(parents=True)
    (pkg / "LongTypeName.msg").write_text("int32 x\n")
    props = {"t": apps.prop("TComponent", "/t", "p" * 40 + "/msg/LongTypeName")}
    app = apps.generate(apps.thing("Types", props), [tmp_path])
    assert [d.code for d in app.diags.errors()] == ["MROS904"]


def test_table_sizes_grow_with_a_warning() -> None:
    props = {f"p{i}": apps.prop("ManyComponent", f"/topic{i}", "std_msgs/msg/Int32") for i in range(22)}
    app = apps.generate(apps.thing("Many", props), [])
    assert not app.diags.has_errors
    assert _codes(app.diags, Severity.WARNING) == ["MROS905", "MROS905"]  # 22 topics, 22 subscriptions
    conf = _usr_config(app)
    assert conf["MROS_TOPIC_MAX_NUM"] == 22 and conf["MROS_SUB_TOPIC_CONNECTOR_MAX_NUM"] == 22
    assert conf["MROS_PUB_TOPIC_CONNECTOR_MAX_NUM"] == 10
    assert "MROS_USR_TASK_NUM                        1" in app.text(mros_lint.USR_CONFIG_H)  # no publisher task


def test_no_topics_gives_only_a_readme() -> None:
    td = apps.thing("Only actions", {})
    del td["properties"]
    td["actions"] = {
        "reset": {
            "forms": [
                {"href": "ros:reset", "op": "invokeaction", "rosv:name": "/reset", "rosv:type": "std_srvs/srv/Empty"}
            ]
        }
    }
    app = apps.generate(td, [])
    assert not app.diags.has_errors
    assert _codes(app.diags) == ["MROS900", "MROS930"]
    assert list(app.tree.files) == [app.root + "README.md"]
    assert "`reset`" in app.text("README.md")


def test_types_mros_cannot_represent() -> None:
    model = apps.compile_td(EXAMPLE / "td.json", [apps.RB1_INTERFACES])
    table = model.ros1
    # a missing type
    without = replace(table, messages=tuple(m for m in table.messages if m.name != "geometry_msgs/msg/Pose"))
    diags = Diagnostics()
    tree = mros.generate(replace(model, ros1=without), GenOptions(partial=True, extra=apps.TREE_LIMITS), diags)
    assert [d.code for d in diags.errors()] == ["MROS931"] and not tree.files
    assert "geometry_msgs/msg/Pose" in diags.errors()[0].message
    # a ROS 2 wstring field
    pose = table.message("geometry_msgs/msg/Point")
    wide = replace(pose, fields=(*pose.fields, MessageField("label", FieldType("wstring"))))
    messages = tuple(wide if m.name == pose.name else m for m in table.messages)
    diags = Diagnostics()
    mros.generate(
        replace(model, ros1=replace(table, messages=messages)), GenOptions(partial=True, extra=apps.TREE_LIMITS), diags
    )
    assert [d.code for d in diags.errors()] == ["MROS932"]


def test_names_cpp_cannot_use_are_mangled() -> None:
    app = apps.generate(apps.keywords_td(), [apps.KEYWORD_INTERFACES])
    assert not app.diags.has_errors
    warned = {d.message.split("'")[1] for d in app.diags if d.code == "MROS920"}
    assert warned == {"class", "new", "linux", "swap", "dataSize", "major", "delete", "td2a_read", "NULL", "EOF",
                      "Keywords2", "unix"}  # fmt: skip
    assert any(d.code == "MROS921" and "'ros_'" in d.message for d in app.diags)
    header = app.text("include/td2a_kw_msgs/Keywords.h")
    for member in ("int32_t class_;", "double new_;", "std::string linux_;", "uint8_t swap_;", "int16_t major_;"):
        assert member in header
    assert "static const int32_t NULL_ = 0;" in header
    assert "namespace ros_ {" in app.text("include/ros/Rate.h")
    assert '"ros/Rate"' in app.text("include/ros/Rate.h")  # the wire name is unchanged


def test_component_names() -> None:
    model = apps.compile_td(EXAMPLE / "td.json", [apps.RB1_INTERFACES])
    renamed = tuple(replace(c, name="linux") if c.name == "DoorComponent" else c for c in model.components)
    diags = Diagnostics()
    tree = mros.generate(replace(model, components=renamed), GenOptions(partial=True, extra=apps.TREE_LIMITS), diags)
    assert any(d.code == "MROS923" and "'linuxClass'" in d.message for d in diags)
    assert b"linuxClass linuxClassInstance;" in tree.files["robotnik_rb_1_adaptor/app.cpp"]
    hostile = tuple(
        replace(c, name="Door Component; int x") if c.name == "DoorComponent" else c for c in model.components
    )
    diags = Diagnostics()
    mros.generate(replace(model, components=hostile), GenOptions(partial=True, extra=apps.TREE_LIMITS), diags)
    assert [d.code for d in diags.errors()] == ["MROS922"]


def test_comment_text_cannot_end_a_comment() -> None:
    for text in ["*/ x", "*\\ x", "/* x", "a ??/\nb", "???/", "**//**", "*\\\\/"]:
        out = comment(text)
        assert "*/" not in out and "/*" not in out and "??" not in out and "\n" not in out, (text, out)
    assert comment("plain text") == "plain text"
    assert macro_like("INT32_MAX") and macro_like("M_PI") and macro_like("linux") and not macro_like("ERROR")


def test_output_is_deterministic_across_processes(tmp_path: Path) -> None:
    script = (
        "import sys; sys.path.insert(0, sys.argv[1]); from tests.backends.mros import apps; import hashlib\n"
        "a = apps.features(); print(hashlib.sha256(b''.join(p.encode() + d for p, d in a.tree)).hexdigest())"
    )
    digests = set()
    for seed in ("1", "2"):
        env = {**os.environ, "PYTHONHASHSEED": seed}
        out = subprocess.run(
            [sys.executable, "-c", script, str(REPO)], env=env, capture_output=True, text=True, check=True, cwd=tmp_path
        )
        digests.add(out.stdout.strip())
    assert len(digests) == 1


def test_constants_that_cpp_cannot_hold(tmp_path: Path) -> None:
    pkg = tmp_path / "odd_msgs" / "msg"
    pkg.mkdir(parents=True)
    (pkg / "Odd.msg").write_text("float64 BIG=inf\nfloat32 HALF=0.5\nint32 x\n")
    app = apps.generate(apps.thing("Odd", {"o": apps.prop("OComponent", "/o", "odd_msgs/msg/Odd")}), [tmp_path])
    assert [d.code for d in app.diags if d.severity is Severity.WARNING] == ["MROS933"]
    header = app.text("include/odd_msgs/Odd.h")
    assert "BIG" not in header.split("class Odd")[0].split("struct Odd")[1]
    assert "const float Odd<D>::HALF = 0.5f;" in header
