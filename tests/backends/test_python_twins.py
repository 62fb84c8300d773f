"""The rclpy and rospy packages of one TD keep the contract of the generated API (`td2adaptor/model/genapi.py`):
the methods it names, in its shapes, with the same parameter names (also for fields named like Python builtins
or the methods' own parameters), the goal handle's members, one clash check; and they behave alike where their
shared runtime decides: the same refusal of a timeout that would wait forever, the same CallFailed text when
the robot sends an empty message or a bare `success: false`."""

from __future__ import annotations

import ast
import importlib
import json
import math
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from types import ModuleType, SimpleNamespace
from typing import Any

import pytest

import td2adaptor
from td2adaptor.backends.registry import load as load_backend
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GenOptions
from td2adaptor.model import Model, genapi

PACKAGE = "twins_adaptor"
#: request and message fields that clash with builtins (id, type, list) and with call_X's own `timeout`
_SRV = "int32 id\nstring type\nfloat64 timeout\nstring list\n---\nbool success\nstring message\n"
_MSG = "int32 id\nstring type\nfloat64 timeout\n"
#: a response that says failure with `success` alone, no message
_FLAG = "int32 id\n---\nbool success\n"
_PACKAGE_XML = (
    '<?xml version="1.0"?><package format="3"><name>kw_msgs</name><version>0.0.0</version><description>x'
    '</description><maintainer email="a@b.c">a</maintainer><license>MIT</license></package>'
)


def _td() -> dict[str, Any]:
    def form(name: str, rtype: str, op: str | list[str]) -> list[dict[str, Any]]:
        return [{"href": "ros:" + name.strip("/"), "op": op, "rosv:name": name, "rosv:type": rtype}]

    return {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "id": "urn:dev:wot:twins",
        "title": "Twins",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "properties": {
            "state": {
                "rosv:component": "GoComponent",
                "readOnly": True,
                "observable": True,
                "forms": form("/state", "kw_msgs/msg/State", ["readproperty", "observeproperty"]),
            }
        },
        "actions": {
            "go": {
                "rosv:component": "GoComponent",
                "safe": False,
                "idempotent": False,
                "forms": form("/go", "kw_msgs/srv/Go", "invokeaction"),
            },
            "flag": {
                "rosv:component": "GoComponent",
                "safe": False,
                "idempotent": False,
                "forms": form("/flag", "kw_msgs/srv/Flag", "invokeaction"),
            },
        },
    }


@pytest.fixture(scope="module")
def model(tmp_path_factory: pytest.TempPathFactory) -> Model:
    tmp = tmp_path_factory.mktemp("twins")
    pkg = tmp / "ifaces" / "kw_msgs"
    (pkg / "srv").mkdir(parents=True)
    (pkg / "msg").mkdir()
    (pkg / "package.xml").write_text(_PACKAGE_XML, encoding="utf-8")
    (pkg / "srv" / "Go.srv").write_text(_SRV, encoding="utf-8")
    (pkg / "srv" / "Flag.srv").write_text(_FLAG, encoding="utf-8")
    (pkg / "msg" / "State.msg").write_text(_MSG, encoding="utf-8")
    (tmp / "td.json").write_text(json.dumps(_td()), encoding="utf-8")
    result = td2adaptor.compile(tmp / "td.json", interfaces=[tmp / "ifaces"])
    assert result.model is not None, [d.message for d in result.diagnostics]
    return result.model


@pytest.fixture(scope="module")
def trees(model: Model) -> dict[str, dict[str, bytes]]:
    out = {}
    for backend in ("rclpy", "rospy"):
        diags = Diagnostics()
        tree = load_backend(backend).generate(model, GenOptions(package_name=PACKAGE), diags)
        assert not [d for d in diags if d.severity is Severity.ERROR], [d.message for d in diags]
        out[backend] = dict(tree)
    return out


def _components(tree: dict[str, bytes]) -> str:
    (name,) = [n for n in tree if n.endswith(f"{PACKAGE}/components.py")]
    return tree[name].decode("utf-8")


def _api(source: str) -> dict[str, dict[str, list[str]]]:
    """Per component class, its public methods, async ones too (and __init__'s keyword-only part), with their
    parameter names: positional ones, "*", keyword-only ones."""
    api: dict[str, dict[str, list[str]]] = {}
    for node in ast.parse(source).body:
        if not isinstance(node, ast.ClassDef):
            continue
        methods = api.setdefault(node.name, {})
        for f in node.body:
            if not isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            a = f.args
            if f.name == "__init__":
                methods[f.name] = [x.arg for x in a.kwonlyargs]
            elif not f.name.startswith("_"):
                methods[f.name] = [x.arg for x in a.posonlyargs + a.args] + ["*"] + [x.arg for x in a.kwonlyargs]
    return api


def _contract(backend: str, model: Model, component: str) -> dict[str, tuple[str, ...]]:
    """What the contract (`model/genapi.py`) says a component class of `backend` offers: method -> shape."""
    comp = model.component(component)
    groups = (
        (genapi.SERVICE, [s.name for s in comp.services]),
        (genapi.ACTION, [a.name for a in comp.actions]),
        (genapi.SUBSCRIBER, [t.name for t in comp.subscribers]),
        (genapi.PUBLISHER, [t.name for t in comp.publishers]),
    )
    out = {m.pattern: m.shape for m in (genapi.REGISTER, genapi.CLOSE, genapi.SERVERS_READY) if backend in m.backends}
    for methods, names in groups:
        out |= {m(name): m.shape for name in names for m in methods if backend in m.backends}
    if len(comp.subscribers) == 1:
        out[genapi.GET_ONLY.pattern] = genapi.GET_ONLY.shape
    for proc in comp.procedures:
        for role, action in (("query", proc.query), ("cancel", proc.cancel)):
            if action is not None and proc.slot(role):
                call = genapi.CALL(action)
                out[call] = (*out[call][:-1], genapi.MISSION_ID, out[call][-1])
    return out


def _matches(shape: tuple[str, ...], params: list[str]) -> bool:
    """Whether a method's parameters (without self: positional ones, "*", keyword-only ones) have the contract's
    shape; "**fields" stands for the keyword-only fields of a message."""
    if "**fields" in shape:
        return params[: params.index("*")] == []
    return params == ([*shape] if "*" in shape else [*shape, "*"])


def test_both_packages_offer_the_contracts_methods_in_its_shapes(
    trees: dict[str, dict[str, bytes]], model: Model
) -> None:
    for backend in ("rclpy", "rospy"):
        api = _api(_components(trees[backend]))
        assert set(api) == {c.name for c in model.components}
        for cls, methods in api.items():
            contract = _contract(backend, model, cls)
            offered = {name: params[1:] for name, params in methods.items() if name != "__init__"}
            # robot_name: a property in rclpy, an attribute in rospy; the contract counts it among the attributes
            assert set(offered) - set(genapi.ATTRIBUTES) == set(contract), backend
            for name, shape in contract.items():
                assert _matches(shape, offered[name]), (backend, name, offered[name], shape)
    # a field never takes a builtin's or the method's own name (`timeout=` stays the per-call timeout), and both
    # packages name the fields alike
    ros2, ros1 = (_api(_components(trees[b]))["GoComponent"] for b in ("rclpy", "rospy"))
    assert ros2["construct_go_Msg"] == ros1["construct_go_Msg"] == ["self", "*", "id_", "type_", "timeout_", "list_"]


def test_the_goal_handles_offer_what_the_contract_names() -> None:
    """`send_X`/`start_X` return a GoalHandle: both packages' (with their shared GoalRecord) define every member
    the contract names, which the edge node's generated port uses."""
    from td2adaptor.backends import _python, rclpy, rospy

    shared = Path(_python.__file__).parent / "verbatim" / "goals.py"
    own = (
        Path(rclpy.__file__).parent / "verbatim" / "runtime.py",
        Path(rospy.__file__).parent / "verbatim" / "_actions.py",
    )
    for module in own:
        defined: set[str] = set()
        for source in (module, shared):
            for cls in ast.parse(source.read_text(encoding="utf-8")).body:
                if isinstance(cls, ast.ClassDef) and cls.name in ("GoalHandle", "GoalRecord"):
                    for node in ast.walk(cls):
                        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                            defined.add(node.name)
                        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
                            defined.add(node.attr)
                        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                            defined.add(node.target.id)
        assert set(genapi.GOAL_HANDLE) <= defined, (module.name, set(genapi.GOAL_HANDLE) - defined)


def test_one_clash_check_for_both_packages() -> None:
    """An action and a published property of one name, a service `go_async` beside `go` (rclpy's awaitable
    call_go_async), a subscriber `a_serialized` beside `a`: the contract finds each."""
    assert genapi.clashes(services=["go"], publishers=["go"]) == [("construct_go_Msg", "go", "go")]
    assert [c[0] for c in genapi.clashes(services=["go", "go_async"])] == ["call_go_async"]
    assert [c[0] for c in genapi.clashes(subscribers=["a", "a_serialized"])] == ["on_a_serialized"]
    assert genapi.clashes(services=["go"], actions=["fly"], subscribers=["state"], publishers=["cmd"]) == []


@pytest.mark.parametrize(("backend", "code"), [("rclpy", "GEN822"), ("rospy", "GEN841")])
def test_both_backends_refuse_a_clash_alike(model: Model, backend: str, code: str) -> None:
    """rospy has no call_X_async, but refuses a service `go_async` beside `go` as rclpy does: one TD gives both
    packages the same names, or neither gets generated."""
    comp = model.components[0]
    twin = replace(comp.service("go"), name="go_async")
    clashing = replace(model, components=(replace(comp, services=(*comp.services, twin)),))
    diags = Diagnostics()
    load_backend(backend).generate(clashing, GenOptions(package_name=PACKAGE), diags)
    errors = [d for d in diags if d.severity is Severity.ERROR]
    assert [d.code for d in errors] == [code] and "call_go_async" in errors[0].message, [d.message for d in errors]


@pytest.fixture(scope="module")
def rclpy_runtime(trees: dict[str, dict[str, bytes]], tmp_path_factory: pytest.TempPathFactory) -> Iterator[ModuleType]:
    root = tmp_path_factory.mktemp("twins_rclpy")
    for name, data in trees["rclpy"].items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    # the package without its __init__ (components.py imports kw_msgs, which is not built here)
    package = ModuleType(PACKAGE)
    package.__path__ = [str(root / PACKAGE / PACKAGE)]
    sys.modules[PACKAGE] = package
    try:
        yield importlib.import_module(f"{PACKAGE}.runtime")
    finally:
        for mod in [m for m in sys.modules if m == PACKAGE or m.startswith(PACKAGE + ".")]:
            del sys.modules[mod]


@pytest.mark.parametrize("timeout", [math.nan, math.inf, -1.0, 0.0])
def test_rclpy_refuses_a_per_call_timeout_that_would_wait_forever_as_rospy_does(
    rclpy_runtime: ModuleType, timeout: float
) -> None:
    # checked before the node is touched (no node is needed to see the refusal)
    client = rclpy_runtime.ServiceClient(None, object, "/go")
    with pytest.raises(ValueError, match="timeout must be a positive finite number of seconds"):
        client.call(object(), timeout, 1.0)
    with pytest.raises(ValueError, match="wait_timeout must be a positive finite number of seconds"):
        client.call(object(), 1.0, timeout)
    subscriber = rclpy_runtime.TopicSubscriber(None, object, "/state", None)
    with pytest.raises(ValueError, match="timeout must be a positive finite number of seconds"):
        subscriber.latest(timeout)


def test_an_empty_robot_message_gives_the_same_call_failed_text(
    trees: dict[str, dict[str, bytes]], rclpy_runtime: ModuleType
) -> None:
    common = importlib.import_module(f"{PACKAGE}.common")
    empty = SimpleNamespace(success=False, message="")
    assert rclpy_runtime.success_failure(empty) == common.FAILURE_WITHOUT_MESSAGE == "the robot reported a failure"
    error = SimpleNamespace(result=SimpleNamespace(result="error", message=""))
    assert rclpy_runtime.procedure_failure(error) == common.ERROR_WITHOUT_MESSAGE
    # rospy's generated call_go says the same: the shared constant when the robot's message is empty
    ros1 = _components(trees["rospy"])
    assert "CallFailed(self._svc_go.name, response.message or FAILURE_WITHOUT_MESSAGE, response)" in ros1
    imported = ros1.split("from .common import", 1)[1]
    imported = imported.split(")", 1)[0] if imported.lstrip().startswith("(") else imported.split("\n", 1)[0]
    assert "FAILURE_WITHOUT_MESSAGE" in imported.replace(",", " ").split()
    # and rclpy's checks the response with success_failure
    assert "success_failure" in _components(trees["rclpy"])
    assert trees["rospy"][f"{PACKAGE}/src/{PACKAGE}/common.py"] == trees["rclpy"][f"{PACKAGE}/{PACKAGE}/common.py"]


def test_a_response_with_success_alone_fails_alike(
    trees: dict[str, dict[str, bytes]], rclpy_runtime: ModuleType
) -> None:
    """`success` false without a message field: both packages raise CallFailed with the shared text (the rule is
    the model's, `Failure.SUCCESS_ONLY`; rclpy used to return such a response as a success)."""
    common = importlib.import_module(f"{PACKAGE}.common")
    assert rclpy_runtime.success_only_failure(SimpleNamespace(success=False)) == common.FAILURE_WITHOUT_MESSAGE
    assert rclpy_runtime.success_only_failure(SimpleNamespace(success=True)) is None
    ros2 = _components(trees["rclpy"])
    assert "success_only_failure" in ros2.split("self._flag: ServiceClient", 1)[1].split(")\n", 1)[0]
    ros1 = _components(trees["rospy"])
    assert "if not response.success:\n            raise CallFailed(self._svc_flag.name, FAILURE_WITHOUT_MESSAGE" in ros1
