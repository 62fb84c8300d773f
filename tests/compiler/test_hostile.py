"""Hostile TDs: no TD string can become code in any generated file; hostile names are rejected.

For each variant the generated tree is compared with the clean RB-1 tree: Python files must have the same
AST once string constants are blanked (payloads may only change string contents), XML the same element
structure, setup.cfg the same sections and keys; in C/C++, CMake and Makefiles the marker may only appear
inside string literals or comments. Nothing generated here is ever executed.
"""

from __future__ import annotations

import ast
import configparser
import io
import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
import yaml

import td2adaptor
from td2adaptor.backends.registry import available
from td2adaptor.compiler.build import generate_trees
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GeneratedTree
from tests.compiler.hostile_corpus import MARK, name_variants, variants
from tests.conftest import EXAMPLE

INTERFACES = [EXAMPLE / "interfaces"]


CLEAN_PACKAGE = "robotnik_rb_1_adaptor"


def _trees(td: dict[str, Any]) -> dict[str, GeneratedTree] | None:
    result = td2adaptor.compile("-", stdin=io.BytesIO(json.dumps(td).encode()), interfaces=INTERFACES)
    if result.model is None:
        return None
    # a hostile title yields a different, but always safe, package name (REP 144 characters only);
    # the structural comparison below pins the name so that file paths and imports line up
    assert re.fullmatch(r"[a-z][a-z0-9_]*_adaptor", result.model.package_name), result.model.package_name
    diags = Diagnostics()
    # the mROS tree stated to take the RB-1 types' TCPROS headers (MROS914 otherwise), as pyproject.toml does
    limits = (("mros.tcpros_header_max", 8192),)
    trees = generate_trees(
        result.model, available(), diags, partial=True, package_name=CLEAN_PACKAGE, backend_options=limits
    )
    assert trees is not None, [d.message for d in diags if d.severity is Severity.ERROR]
    return trees


@pytest.fixture(scope="module")
def clean() -> dict[str, GeneratedTree]:
    trees = _trees(json.loads((EXAMPLE / "td.json").read_text()))
    assert trees is not None
    return trees


class _Blank(ast.NodeTransformer):
    def visit_Constant(self, node: ast.Constant) -> ast.AST:
        return ast.Constant("") if isinstance(node.value, str) else node

    def visit_JoinedStr(self, node: ast.JoinedStr) -> ast.AST:
        return ast.Constant("")


def _py_shape(data: bytes) -> str:
    return ast.dump(_Blank().visit(ast.parse(data.decode("utf-8"))))


def _xml_shape(data: bytes) -> list[tuple[str, tuple[str, ...]]]:
    return [(el.tag, tuple(sorted(el.attrib))) for el in ET.fromstring(data).iter()]


_C_TOKENS = re.compile(r'"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\'|/\*.*?\*/|//[^\n]*', re.S)


def _code_outside_literals(data: bytes, suffix: str) -> str:
    text = data.decode("utf-8")
    if suffix in (".h", ".hpp", ".cpp", ".cc", ".c", ".cfg"):
        return _C_TOKENS.sub(" ", text)
    return "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))


def _check_file(rel: str, data: bytes, clean: GeneratedTree) -> None:
    suffix = Path(rel).suffix
    name = Path(rel).name
    if suffix in (".py", ".pyi"):
        assert _py_shape(data) == _py_shape(clean.files[rel]), f"{rel}: Python structure changed"
    elif suffix == ".xml":
        assert _xml_shape(data) == _xml_shape(clean.files[rel]), f"{rel}: XML structure changed"
    elif suffix in (".json", ".jsonld"):
        json.loads(data)
    elif suffix in (".yaml", ".yml"):
        yaml.safe_load(data)
    elif name == "setup.cfg":
        shapes = []
        for blob in (data, clean.files[rel]):
            cp = configparser.ConfigParser(interpolation=None)
            cp.read_string(blob.decode("utf-8"))
            shapes.append({s: sorted(cp[s]) for s in cp.sections()})
        assert shapes[0] == shapes[1], f"{rel}: setup.cfg structure changed"
    elif suffix in (".md", ".txt", ".rst") or name in ("README", "LICENSE"):
        return  # documentation: any text is fine
    else:
        assert MARK not in _code_outside_literals(data, suffix), f"{rel}: payload outside literals/comments"


@pytest.mark.parametrize(
    ("label", "td"), list(variants(EXAMPLE / "td.json")), ids=lambda v: v if isinstance(v, str) else ""
)
def test_payloads_never_become_code(label: str, td: dict[str, Any], clean: dict[str, GeneratedTree]) -> None:
    trees = _trees(td)
    assert trees is not None, label
    assert trees.keys() == clean.keys()
    for backend, tree in trees.items():
        assert set(tree.files) == set(clean[backend].files), f"{backend}: file set changed"
        for rel, data in tree:
            _check_file(rel, data, clean[backend])


@pytest.mark.parametrize(
    ("label", "td"), list(name_variants(EXAMPLE / "td.json")), ids=lambda v: v if isinstance(v, str) else ""
)
def test_hostile_names_are_rejected(label: str, td: dict[str, Any]) -> None:
    result = td2adaptor.compile("-", stdin=io.BytesIO(json.dumps(td).encode()), interfaces=INTERFACES)
    assert result.model is None, label
    codes = {d.code for d in result.diagnostics if d.severity is Severity.ERROR}
    assert codes & {"ROS409", "ROS410", "ROS430", "ROS431", "ROS441", "ROS442"}, (label, codes)
