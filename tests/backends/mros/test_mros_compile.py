"""Generated mROS applications compile, link and behave (host g++ and Debian's arm-none-eabi toolchain).

* C++98 with every warning an error (`g++ -std=gnu++98 -Wall -Wextra -Werror`), against our stand-in mROS
  headers (tests/backends/mros/mros_api/), with the C library's macro-defining headers force-included; every
  message header on its own; newer standards too.
* Cortex-A9 objects (`arm-none-eabi-g++ -mcpu=cortex-a9 -marm -mfpu=vfpv3 -mfloat-abi=hard -Os
  -fno-exceptions`): every mROS symbol the application needs is instantiated by the library translation unit
  (the contract `message_class_specialization.h` must meet; a full link needs libstdc++ for the target).
* The library translation unit rejects a missing or duplicated instantiation (the harness is not blind).
* The application's tasks run on the host over a loopback bus: node names, namespaced topics, md5s, hooks,
  latest values, publishing, the pool-size guard and an invalid robot namespace.
* Hostile TD text (quotes, backslashes, newlines, comment ends, trigraphs) compiles and injects nothing.
"""

from __future__ import annotations

import copy
import json
import re
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from td2adaptor.backends.mros import generator as mros
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.backend import GenOptions
from tests.backends.mros import apps, build, fixtures, loopback
from tests.backends.mros.fixtures import needs_arm, needs_host
from tests.compiler.hostile_corpus import MARK, PAYLOADS
from tests.conftest import EXAMPLE

# the session fixtures this module uses
shared_root = fixtures.shared_root
generated = fixtures.generated

Apps = dict[str, tuple[apps.App, Path]]
#: C headers that define macros in lower or mixed case or with names a ROS constant may have
FORCE_INCLUDES = ["limits.h", "stdint.h", "stdio.h", "stdlib.h", "math.h", "errno.h", "stddef.h", "string.h"]


def _force_includes() -> list[str]:
    return [arg for h in FORCE_INCLUDES for arg in ("-include", h)]


@needs_host
@pytest.mark.parametrize("name", ["rb1", "features", "keywords"])
def test_cxx98_syntax_with_every_warning_an_error(name: str, generated: Apps) -> None:
    app, root = generated[name]
    build.run([build.HOST_CXX, *build.HOST_SYNTAX, *_force_includes(), *build.includes(root), str(root / "app.cpp")])
    # every message header compiles on its own (it includes what it needs)
    units = []
    for header in sorted((root / "include").glob("*/*.h")):
        unit = root / f"standalone_{header.parent.name}_{header.stem}.cpp"
        unit.write_text(f'#include "{header.parent.name}/{header.name}"\n')
        units.append(str(unit))
    build.run([build.HOST_CXX, *build.HOST_SYNTAX, *build.includes(root), *units])
    # the C configuration file
    build.run(
        [
            "gcc",
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-fsyntax-only",
            *build.includes(root),
            str(root / "mros_config" / "mros_usr_config.c"),
        ]
    )


@needs_host
@pytest.mark.parametrize("std", ["gnu++11", "gnu++17", "gnu++20"])
def test_newer_standards(std: str, generated: Apps) -> None:
    root = generated["features"][1]
    flags = [f"-std={std}", "-Wall", "-Wextra", "-Werror", "-fsyntax-only"]
    build.run([build.HOST_CXX, *flags, *build.includes(root), str(root / "app.cpp")])


@needs_arm
@pytest.mark.parametrize("name", ["rb1", "features", "keywords"])
def test_cortex_a9_objects_and_symbol_contract(name: str, generated: Apps, tmp_path: Path) -> None:
    root = generated[name][1]
    objs = build.arm_objects(root, tmp_path)
    app_obj, lib_obj, cfg_obj = objs
    sizes = build.size(objs)
    assert sizes[str(app_obj)][0] > 0 and sizes[str(lib_obj)][0] > 0
    assert sizes[str(cfg_obj)][2] > 0  # the pools are static BSS
    needed = {line.split("U ", 1)[1].strip() for line in build.nm(app_obj, "--undefined-only") if " U " in line}
    mros_needed = {
        s for s in needed if s.startswith(("ros::", "void ros::", "ros::Publisher ros::", "ros::Subscriber"))
    }
    defined = {line.split(None, 2)[2] for line in build.nm(lib_obj, "--defined-only") if len(line.split(None, 2)) == 3}
    assert mros_needed, "the application calls no mROS function?"
    assert mros_needed <= defined, sorted(mros_needed - defined)
    # the traits and the callback dispatch are header-only: nothing else of mROS is left undefined
    assert not {s for s in needed if "message_traits" in s or "subtask_methods" in s}


def _lib_object(root: Path, out: Path, specialization: str) -> str:
    """Compile the ros.cpp stand-in against a modified message_class_specialization.h; the compiler output."""
    inc = out / "override"
    inc.mkdir(parents=True, exist_ok=True)
    (inc / "message_class_specialization.h").write_text(specialization)
    proc = subprocess.run(
        [
            build.HOST_CXX,
            "-std=gnu++98",
            "-I",
            str(inc),
            *build.includes(root),
            "-c",
            str(build.API / "mros_stub_lib.cpp"),
            "-o",
            str(out / "lib.o"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    return proc.stderr if proc.returncode else ""


@needs_host
def test_library_unit_rejects_missing_and_duplicate_instantiations(generated: Apps, tmp_path: Path) -> None:
    root = generated["rb1"][1]
    text = (root / "include" / "message_class_specialization.h").read_text()
    lines = text.splitlines(keepends=True)
    first = next(i for i, line in enumerate(lines) if line.startswith("template "))
    duplicated = "".join(lines[: first + 1] + [lines[first]] + lines[first + 1 :])
    assert "duplicate explicit instantiation" in _lib_object(root, tmp_path / "dup", duplicated)
    # missing: the application object then has an undefined reference the library does not define
    missing = "".join(lines[:first] + lines[first + 1 :])
    assert _lib_object(root, tmp_path / "missing", missing) == ""
    objs = build.host_objects(root, tmp_path / "objs")
    lib = tmp_path / "missing" / "lib.o"
    proc = subprocess.run(
        [build.HOST_CXX, str(objs[0]), str(lib), *map(str, objs[2:]), "-o", str(tmp_path / "a.out"), "-lpthread"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode != 0 and "undefined reference" in proc.stderr


@needs_host
def test_subscribed_types_must_fit_the_sub_task_stack(generated: Apps, tmp_path: Path) -> None:
    root = generated["rb1"][1]
    lib = [*build.includes(root), "-c", str(build.API / "mros_stub_lib.cpp"), "-o", str(tmp_path / "lib.o")]
    build.run([build.HOST_CXX, "-std=gnu++98", *lib])
    small = [build.HOST_CXX, "-std=gnu++98", "-DTD2A_SUB_TASK_MSG_MAX=64", *lib]
    proc = subprocess.run(small, capture_output=True, text=True, check=False)
    assert proc.returncode != 0 and "td2a_check_sub_task_stack_ROBOT_LOCAL_CONTROL_MSGS_STATUS_MSG_ID" in proc.stderr


@needs_host
def test_robot_namespace_length_is_checked_when_compiling(generated: Apps) -> None:
    app, root = generated["rb1"]
    ns_max = mros.plan(app.model, GenOptions(partial=True, extra=apps.TREE_LIMITS), Diagnostics()).context["ns_max"]  # type: ignore[union-attr]
    ok = f'-DTD2A_ROBOT_NAMESPACE="{"n" * ns_max}"'
    build.run([build.HOST_CXX, *build.HOST_SYNTAX, ok, *build.includes(root), str(root / "app.cpp")])
    too_long = f'-DTD2A_ROBOT_NAMESPACE="{"n" * (ns_max + 1)}"'
    proc = subprocess.run(
        [build.HOST_CXX, *build.HOST_SYNTAX, too_long, *build.includes(root), str(root / "app.cpp")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode != 0 and "td2a_check_robot_namespace_length" in proc.stderr
    long_node = '-DTD2A_SUB_NODE_NAME="a_node_name_of_20_ch"'
    proc = subprocess.run(
        [build.HOST_CXX, *build.HOST_SYNTAX, long_node, *build.includes(root), str(root / "app.cpp")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode != 0 and "td2a_check_sub_node_name_length" in proc.stderr


def _context(app: apps.App) -> dict[str, Any]:
    made = mros.plan(app.model, GenOptions(partial=True, extra=apps.TREE_LIMITS), Diagnostics())
    assert made is not None
    return made.context


def _loopback(name: str, generated: Apps, shared_root: Path, defines: list[str]) -> loopback.Loopback:
    app, root = generated[name]
    context = _context(app)
    source = loopback.harness_source(context)
    key = f"loop-{name}-" + build.digest(build.app_sources(root), source, *defines)

    def make(target: Path) -> None:
        loopback.build_harness(root, context, target, defines)

    return loopback.Loopback(build.shared(shared_root, key, make) / "loopback")


def _typestore(interfaces: list[Path]) -> Any:
    from td2adaptor.rostypes.registry import TypeRegistry

    return TypeRegistry("ros1", interfaces).typestore()


@needs_host
def test_rb1_tasks_on_the_loopback_bus(generated: Apps, shared_root: Path) -> None:
    app = generated["rb1"][0]
    ts = _typestore([apps.RB1_INTERFACES])
    lb = _loopback("rb1", generated, shared_root, ['-DTD2A_ROBOT_NAMESPACE="rb1_base"'])
    try:
        assert lb.ask("GET availability") == "none"  # nothing received yet
        assert lb.ask("RUNSUB") == ""
        lb.ask("FILL door " + "000000000000f03f")  # 1.0
        lb.ask("RUNPUB 3")
        endpoints = [e.split(",") for e in lb.items("ENDPOINTS")]
        table = app.model.ros1
        assert [(e[0], e[1], e[2], e[3], e[4], e[5]) for e in endpoints] == [
            (
                "robotnik_rb_1_sub",
                "/rb1_base/robot_local_control/state",
                "robot_local_control_msgs/Status",
                table.ros1_digest("robot_local_control_msgs/msg/Status").md5,
                "10",
                "0",
            ),
            (
                "robotnik_rb_1_sub",
                "/rb1_base/ar_pose_marker",
                "ar_track_alvar_msgs/AlvarMarkers",
                table.ros1_digest("ar_track_alvar_msgs/msg/AlvarMarkers").md5,
                "10",
                "0",
            ),
            (
                "robotnik_rb_1_pub",
                "/door1/door_controller/command",
                "std_msgs/Float64",
                table.ros1_digest("std_msgs/msg/Float64").md5,
                "10",
                "1",
            ),
        ]
        float64 = ts.types["std_msgs/msg/Float64"]
        door = bytes(ts.serialize_ros1(float64(data=1.0), "std_msgs/msg/Float64"))
        assert (
            lb.items("PUBLISHED")
            == ["/door1/door_controller/command," + (len(door).to_bytes(4, "little") + door).hex()] * 3
        )
        # a Status from the robot: the hook sees it, the component keeps it
        status = _sample_status(ts)
        assert lb.ask(f"INJECT /rb1_base/robot_local_control/state {status.hex()}") == "1"
        assert lb.ask("HOOK availability") == f"1 {status.hex()}"
        assert lb.ask("GET availability") == status.hex()
        assert lb.ask("GETVALUE availability") == status.hex()
        assert lb.ask(f"INJECT /robot_local_control/state {status.hex()}") == "0"  # not our namespace
        assert lb.ask(f"PUBLISH door {door.hex()}") == "1"
        assert lb.items("PROBLEMS") == []
        assert lb.items("LOG") == []
        # a truncated Status is dropped with a log line that survives mROS's -DMROS_LOG_DISABLE_WARN
        assert lb.ask(f"INJECT /rb1_base/robot_local_control/state {status[:-3].hex()}") == "1"
        assert lb.ask("HOOK availability") == f"1 {status.hex()}"  # the hook did not see it
        log = lb.items("LOG")
        assert len(log) == 1 and "dropped a malformed robot_local_control_msgs/Status message" in log[0]
    finally:
        lb.close()


def _sample_status(ts: Any) -> bytes:
    from tests.backends.mros import wire

    app = apps.rb1()
    value = wire.fixed_value(app.model.ros1, "robot_local_control_msgs/msg/Status", (5, 2), "max")
    return bytes(
        ts.serialize_ros1(
            wire.to_rosbags(ts, app.model.ros1, "robot_local_control_msgs/msg/Status", value),
            "robot_local_control_msgs/msg/Status",
        )
    )


@needs_host
def test_invalid_robot_namespace_registers_nothing(generated: Apps, shared_root: Path) -> None:
    lb = _loopback("rb1", generated, shared_root, ['-DTD2A_ROBOT_NAMESPACE="9lives//x"'])
    try:
        lb.ask("RUNSUB")
        lb.ask("RUNPUB 1")
        assert lb.items("ENDPOINTS") == []
        log = lb.items("LOG")
        assert len(log) == 2 and all("TD2A_ROBOT_NAMESPACE is not a valid ROS namespace" in line for line in log)
    finally:
        lb.close()


@needs_host
def test_feature_app_loops_back_and_guards_the_pool(generated: Apps, shared_root: Path) -> None:
    ts = _typestore([apps.INTERFACES, apps.RB1_INTERFACES])
    lb = _loopback("features", generated, shared_root, [])
    try:
        lb.ask("RUNSUB")
        # publishers are usable once registered (by the publisher task, which publishes nothing unfilled)
        assert lb.ask("PUBLISH emptyOut") == "0"
        lb.ask("RUNPUB 1")
        assert lb.items("PUBLISHED") == []
        assert lb.ask("PUBLISH emptyOut") == "1"
        inner = ts.types["td2a_test_msgs/msg/Inner"]
        empty = ts.types["td2a_test_msgs/msg/Empty"]
        sample = bytes(
            ts.serialize_ros1(
                inner(label="hi", nothing=empty(), data=np.array([1, 2], np.uint8)), "td2a_test_msgs/msg/Inner"
            )
        )
        # /loop is published and subscribed by the same application: mROS delivers it in-process
        assert lb.ask(f"PUBLISH loopOut {sample.hex()}") == "1"
        assert lb.ask("GET loop") == sample.hex()
        assert lb.ask("GETVALUE loop") == sample.hex()
        assert lb.ask("HOOK loop") == f"1 {sample.hex()}"
        # a message larger than the publish pool's largest block is refused, with a log line
        big = bytes(
            ts.serialize_ros1(
                inner(label="x" * 5000, nothing=empty(), data=np.zeros(0, np.uint8)), "td2a_test_msgs/msg/Inner"
            )
        )
        assert lb.ask(f"PUBLISH loopOut {big.hex()}") == "0"
        assert any("does not fit the publish pool" in line for line in lb.items("LOG"))
        topics = {e.split(",")[1] for e in lb.items("ENDPOINTS")}
        assert {"/prims", "/arrays", "/nested", "/nested_out", "/empty", "stamp", "/loop"} <= topics
        assert lb.items("PROBLEMS") == []
    finally:
        lb.close()


# ---------------------------------------------------------------------------------------------------------
# hostile TD text

_LITERALS_AND_COMMENTS = re.compile(r'"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\'|/\*.*?\*/|//[^\n]*', re.S)


def _hostile_td() -> dict[str, Any]:
    td: dict[str, Any] = json.loads((EXAMPLE / "td.json").read_text())
    texts = iter(PAYLOADS * 4)
    td["title"] = "Robot " + next(texts)
    td["description"] = next(texts)
    for group in ("actions", "properties"):
        for aff in td[group].values():
            aff["title"] = next(texts)
            aff["description"] = next(texts) + " */ int " + MARK + "_x; /* ??/\n" + "*\\ " + MARK + "();"
    return td


@needs_host
def test_hostile_td_text_compiles_and_injects_nothing(tmp_path: Path) -> None:
    td = _hostile_td()
    app = apps.generate(copy.deepcopy(td), [apps.RB1_INTERFACES])
    assert not app.diags.has_errors
    clean = apps.rb1()
    assert sorted(app.tree.files) == [p.replace(clean.root, app.root) for p in sorted(clean.tree.files)]
    for rel, data in app.tree:
        if rel.endswith((".h", ".cpp", ".c", ".cfg", ".mk")):
            text = data.decode("utf-8")
            assert MARK not in _LITERALS_AND_COMMENTS.sub(" ", text), rel
            assert "??" not in text, rel  # no trigraph anywhere
    root = apps.write(app, tmp_path)
    build.run(
        [
            build.HOST_CXX,
            "-std=c++98",
            "-trigraphs",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-fsyntax-only",
            *build.includes(root),
            str(root / "app.cpp"),
        ]
    )
    # what the compiler sees once comments are gone and macros expanded: the marker only inside literals
    pre = build.run(
        [build.HOST_CXX, "-std=c++98", "-trigraphs", "-E", "-P", *build.includes(root), str(root / "app.cpp")]
    )
    assert MARK not in _LITERALS_AND_COMMENTS.sub(" ", pre)
    if build.have(build.ARM_CXX):
        build.arm_objects(root, tmp_path)
