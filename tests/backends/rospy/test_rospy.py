"""The rospy backend without ROS: layout, determinism, lint/format/type cleanliness, TD text cannot inject code,
and the reference dialect yields the same package. The real-ROS tests are in test_backend_rospy_runtime.py.
"""

from __future__ import annotations

import ast
import copy
import importlib.machinery
import importlib.util
import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.backends.rospy import generator as backend
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.model import Model
from tests.conftest import EXAMPLE, REPO

PKG = "robotnik_rb_1_adaptor"
COMPONENTS = [
    "GoToComponent",
    "PickComponent",
    "PlaceComponent",
    "AvailabilityComponent",
    "PoseMarkerComponent",
    "DoorComponent",
]
HOSTILE = (
    '"""\nimport os\nos.system("echo pwned")\n"""\\ \' \'\'\' \x00\x07 \u2028 \r\n'
    '</description><evil/> & <!-- --> ]]> \\" \\\\""" {{ jinja }} {% raw %} # not a comment\n'
    "\tdef f(): pass\n" + "x" * 300
)


def model_of(td: Path) -> Model:
    result = td2adaptor.compile(td, interfaces=[EXAMPLE / "interfaces"])
    assert result.model is not None, [d.message for d in result.diagnostics]
    return result.model


def generate(model: Model, package_name: str | None = None) -> GeneratedTree:
    diags = Diagnostics()
    tree = backend.generate(model, GenOptions(package_name=package_name), diags)
    assert not [d for d in diags if d.severity is Severity.ERROR], [d.message for d in diags]
    return tree


def write(tree: GeneratedTree, root: Path) -> Path:
    for rel, data in tree:
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(data)
    return root / PKG


def hostile_td(tmp_path: Path) -> Path:
    """The RB-1 TD with every human-readable text replaced by hostile text."""
    td: dict[str, Any] = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    td["title"] = HOSTILE
    td["description"] = HOSTILE
    for group in ("actions", "properties"):
        for aff in td.get(group, {}).values():
            aff["title"] = HOSTILE
            aff["description"] = HOSTILE
    path = tmp_path / "hostile.td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def rb1_tree() -> GeneratedTree:
    return generate(model_of(EXAMPLE / "td.json"))


def test_backend_metadata() -> None:
    from td2adaptor.backends.registry import load

    plugin = load("rospy")
    assert (plugin.NAME, plugin.DISTRO) == ("rospy", "ros1")


def test_layout_and_determinism(rb1_tree: GeneratedTree) -> None:
    again = generate(model_of(EXAMPLE / "td.json"))
    assert rb1_tree.files == again.files
    names = set(rb1_tree.files)
    for rel in ("package.xml", "CMakeLists.txt", "setup.py", "README.md", "mypy.ini", "ruff.toml"):
        assert f"{PKG}/{rel}" in names
    for rel in ("__init__.py", "py.typed", "errors.py", "_runtime.py", "components.py"):
        assert f"{PKG}/src/{PKG}/{rel}" in names
    for stub in ("procedures_msgs/srv", "robot_local_control_msgs/msg", "std_msgs/msg", "geometry_msgs/msg"):
        assert f"{PKG}/stubs/{stub}/__init__.pyi" in names
    for rel, data in rb1_tree:
        text = data.decode("utf-8")
        assert str(REPO) not in text and "/tmp/" not in text, rel
        if rel.endswith((".py", ".pyi")):  # the package must not need td2adaptor at run time
            modules = [
                alias.name for n in ast.walk(ast.parse(text)) if isinstance(n, ast.Import) for alias in n.names
            ] + [n.module or "" for n in ast.walk(ast.parse(text)) if isinstance(n, ast.ImportFrom)]
            assert not [m for m in modules if m.split(".")[0] == "td2adaptor"], rel


def test_components_in_td_order_with_paper_methods(rb1_tree: GeneratedTree) -> None:
    module = ast.parse(rb1_tree.files[f"{PKG}/src/{PKG}/components.py"])
    classes = [n for n in module.body if isinstance(n, ast.ClassDef)]
    assert [c.name for c in classes] == COMPONENTS
    methods = {c.name: [f.name for f in c.body if isinstance(f, ast.FunctionDef)] for c in classes}
    assert {"construct_gotoRun_Msg", "call_gotoRun", "call_gotoQuery", "call_gotoCancel", "register"} <= set(
        methods["GoToComponent"]
    )
    assert {"get_availability_value", "get_value", "on_availability"} <= set(methods["AvailabilityComponent"])
    assert {"construct_door_Msg", "publish_door_Msg"} <= set(methods["DoorComponent"])
    init = next(f for f in classes[0].body if isinstance(f, ast.FunctionDef) and f.name == "__init__")
    assert [a.arg for a in init.args.args] == ["self", "robot_name"]
    assert [a.arg for a in init.args.kwonlyargs] == ["timeout", "wait_timeout"]
    query = next(f for f in classes[0].body if isinstance(f, ast.FunctionDef) and f.name == "call_gotoQuery")
    assert [a.arg for a in query.args.kwonlyargs] == ["mission_id", "timeout"]
    run = next(f for f in classes[0].body if isinstance(f, ast.FunctionDef) and f.name == "call_gotoRun")
    assert ast.unparse(run.returns) == "Started[GoToPetitionResponse]"  # type: ignore[arg-type]
    generated = (REPO / "generated" / "rospy" / PKG / "src" / PKG / "components.py").read_bytes()
    assert generated == rb1_tree.files[f"{PKG}/src/{PKG}/components.py"]


def test_package_xml_is_valid_xml_with_every_dependency(rb1_tree: GeneratedTree) -> None:
    root = ET.fromstring(rb1_tree.files[f"{PKG}/package.xml"])
    assert root.tag == "package" and root.get("format") == "2"
    assert root.findtext("name") == PKG
    expected = {
        "rospy",
        "ar_track_alvar_msgs",
        "geometry_msgs",
        "procedures_msgs",
        "robot_local_control_msgs",
        "robotnik_msgs",
        "std_msgs",
    }
    # roslaunch: launch/edge_node.launch; rosgraph: `servers_ready()` asks the ROS master
    assert {e.text for e in root.findall("exec_depend")} == expected | {"roslaunch", "rosgraph"}
    assert {e.text for e in root.findall("build_depend")} == expected
    assert [e.text for e in root.findall("buildtool_depend")] == ["catkin"]


def _lint(pkg_dir: Path) -> None:
    """ruff check, ruff format --check and mypy --strict, with the package's own configuration."""
    bindir = Path(sys.executable).parent
    for cmd in (
        [str(bindir / "ruff"), "check", "--no-cache", "."],
        [str(bindir / "ruff"), "format", "--check", "--no-cache", "."],
        [str(bindir / "mypy"), "--config-file", "mypy.ini", "--cache-dir", str(pkg_dir.parent / ".mypy")],
    ):
        out = subprocess.run(cmd, cwd=pkg_dir, capture_output=True, text=True)
        assert out.returncode == 0, f"{' '.join(cmd[:2])}:\n{out.stdout}\n{out.stderr}"


def test_generated_package_is_lint_format_and_mypy_strict_clean(rb1_tree: GeneratedTree, tmp_path: Path) -> None:
    _lint(write(rb1_tree, tmp_path))


def test_stubs_catch_type_errors(rb1_tree: GeneratedTree, tmp_path: Path) -> None:
    """The stubs are real types: misuse of messages and components is a mypy error."""
    pkg = write(rb1_tree, tmp_path)
    (pkg / "src" / PKG / "misuse.py").write_text(
        "from robotnik_rb_1_adaptor import GoToComponent\n"
        "from procedures_msgs.msg import ProcedureHeader\n\n"
        "def f(c: GoToComponent) -> str:\n"
        "    started = c.call_gotoRun()\n"
        "    return started.mission_id\n\n"
        "def g() -> None:\n"
        "    ProcedureHeader(id='x')\n"
    )
    bindir = Path(sys.executable).parent
    out = subprocess.run(
        [str(bindir / "mypy"), "--config-file", "mypy.ini", "--cache-dir", str(tmp_path / ".mypy")],
        cwd=pkg,
        capture_output=True,
        text=True,
    )
    assert out.returncode == 1
    assert 'Incompatible return value type (got "int", expected "str")' in out.stdout
    assert 'Argument "id" to "ProcedureHeader" has incompatible type "str"; expected "int"' in out.stdout


def _without_docstrings(tree: ast.AST) -> str:
    tree = copy.deepcopy(tree)
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                if isinstance(body[0].value.value, str):
                    node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree)


def test_hostile_td_text_cannot_inject_code(rb1_tree: GeneratedTree, tmp_path: Path) -> None:
    tree = generate(model_of(hostile_td(tmp_path)), PKG)
    assert set(tree.files) == set(rb1_tree.files)
    for rel, data in tree:
        if rel.endswith((".py", ".pyi")):
            # the same program as for the harmless TD: TD text changed docstrings and nothing else
            assert _without_docstrings(ast.parse(data)) == _without_docstrings(ast.parse(rb1_tree.files[rel])), rel
    module = ast.parse(tree.files[f"{PKG}/src/{PKG}/components.py"])
    kinds = [type(n).__name__ for n in module.body]
    assert kinds[0] == "Expr" and kinds[-len(COMPONENTS) :] == ["ClassDef"] * len(COMPONENTS)
    assert set(kinds[1 : -len(COMPONENTS)]) == {"ImportFrom", "Assign"}
    assert ast.get_docstring(module) is not None and "import os" in ast.get_docstring(module)  # type: ignore[operator]
    root = ET.fromstring(tree.files[f"{PKG}/package.xml"])
    assert root.find("evil") is None and root.find("description/evil") is None
    assert "</description><evil/>" in (root.findtext("description") or "")
    for rel in (f"{PKG}/setup.py", f"{PKG}/CMakeLists.txt", f"{PKG}/mypy.ini", f"{PKG}/launch/edge_node.launch"):
        assert tree.files[rel] == rb1_tree.files[rel]
    _lint(write(tree, tmp_path / "out"))


def test_reference_dialect_gives_the_same_package(rb1_tree: GeneratedTree) -> None:
    other = generate(model_of(EXAMPLE / "td.reference-dialect.json"))
    assert set(other.files) == set(rb1_tree.files)
    for rel, data in other:
        if rel.endswith((".py", ".pyi")):
            assert _without_docstrings(ast.parse(data)) == _without_docstrings(ast.parse(rb1_tree.files[rel])), rel


def test_docstring_wrapping_keeps_escapes_whole() -> None:
    text = '"' * 500 + "\\" * 77 + " word" * 40
    doc = backend.docstring([text], ["Fixed."], "        ")
    assert ast.literal_eval(doc) is not None
    lines = doc.splitlines()
    assert all(len(line) <= backend.LINE for line in ["        " + lines[0], *lines[1:]])
    value = ast.literal_eval(doc)
    assert value.replace("\n", "").replace(" ", "").startswith('"' * 500 + "\\" * 77)


def test_edge_node_module_and_rosrun_script_drop_remapping_arguments() -> None:
    # one template renders both; the script is the module plus a shebang (rosrun runs it without the package)
    pkg = REPO / "generated" / "rospy" / PKG
    script = (pkg / "scripts" / "edge_node").read_text()
    assert script.startswith("#!/usr/bin/env python3\n") and os.access(pkg / "scripts" / "edge_node", os.X_OK)
    assert f"from {PKG}" not in script and f"import {PKG}" not in script
    for path in (pkg / "src" / PKG / "edge_node.py", pkg / "scripts" / "edge_node"):
        loader = importlib.machinery.SourceFileLoader("rb1_edge_node", str(path))
        spec = importlib.util.spec_from_loader("rb1_edge_node", loader)
        assert spec is not None
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
        assert module.user_args(["td.json", "--robot", "a", "__name:=edge", "__log:=/tmp/x.log"]) == [
            "td.json",
            "--robot",
            "a",
        ]
        # the launch file's options: empty ones left out, --interfaces=A:B one option per folder, others kept
        given = ["td.json", "--robot=a", "--namespace=", "--config=", "--interfaces=/i:/j", "--interfaces=", "-x="]
        assert module.launch_args([*given, "--set", "k=", "--bus=mqtt://h:1"]) == [
            "td.json",
            "--robot=a",
            "--interfaces=/i",
            "--interfaces=/j",
            "-x=",
            "--set",
            "k=",
            "--bus=mqtt://h:1",
        ]


def test_launch_file_starts_the_rosrun_script_with_every_documented_argument(rb1_tree: GeneratedTree) -> None:
    root = ET.fromstring(rb1_tree.files[f"{PKG}/launch/edge_node.launch"])
    names = [arg.get("name") for arg in root.iter("arg")]
    readme = bytes(rb1_tree.files[f"{PKG}/README.md"]).decode()
    section = readme.split("## Launch file", 1)[1].split("\n## ", 1)[0]
    assert names == re.findall(r"^\| `(\w+)` \|", section, re.MULTILINE)
    assert [arg.get("name") for arg in root.iter("arg") if arg.get("default") is None] == ["td", "robot"]
    (node,) = root.iter("node")
    assert (node.get("pkg"), node.get("type")) == (PKG, "edge_node")
    # every argument reaches the node, as an option or a TD2ADAPTOR_* variable; credentials are none of them
    environment = {env.get("name"): env.get("value") for env in node.iter("env")}
    used = re.findall(r"\$\(arg (\w+)\)", " ".join([node.get("args") or "", *map(str, environment.values())]))
    assert sorted(used) == sorted(names)
    assert all(name and name.startswith("TD2ADAPTOR_") and "PASSWORD" not in name for name in environment)
    assert (
        "install(DIRECTORY launch DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})"
        in bytes(rb1_tree.files[f"{PKG}/CMakeLists.txt"]).decode()
    )
