"""The layering of td2adaptor's packages, from one table (`STANDS_ON`; docs/architecture.md draws it).

Each package (a folder of td2adaptor/, or a module beside them) may import its own modules and the packages it
stands on, directly or through another; never one above or beside it. Imports inside functions and under
TYPE_CHECKING count: a lazy import is still knowledge of the other package. No import cycle joins two packages
or two files. The model is what the stages meet on, so it sits at the bottom with `support` and `diagnostics`;
the back half (generation, backends) and the runtime read the model and never the front half (frontend,
rostypes, lowering); the compiler drives both halves. A new package fails here until it has a place.
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

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "td2adaptor"

#: every package and the packages it stands on directly, bottom first
STANDS_ON: dict[str, tuple[str, ...]] = {
    "support": (),  # small services any stage may use: the cache directory, atomic writes, JSON text, builds
    "diagnostics": (),  # diagnostics as values and the one catalogue of codes
    "model": ("support", "diagnostics"),  # the canonical model, the event contract, the exposed TD
    "frontend": ("model",),  # inputs: JSON with positions, conformance, terms, JSON-LD, Thing Models, extract
    "rostypes": ("model",),  # which ROS interface types exist and what they contain, per distribution
    "lowering": ("frontend", "rostypes"),  # raw bindings and types into the model
    "generation": ("model",),  # what backends are built on: targets, the backend interface, templates, emit
    "backends": ("generation",),  # one folder per output kind, and the registry that finds them
    "compiler": ("lowering", "backends"),  # drives it all: compile (with its result cache) and the build
    "runtime": ("model",),  # the edge node: bus events to ROS calls (tests/runtime/test_layers.py: its inside)
    "dashboard": ("runtime",),  # the operator's web page of a fleet on the bus (`td2adaptor dashboard`)
    "scaffold": ("rostypes",),  # the other way: from a running robot, a bag or a listing to a TD
    "api": ("compiler",),  # generate and check for build scripts
    "__init__": ("api",),  # the library's names (load, validate, compile, generate, check), loaded on first use
    "cli": ("__init__", "runtime", "scaffold", "dashboard"),  # the command line
    "__main__": ("cli",),  # python -m td2adaptor
}

#: what each lower layer must not import (packages above it in the pipeline, or beside it as doors); the
#: compiler drives generation since the build moved there, so it is no longer one of them
FORBIDDEN = ("td2adaptor.backends", "td2adaptor.generation", "td2adaptor.cli")
LAYERS = ("frontend", "rostypes", "lowering", "model", "runtime", "scaffold", "diagnostics", "support", "dashboard")


def _name(path: Path, root: Path) -> str:
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@cache
def _modules(root: Path = PACKAGE) -> dict[str, Path]:
    """Every module of td2adaptor by its dotted name (the backends' verbatim files run inside generated
    packages, not as td2adaptor modules: they are checked there)."""
    return {_name(p, root): p for p in sorted(root.rglob("*.py")) if "verbatim" not in p.relative_to(root).parts}


def _unit(module: str) -> str:
    """The package of the table a module belongs to (`td2adaptor` itself is `__init__`)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _known(name: str, modules: dict[str, Path]) -> str | None:
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def _root_names_used(tree: ast.AST, root: str) -> bool:
    """Whether a module that did `import td2adaptor` uses one of its names (not just `__file__`, `__version__`):
    the package itself is loaded before any of its modules, its lazy names are the library's door."""
    return any(
        isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and n.value.id == root and n.attr[:2] != "__"
        for n in ast.walk(tree)
    )


def _imports(path: Path, modules: dict[str, Path]) -> Iterator[tuple[int, str]]:
    """(line, td2adaptor module) for every import anywhere in `path`, relative ones resolved."""
    own = next(name for name, p in modules.items() if p == path)
    root = own.split(".")[0]
    package = own if path.name == "__init__.py" else own.rpartition(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == root and not (alias.asname is None and _root_names_used(tree, root)):
                    continue
                if found := _known(alias.name, modules):
                    yield node.lineno, found
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join([*parts[: len(parts) - node.level + 1], base]).strip(".")
            found: set[str] = set()
            for alias in node.names:
                if f"{base}.{alias.name}" in modules:
                    found.add(f"{base}.{alias.name}")
                elif base == root and alias.name[:2] == "__":
                    continue  # `from td2adaptor import __version__`: the package itself, see _root_names_used
                elif known := _known(base, modules):
                    found.add(known)
            yield from ((node.lineno, name) for name in sorted(found))


def _allowed() -> dict[str, frozenset[str]]:
    """Each package and every package below it (the closure of `STANDS_ON`)."""
    allowed: dict[str, frozenset[str]] = {}

    def below(unit: str) -> frozenset[str]:
        if unit not in allowed:
            allowed[unit] = frozenset().union(*({d} | below(d) for d in STANDS_ON[unit]))
        return allowed[unit]

    for unit in STANDS_ON:
        below(unit)
    return allowed


def _show(path: Path, root: Path) -> str:
    return path.relative_to(root.parent).as_posix()


def _against_the_order(modules: dict[str, Path], root: Path = PACKAGE) -> list[str]:
    allowed = _allowed()
    bad = []
    for name, path in modules.items():
        unit = _unit(name)
        for line, dst in _imports(path, modules):
            other = _unit(dst)
            if other != unit and other not in allowed.get(unit, frozenset()):
                bad.append(f"{_show(path, root)}:{line}: {unit} imports {dst} ({other} is not below {unit})")
    return bad


def _file_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    return {m: {dst for _, dst in _imports(p, modules) if dst != m} for m, p in modules.items()}


def _package_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for src, dsts in _file_graph(modules).items():
        graph.setdefault(_unit(src), set()).update(_unit(d) for d in dsts if _unit(d) != _unit(src))
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected parts of `graph` with more than one node (each sorted): its import cycles."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            part = stack[stack.index(node) :]
            del stack[stack.index(node) :]
            if len(part) > 1:
                found.append(sorted(part))

    for start in sorted(graph):
        if start not in index:
            visit(start)
    return sorted(found)


def _explain(cycles: list[list[str]], graph: dict[str, set[str]]) -> list[str]:
    """Each cycle with the imports inside it (`a -> b`)."""
    return [
        f"{' / '.join(c)}: " + ", ".join(f"{a} -> {b}" for a in c for b in sorted(graph[a]) if b in c) for c in cycles
    ]


def test_every_package_has_a_place_in_the_table() -> None:
    units = {_unit(m) for m in _modules()}
    assert sorted(units - set(STANDS_ON)) == []
    assert sorted(set(STANDS_ON) - units) == []


def test_the_table_is_an_order() -> None:
    """It names only its own packages, and no package stands on itself, however far down."""
    assert [d for deps in STANDS_ON.values() for d in deps if d not in STANDS_ON] == []
    assert [u for u, below in _allowed().items() if u in below] == []


def test_no_import_runs_against_the_layers() -> None:
    assert _against_the_order(_modules()) == []


def test_no_import_cycle_joins_two_packages() -> None:
    graph = _package_graph(_modules())
    assert _explain(_cycles(graph), graph) == []


def test_no_import_cycle_joins_two_files() -> None:
    graph = _file_graph(_modules())
    assert _explain(_cycles(graph), graph) == []


def _lower_imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
    return found


@pytest.mark.parametrize("layer", LAYERS)
def test_a_stage_imports_no_backend_generation_or_cli(layer: str) -> None:
    """A second fence, apart from the table: loosening `STANDS_ON` does not let a stage, the runtime or the
    scaffold reach into a backend, generation or the CLI."""
    bad = [
        f"{path.relative_to(PACKAGE.parent)}:{line}: {name}"
        for path in sorted((PACKAGE / layer).rglob("*.py"))
        if "verbatim" not in path.parts
        for line, name in _lower_imports(path)
        if name.startswith(FORBIDDEN)
    ]
    assert bad == []


def test_the_scan_sees_a_forbidden_import(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from td2adaptor.backends.events.generator import dump\n", encoding="utf-8")
    assert _lower_imports(module) == [(2, "td2adaptor.backends.events.generator")]


def test_the_checks_see_what_they_look_for(tmp_path: Path) -> None:
    """Not vacuous: an upward import inside a function, a relative one under TYPE_CHECKING, the package's lazy
    names, a package cycle and a file cycle are all found; `__version__` and `__file__` are not imports."""
    root = tmp_path / "td2adaptor"
    files = {
        "__init__.py": "__version__ = '0'\n",
        "model/__init__.py": "def f():\n    from td2adaptor.frontend import terms\n",
        "frontend/__init__.py": "",
        "frontend/terms.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..model import f\n",
        "support/a.py": "from td2adaptor import __version__\nfrom . import b\n",
        "support/b.py": "import td2adaptor\nPATH = td2adaptor.__file__\nimport td2adaptor.support.a\n",
        "runtime/__init__.py": "import td2adaptor\nX = td2adaptor.compile\n",
    }
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text, encoding="utf-8")
    modules = _modules(root)
    assert _against_the_order(modules, root) == [
        "td2adaptor/model/__init__.py:2: model imports td2adaptor.frontend.terms (frontend is not below model)",
        "td2adaptor/runtime/__init__.py:1: runtime imports td2adaptor (__init__ is not below runtime)",
    ]
    assert _cycles(_package_graph(modules)) == [["frontend", "model"]]
    files_graph = _file_graph(modules)
    assert _cycles(files_graph) == [
        ["td2adaptor.frontend.terms", "td2adaptor.model"],
        ["td2adaptor.support.a", "td2adaptor.support.b"],
    ]
    assert _explain([["td2adaptor.support.a", "td2adaptor.support.b"]], files_graph) == [
        "td2adaptor.support.a / td2adaptor.support.b: td2adaptor.support.a -> td2adaptor.support.b, "
        "td2adaptor.support.b -> td2adaptor.support.a"
    ]


_LOADED = """
import sys
from td2adaptor.cli.main import cli
try:
    cli.main(sys.argv[1:], standalone_mode=False)
except SystemExit as exc:
    assert exc.code == 0, exc.code
print(" ".join(sorted(m for m in sys.modules if m.startswith(("td2adaptor.generation", "td2adaptor.backends")))))
"""


def test_the_front_end_commands_load_no_generation(tmp_path: Path) -> None:
    """`validate` of two TDs groups them as `gen` does (compiler/units) without loading the build, and with it
    generation and the backends (it did through generation.build)."""
    examples = PACKAGE.parent / "examples"
    args = ["validate", "--no-cache", *(str(examples / e / "td.json") for e in ("nav_base", "robotnik_rb1"))]
    args += [f"--interfaces={examples / e / 'interfaces'}" for e in ("nav_base", "robotnik_rb1")]
    env = {**os.environ, "TD2ADAPTOR_CACHE_DIR": str(tmp_path)}
    proc = subprocess.run(
        [sys.executable, "-c", _LOADED, *args], capture_output=True, text=True, timeout=120, env=env, check=False
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == []


#: the packages whose paragraph of docs/architecture.md names their modules (the runtime has its own check)
_DESCRIBED = (
    "frontend",
    "rostypes",
    "lowering",
    "model",
    "compiler",
    "generation",
    "backends",
    "scaffold",
    "support",
    "cli",
    "dashboard",
)


@pytest.mark.parametrize("unit", _DESCRIBED)
def test_the_architecture_page_describes_each_module_in_its_package(unit: str) -> None:
    """Each module (or subpackage) of the package is named in its paragraph, and no module of another package
    is named there as if it were one of this package's (a package of the table may be): a moved module is
    described where it went."""
    text = (PACKAGE.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    start = text.index(f"\n**{unit}/**")
    paragraph = text[start : text.find("\n\n", start + 1)]
    named = {path.stem for path in (PACKAGE / unit).glob("*.py") if path.name != "__init__.py"}
    named |= {path.parent.name for path in (PACKAGE / unit).glob("*/__init__.py")}
    missing = sorted(name for name in named if not re.search(rf"`{re.escape(name)}[/.`]", paragraph))
    elsewhere = {name.rpartition(".")[2] for name in _modules()} - named - set(STANDS_ON)
    stale = sorted(set(re.findall(r"`(\w+)/?`", paragraph)) & elsewhere)
    assert (missing, stale) == ([], [])
