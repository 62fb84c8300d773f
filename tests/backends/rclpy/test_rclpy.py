"""The rclpy backend's output without a ROS graph: determinism, lint and types, code injection, dialects.

(The real-runtime tests are in test_backend_rclpy_ros2.py.)
"""

from __future__ import annotations

import ast
import copy
import json
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import td2adaptor
from td2adaptor.backends.registry import load as load_backend
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GenOptions
from tests.ros2 import env
from tests.ros2.build import translate, translate_line
from tests.ros2.common import EXAMPLE, PACKAGE, generate_rclpy, require_ros2, std_td

VENV_BIN = Path(sys.executable).parent
PY_MODULES = ("__init__.py", "components.py", "convert.py", "errors.py", "runtime.py")

HOSTILE = [
    '"""; import os; os.system("echo pwned") #',
    "'''\nimport os\nos.system('echo pwned')\n'''",
    "Back\\slash at the end\\",
    'a quote at the end"',
    '\\""" + __import__(\'os\').system(\'id\') + """\\',
    "line one\r\nline two\n\n    indented code()\n\ttabbed\x00nul\x1bescape\u2028separator",
    "</description><exec_depend>evil</exec_depend><!-- -->&amp;",
    "{{ jinja }} {% raw %} ${shell} `backticks` $(whoami)",
    "x" * 300,
]


def _gen_tree(td: Path | dict[str, Any], tmp: Path, *, package_name: str | None = None) -> dict[str, bytes]:
    if isinstance(td, dict):
        tmp.mkdir(parents=True, exist_ok=True)
        path = tmp / "td.json"
        path.write_text(json.dumps(td), encoding="utf-8")
        td = path
    result = td2adaptor.compile(td, interfaces=[EXAMPLE / "interfaces"])
    assert result.model is not None, [d.message for d in result.diagnostics]
    diags = Diagnostics()
    tree = load_backend("rclpy").generate(result.model, GenOptions(package_name=package_name), diags)
    assert not [d for d in diags if d.severity is Severity.ERROR], [d.message for d in diags]
    return dict(tree)


def _write(tree: dict[str, bytes], out: Path) -> None:
    for rel, data in tree.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(data)


def hostile_td() -> dict[str, Any]:
    td: dict[str, Any] = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    td["title"] = "Robotnik RB-1 " + HOSTILE[0]
    td["description"] = "\n".join(HOSTILE)
    for i, affordance in enumerate([*td["actions"].values(), *td["properties"].values()]):
        affordance["title"] = HOSTILE[i % len(HOSTILE)]
        affordance["description"] = HOSTILE[(i + 1) % len(HOSTILE)] + " " + HOSTILE[(i + 4) % len(HOSTILE)]
    return td


def _strip_docstrings(tree: ast.AST) -> str:
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (
            isinstance(body, list)
            and body
            and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant)
        ):
            if isinstance(body[0].value.value, str):
                body[0] = ast.Pass()
    return ast.dump(tree)


def test_deterministic_and_free_of_local_paths(tmp_path: Path) -> None:
    first = _gen_tree(EXAMPLE / "td.json", tmp_path)
    second = _gen_tree(EXAMPLE / "td.json", tmp_path)
    assert first == second
    assert f"{PACKAGE}/package.xml" in first and f"{PACKAGE}/resource/{PACKAGE}" in first
    assert f"{PACKAGE}/{PACKAGE}/py.typed" in first
    for rel, data in first.items():
        text = data.decode("utf-8")
        assert str(env.REPO) not in text and "/tmp" not in text, rel
        assert "\r" not in text and (not text or text.endswith("\n") or rel.endswith(f"resource/{PACKAGE}")), rel


def test_package_xml_and_setup(tmp_path: Path) -> None:
    tree = _gen_tree(EXAMPLE / "td.json", tmp_path, package_name="rb1_client")
    root = ET.fromstring(tree["rb1_client/package.xml"])
    assert root.get("format") == "3" and root.findtext("name") == "rb1_client"
    depends = [e.text or "" for e in root.findall("exec_depend")]
    assert depends == sorted(depends)
    assert {"rclpy", "procedures_msgs", "robot_local_control_msgs", "ar_track_alvar_msgs", "std_msgs"} <= set(depends)
    assert root.findtext("export/build_type") == "ament_python"
    assert 'package_name = "rb1_client"' in tree["rb1_client/setup.py"].decode()
    assert "rb1_client/rb1_client/components.py" in tree and "rb1_client/resource/rb1_client" in tree


def test_components_follow_td_order_and_paper_names(tmp_path: Path) -> None:
    tree = _gen_tree(EXAMPLE / "td.json", tmp_path)
    module = ast.parse(tree[f"{PACKAGE}/{PACKAGE}/components.py"])
    classes = [n for n in module.body if isinstance(n, ast.ClassDef)]
    assert [c.name for c in classes] == [
        "GoToComponent",
        "PickComponent",
        "PlaceComponent",
        "AvailabilityComponent",
        "PoseMarkerComponent",
        "DoorComponent",
    ]
    methods = {
        c.name: [f.name for f in c.body if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))] for c in classes
    }
    assert methods["GoToComponent"] == [
        "__init__",
        "robot_name",
        "register",
        "servers_ready",
        "construct_gotoRun_Msg",
        "call_gotoRun",
        "call_gotoRun_async",
        "call_gotoRun_then",
        "construct_gotoCancel_Msg",
        "call_gotoCancel",
        "call_gotoCancel_async",
        "call_gotoCancel_then",
        "construct_gotoQuery_Msg",
        "call_gotoQuery",
        "call_gotoQuery_async",
        "call_gotoQuery_then",
    ]
    assert methods["AvailabilityComponent"][4:] == [
        "get_availability_value",
        "on_availability",
        "on_availability_serialized",
        "get_value",
    ]
    assert methods["DoorComponent"][4:] == ["construct_door_Msg", "publish_door_Msg"]
    init = next(f for f in classes[0].body if isinstance(f, ast.FunctionDef) and f.name == "__init__")
    assert [a.arg for a in init.args.args] == ["self", "node", "robot_name"]
    assert [a.arg for a in init.args.kwonlyargs] == ["timeout", "wait_timeout"]


def test_hostile_titles_and_descriptions_stay_text(tmp_path: Path) -> None:
    """No TD text becomes code: same AST as the benign package once docstrings are removed, only known
    top-level statements and imports, and the texts survive as docstring data."""
    benign = _gen_tree(EXAMPLE / "td.json", tmp_path / "benign")
    hostile = _gen_tree(hostile_td(), tmp_path / "hostile", package_name=PACKAGE)
    assert sorted(benign) == sorted(hostile)
    interface_modules = {
        f"{pkg}.{kind}"
        for pkg in (
            "ar_track_alvar_msgs",
            "builtin_interfaces",
            "geometry_msgs",
            "procedures_msgs",
            "std_msgs",
            "robot_local_control_msgs",
            "robotnik_msgs",
        )
        for kind in ("msg", "srv")
    }
    allowed_imports = {
        "__future__",
        "collections",
        "collections.abc",
        "typing",
        "math",
        "re",
        "itertools",
        "heapq",
        "sys",
        "threading",
        "time",
        "dataclasses",
        "types",
        "rclpy.node",
        "rclpy.action.client",
        "rclpy.callback_groups",
        "rclpy.client",
        "rclpy.executors",
        "rclpy.publisher",
        "rclpy.qos",
        "rclpy.serialization",
        "rclpy.guard_condition",
        "rclpy.impl.implementation_singleton",
        "contextlib",
        "weakref",
        "rclpy.subscription",
        "rclpy.task",
        "rclpy.timer",
        "numpy.typing",
        "array",
        "os",
        "uuid",  # runtime.py: a random goal id to probe an action server with
        "setuptools",
        "components",
        "common",
        "convert",
        "errors",
        "goals",
        "runtime",
        "launch",  # launch/edge_node.launch.py and the stubs of what it uses
        "launch.actions",
        "launch.substitutions",
        "launch_ros.actions",
    } | interface_modules
    docstrings: list[str] = []
    for rel in sorted(hostile):
        if not rel.endswith((".py", ".pyi")):
            continue
        tree = ast.parse(hostile[rel])
        assert _strip_docstrings(tree) == _strip_docstrings(ast.parse(benign[rel])), rel
        for node in ast.walk(ast.parse(hostile[rel])):
            if isinstance(node, ast.Import):
                assert {a.name for a in node.names} <= allowed_imports, (rel, ast.dump(node))
            elif isinstance(node, ast.ImportFrom):
                assert (node.module or "") in allowed_imports, (rel, node.module)
            elif isinstance(node, (ast.Call, ast.Attribute, ast.Name)):
                assert "pwned" not in ast.dump(node)
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                doc = ast.get_docstring(node, clean=False)
                if doc:
                    docstrings.append(doc)
    components = ast.parse(hostile[f"{PACKAGE}/{PACKAGE}/components.py"])
    kinds = [type(n).__name__ for n in components.body]
    assert kinds[0] == "Expr" and set(kinds[1:]) == {"ImportFrom", "ClassDef"}
    assert [n.name for n in components.body if isinstance(n, ast.ClassDef)] == [
        "GoToComponent",
        "PickComponent",
        "PlaceComponent",
        "AvailabilityComponent",
        "PoseMarkerComponent",
        "DoorComponent",
    ]
    joined = "\n".join(docstrings)
    for fragment in ('"""; import os; os.system("echo pwned") #', "os.system('echo pwned')", "$(whoami)", "x" * 100):
        assert fragment in joined or fragment.replace(" ", "\n") in joined or fragment in joined.replace("\n", " ")
    xml = ET.fromstring(hostile[f"{PACKAGE}/package.xml"])
    assert [e.text for e in xml.findall("exec_depend")] == [
        e.text for e in ET.fromstring(benign[f"{PACKAGE}/package.xml"]).findall("exec_depend")
    ]
    assert "</description>" in (xml.findtext("description") or "")
    # the hostile package is still lint-clean
    out = tmp_path / "hostile-out"
    _write(hostile, out)
    ruff = VENV_BIN / "ruff"
    pkg = out / PACKAGE
    check = subprocess.run([str(ruff), "check", "--no-cache", "."], cwd=pkg, capture_output=True, text=True)
    assert check.returncode == 0, check.stdout
    fmt = subprocess.run([str(ruff), "format", "--check", "--no-cache", "."], cwd=pkg, capture_output=True, text=True)
    assert fmt.returncode == 0, fmt.stdout + fmt.stderr


def test_reference_dialect_gives_an_equivalent_package(tmp_path: Path) -> None:
    binding = _gen_tree(EXAMPLE / "td.json", tmp_path / "a")
    reference = _gen_tree(EXAMPLE / "td.reference-dialect.json", tmp_path / "b", package_name=PACKAGE)
    assert sorted(binding) == sorted(reference)
    for rel in sorted(binding):
        if rel.endswith((".py", ".pyi")):
            assert _strip_docstrings(ast.parse(binding[rel])) == _strip_docstrings(ast.parse(reference[rel])), rel


def _clash_codes(tmp_path: Path, td: dict[str, Any]) -> tuple[list[str], str, dict[str, Any]]:
    """Compile `td` (an edited RB-1 TD) and generate the rclpy package: its error codes, first message, tree."""
    path = tmp_path / "td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    result = td2adaptor.compile(path, interfaces=[EXAMPLE / "interfaces"])
    assert result.model is not None, [d.message for d in result.diagnostics]
    diags = Diagnostics()
    tree = load_backend("rclpy").generate(result.model, GenOptions(), diags)
    return [d.code for d in diags if d.severity is Severity.ERROR], next(iter(diags)).message, dict(tree)


def test_clashing_member_names_are_reported(tmp_path: Path) -> None:
    td = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    extra = copy.deepcopy(td["actions"]["gotoQuery"])
    extra["forms"][0]["rosv:name"] = "/{{robotName}}/other/query_state"
    extra["forms"][0]["href"] = "ros:other/query_state"
    td["actions"]["gotoRun_async"] = extra  # call_gotoRun_async would exist twice
    codes, message, tree = _clash_codes(tmp_path, td)
    assert codes == ["GEN822"]
    assert "call_gotoRun_async" in message and not tree


def test_a_property_named_like_another_ones_serialized_callback_is_reported(tmp_path: Path) -> None:
    td = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    extra = copy.deepcopy(td["properties"]["availability"])
    extra["forms"][0]["rosv:name"] = "/{{robotName}}/other/state"
    extra["forms"][0]["href"] = "ros:other/state"
    td["properties"]["availability_serialized"] = extra  # on_availability_serialized would exist twice
    codes, message, tree = _clash_codes(tmp_path, td)
    assert codes == ["GEN822"]
    assert "on_availability_serialized" in message and not tree


def test_interface_translation_for_rosidl() -> None:
    assert translate_line("Header header") == "std_msgs/Header header"
    assert translate_line("time stamp   # when") == "builtin_interfaces/Time stamp   # when"
    assert translate_line("duration[] waits") == "builtin_interfaces/Duration[] waits"
    assert translate_line("string OK=ok") == 'string OK="ok"'
    assert translate_line('string Q=say "hi" # not a comment') == 'string Q="say \\"hi\\" # not a comment"'
    assert translate_line("int32 id          # comment") == "int32 id          # comment"
    assert translate("ProcedureHeader header\n---\nstring x\n") == "ProcedureHeader header\n---\nstring x\n"


def test_generated_package_passes_ruff_and_mypy_strict(tmp_path: Path) -> None:
    require_ros2()  # mypy resolves rclpy's own annotations
    pkg = generate_rclpy(EXAMPLE / "td.json", tmp_path / "src")
    ruff = str(VENV_BIN / "ruff")
    for args in (["check", "--no-cache", "."], ["format", "--check", "--no-cache", "."]):
        proc = subprocess.run([ruff, *args], cwd=pkg, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    # user code type-checked against the adaptor and its stubs: good use passes, misuse is caught
    (pkg / "use_ok.py").write_text(
        "from rclpy.node import Node\n"
        f"from {PACKAGE} import AvailabilityComponent, GoToComponent, Started\n"
        "from procedures_msgs.srv import ProcedureQuery_Response\n\n\n"
        "def drive(node: Node) -> int:\n"
        "    goto = GoToComponent(node, 'rb1_base_a', timeout=2.0)\n"
        "    started = goto.call_gotoRun(goto.construct_gotoRun_Msg(procedure={'goals': []}))\n"
        "    state: ProcedureQuery_Response = goto.call_gotoQuery(mission_id=started.mission_id)\n"
        "    level: float = AvailabilityComponent(node).get_value(timeout=1.0).robot_status.battery.level\n"
        "    assert isinstance(started, Started)\n"
        "    return state.state.header.id + int(level)\n",
        encoding="utf-8",
    )
    (pkg / "use_bad.py").write_text(
        "from rclpy.node import Node\n"
        f"from {PACKAGE} import GoToComponent\n\n\n"
        "def drive(node: Node) -> str:\n"
        "    goto = GoToComponent(node, 'rb1_base_a')\n"
        "    goto.call_gotoQuery(mission_id='last')\n"
        "    return goto.call_gotoRun().mission_id\n",
        encoding="utf-8",
    )
    mypy = [str(VENV_BIN / "mypy"), "--cache-dir", str(tmp_path / "mypy-cache")]
    proc = subprocess.run([*mypy], cwd=pkg, capture_output=True, text=True)  # setup.cfg: strict, stubs/
    assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = subprocess.run([*mypy, "use_ok.py", "use_bad.py"], cwd=pkg, capture_output=True, text=True)
    lines = [line for line in proc.stdout.splitlines() if ": error:" in line]
    assert all(line.startswith("use_bad.py") for line in lines), proc.stdout
    assert len(lines) == 2, proc.stdout


def test_standard_interfaces_are_lint_and_type_clean(tmp_path: Path) -> None:
    """Other shapes than RB-1's: std_srvs (success-style failures, an empty service), fixed-size float arrays,
    numeric sequences, best-effort QoS."""
    require_ros2()
    path = tmp_path / "td.json"
    path.write_text(json.dumps(std_td()), encoding="utf-8")
    pkg = generate_rclpy(path, tmp_path / "src")
    code = (pkg / pkg.name / "components.py").read_text(encoding="utf-8")
    assert "success_failure" in code and 'qos_profile("best_effort", "volatile", "keep_last", 5)' in code
    stubs = (pkg / "stubs" / "sensor_msgs" / "msg" / "__init__.pyi").read_text(encoding="utf-8")
    assert "orientation_covariance: NDArray[Any]" in stubs and "ranges: array.array[float]" in stubs
    ruff = str(VENV_BIN / "ruff")
    for args in (["check", "--no-cache", "."], ["format", "--check", "--no-cache", "."]):
        proc = subprocess.run([ruff, *args], cwd=pkg, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = subprocess.run(
        [str(VENV_BIN / "mypy"), "--cache-dir", str(tmp_path / "mypy-cache")], cwd=pkg, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_edge_node_entry_point_drops_ros_arguments() -> None:
    # the generated module itself (stdlib only): `ros2 launch` appends --ros-args; users' options stay
    import importlib.util

    path = env.REPO / "generated" / "rclpy" / "robotnik_rb_1_adaptor" / "robotnik_rb_1_adaptor" / "edge_node.py"
    spec = importlib.util.spec_from_file_location("rb1_edge_node", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    user_args = module.user_args
    assert user_args(["td.json", "--robot", "a"]) == ["td.json", "--robot", "a"]
    assert user_args(["td.json", "--ros-args", "-r", "__node:=x"]) == ["td.json"]
    assert user_args(["--ros-args", "-r", "__ns:=/n", "--", "td.json", "--bus", "local"]) == [
        "td.json",
        "--bus",
        "local",
    ]
    assert user_args(["a", "--ros-args", "--", "b", "--ros-args", "-p", "x:=1"]) == ["a", "b"]
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


def test_launch_file_declares_the_documented_arguments_and_installs() -> None:
    # the golden package's launch file as source (ROS 2's launch is not importable here; see
    # tests/runtime/test_edge_node_ros2.py for the installed file and what reaches the node)
    root = env.REPO / "generated" / "rclpy" / PACKAGE
    tree = ast.parse((root / "launch" / "edge_node.launch.py").read_text(encoding="utf-8"))
    (table,) = [n.value for n in tree.body if isinstance(n, ast.Assign) and ast.unparse(n.targets[0]) == "ARGUMENTS"]
    names = [name for name, _default, _text in ast.literal_eval(table)]
    readme = (root / "README.md").read_text(encoding="utf-8").split("## Launch file", 1)[1].split("\n## ", 1)[0]
    assert names == re.findall(r"^\| `(\w+)` \|", readme, re.MULTILINE)
    setup = (root / "setup.py").read_text(encoding="utf-8")
    assert '("share/" + package_name + "/launch", ["launch/edge_node.launch.py"])' in setup
    assert "files = robotnik_rb_1_adaptor, launch/edge_node.launch.py" in (root / "setup.cfg").read_text()
