"""The edge node's layering inside `td2adaptor/runtime/` (docs/architecture.md draws it), from one table.

A runtime module imports modules of its own unit and of lower layers only, units of one layer never import
each other (the robot side and the event side meet in the engine), no import cycle joins two runtime files
(imports inside functions and under TYPE_CHECKING count: a cycle there is a cycle of knowledge), no module
imports a private name of another or uses a private member it does not define itself (a subclass may use
its base class's, `EXTENDS`), and the ROS 1 bridge still runs under an interpreter with the standard library
only (plus td2adaptor itself), as the ROS 1 child does.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from functools import cache
from pathlib import Path

import paho.mqtt.client as paho_client
import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "td2adaptor"
RUNTIME = PACKAGE / "runtime"
#: the runtime's layers, bottom first; a unit is a subpackage of runtime/ or a module directly in it
RUNTIME_LAYERS: tuple[tuple[str, ...], ...] = (
    ("events", "loop"),  # shared bottom: envelopes, ids and parsing; the process's engine loop (events and
    # timers) and call pool
    ("ros", "bus"),  # the robot side (ports, ROS 1 bridge, CDR) and the event side (buses, WoT topics, security;
    # bus/mqttloop.py, the one thread that serves every MQTT connection of the process, under bus/mqttbus.py)
    ("config",),  # one robot's settings: read by the engine and the node
    ("engine",),  # admission, missions, goals, property streams, outbox, replay guard, ledger
    ("node",),  # putting a robot or a fleet together: bus, engine, ROS graph, discovery, `td2adaptor run`
    ("__init__",),  # the public API (names loaded on first use)
)
#: a subclass may use the protected members of its base class's module (DrivenBus is an MqttBus without a
#: network thread; ServedClient a paho Client that holds its writes and reads a plain PUBACK itself)
EXTENDS = {"bus/drivenbus.py": RUNTIME / "bus/mqttbus.py", "bus/mqttloop.py": Path(paho_client.__file__)}
#: what the ROS 1 bridge's child runs under ROS 1's interpreter, with the standard library and td2adaptor only
BRIDGE = "td2adaptor.runtime.ros.bridge"
STDLIB_ONLY = (
    BRIDGE,
    "td2adaptor.runtime.ros.genport",
    "td2adaptor.runtime.ros.port",
    "td2adaptor.runtime.ros",
    "td2adaptor.model.genapi",
)


def _rank() -> dict[str, int]:
    return {unit: i for i, layer in enumerate(RUNTIME_LAYERS) for unit in layer}


def _show(path: Path) -> str:
    return path.relative_to(PACKAGE.parent).as_posix() if path.is_relative_to(PACKAGE.parent) else path.name


def _name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _unit(path: Path) -> str:
    parts = path.relative_to(RUNTIME).parts
    return parts[0] if len(parts) > 1 else Path(parts[0]).stem


@cache
def _modules(root: Path = RUNTIME) -> dict[str, Path]:
    return {_name(p): p for p in sorted(root.rglob("*.py"))}


def _imports(path: Path, modules: dict[str, Path]) -> Iterator[tuple[int, str, tuple[str, ...]]]:
    """(line, runtime module imported, names taken from it) for every import anywhere in `path`."""
    own = next(name for name, p in modules.items() if p == path)
    package = own if path.name == "__init__.py" else own.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in modules:
                    yield node.lineno, alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join([*package.split(".")[: len(package.split(".")) - node.level + 1], base]).strip(".")
            names = tuple(a.name for a in node.names)
            submodules = [f"{base}.{n}" for n in names if f"{base}.{n}" in modules]
            for sub in submodules:
                yield node.lineno, sub, ()
            rest = tuple(n for n in names if f"{base}.{n}" not in modules)
            if base in modules and (rest or not submodules):
                yield node.lineno, base, rest


def _graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    return {m: {dst for _, dst, _ in _imports(p, modules) if dst != m} for m, p in modules.items()}


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import cycle of `graph` (the modules in order, the first again at the end), [] when it has none."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str]:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        path.pop()
        state[node] = 2
        return []

    for start in sorted(graph):
        if start not in state and (found := visit(start)):
            return found
    return []


def _private_uses(path: Path, allowed: frozenset[str] = frozenset()) -> list[str]:
    """`x._name` uses in `path` of a private member that `path` does not define (nor `allowed` names)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    defined = set(allowed)
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            defined.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            defined.add(node.attr)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            defined.add(node.id)
    return sorted(
        f"{_show(path)}:{node.lineno}: {ast.unparse(node)}"
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute)
        and node.attr.startswith("_")
        and not node.attr.startswith("__")
        and node.attr not in defined
    )


def _defined(path: Path) -> frozenset[str]:
    """The private names `path` defines (for its subclasses elsewhere, `EXTENDS`)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            names.add(node.attr)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
    return frozenset(n for n in names if n.startswith("_"))


def test_every_runtime_file_has_a_place_in_the_layers() -> None:
    rank = _rank()
    assert sorted({_unit(p) for p in _modules().values()} - set(rank)) == []
    assert [u for u in rank if u not in {_unit(p) for p in _modules().values()}] == []


def test_runtime_modules_import_their_own_unit_and_lower_layers_only() -> None:
    modules, rank = _modules(), _rank()
    bad = []
    for path in modules.values():
        unit = _unit(path)
        for line, dst, _ in _imports(path, modules):
            other = _unit(modules[dst])
            if other != unit and not rank.get(other, 99) < rank.get(unit, -1):
                bad.append(f"{_show(path)}:{line}: {unit} imports {dst} ({other})")
    assert bad == []


def test_no_import_cycle_joins_runtime_files() -> None:
    assert _cycle(_graph(_modules())) == []


def test_no_runtime_module_imports_a_private_name_of_another() -> None:
    modules = _modules()
    bad = [
        f"{_show(path)}:{line}: {name} from {dst}"
        for path in modules.values()
        for line, dst, names in _imports(path, modules)
        for name in names
        if name.startswith("_")
    ]
    assert bad == []


#: the standard library's public names that start with an underscore (`os._exit`: leave without running a
#: dying process's clean-up, the ROS 1 bridge's child when its parent is gone)
PUBLIC_UNDERSCORED = frozenset({"_exit"})


def test_no_runtime_module_uses_private_members_it_does_not_define() -> None:
    bad = []
    for path in _modules().values():
        base = EXTENDS.get(path.relative_to(RUNTIME).as_posix())
        bad += _private_uses(path, PUBLIC_UNDERSCORED | (_defined(base) if base else frozenset()))
    assert bad == []


@pytest.mark.parametrize("module", ["goals", "streams"])
def test_goals_and_streams_are_handed_objects_not_the_engine(module: str) -> None:
    """They get the engine's outbox and mission table (engine/outbox.py, engine/missions.py), never the
    `Engine`: no import of engine.py, no parameter or attribute named after it."""
    path = RUNTIME / "engine" / f"{module}.py"
    tree = ast.parse(path.read_text(encoding="utf-8"))
    imported = {dst for _, dst, _ in _imports(path, _modules())}
    assert "td2adaptor.runtime.engine.engine" not in imported
    named = {
        n.arg if isinstance(n, ast.arg) else n.attr
        for n in ast.walk(tree)
        if isinstance(n, ast.arg) or (isinstance(n, ast.Attribute) and isinstance(n.ctx, ast.Store))
    }
    assert "engine" not in named
    assert [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Name) and n.id == "Engine"] == []


def test_the_public_api_still_offers_every_name() -> None:
    """`td2adaptor.runtime`'s names (loaded on first use) are found where its map says, also after moves."""
    import td2adaptor.runtime as runtime

    for name in runtime.__all__:
        assert getattr(runtime, name).__name__ == name


def test_the_architecture_page_names_every_runtime_module_in_its_place() -> None:
    """docs/architecture.md's runtime section names each subpackage and, on the lines after it, each of its
    modules (the top-level ones anywhere in the section)."""
    text = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    section = text[text.index("**runtime/**") : text.index("**diagnostics/**")]
    missing = []
    for path in _modules().values():
        if path.name == "__init__.py":
            continue
        unit = _unit(path)
        start = section.find(f"{unit}/") if unit != path.stem else 0
        if start < 0 or not re.search(rf"\b{re.escape(path.stem)}\b", section[start:]):
            missing.append(path.relative_to(RUNTIME).as_posix())
    assert missing == []


def test_the_ros1_bridge_runs_with_the_standard_library_only(tmp_path: Path) -> None:
    """As `Ros1Bridge` starts it: `python -m td2adaptor.runtime.ros.bridge`, td2adaptor through a link and no
    site-packages (`-S`); an empty input ends it at once with status 0."""
    (tmp_path / "td2adaptor").symlink_to(PACKAGE)
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    proc = subprocess.run(
        [sys.executable, "-S", "-m", BRIDGE], input="", capture_output=True, text=True, timeout=60, env=env
    )
    assert proc.returncode == 0, proc.stderr
    for module in STDLIB_ONLY:
        check = [sys.executable, "-S", "-c", f"import {module}"]
        proc = subprocess.run(check, capture_output=True, text=True, timeout=60, env=env)
        assert proc.returncode == 0, proc.stderr


def test_the_scans_see_what_they_look_for(tmp_path: Path) -> None:
    """The checks above are not vacuous: they find a cycle, a private import and a reach-in when one exists."""
    root = tmp_path / "td2adaptor" / "runtime"
    (root / "engine").mkdir(parents=True)
    (root / "__init__.py").write_text("", encoding="utf-8")
    (root / "engine" / "__init__.py").write_text("", encoding="utf-8")
    (root / "engine" / "engine.py").write_text(
        "from td2adaptor.runtime.engine.goals import _helper\nclass Engine:\n    def _finish(self): ...\n",
        encoding="utf-8",
    )
    goals = root / "engine" / "goals.py"
    goals.write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from td2adaptor.runtime.engine import engine\n"
        "def _helper(e):\n    e._finish()\n",
        encoding="utf-8",
    )
    modules = {".".join(p.relative_to(tmp_path).with_suffix("").parts): p for p in root.rglob("*.py")}
    modules = {k.removesuffix(".__init__"): v for k, v in modules.items()}
    cycle = _cycle(_graph(modules))
    assert cycle and set(cycle) == {"td2adaptor.runtime.engine.engine", "td2adaptor.runtime.engine.goals"}
    engine_imports = list(_imports(root / "engine" / "engine.py", modules))
    assert engine_imports == [(1, "td2adaptor.runtime.engine.goals", ("_helper",))]
    assert [u.rpartition(": ")[2] for u in _private_uses(goals)] == ["e._finish"]
