"""Placeholder values from the command line (`--set NAME=VALUE`) and from `--values` files (JSON or YAML)."""

from __future__ import annotations

import json
import math
from collections.abc import Hashable, Sequence
from functools import cache
from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity, pointer_join
from td2adaptor.frontend.jsonsrc import load_path


def _parse_value(raw: str) -> Any:
    """JSON if the text is JSON (so numbers, booleans, arrays keep their type), else the text itself."""

    def reject(name: str) -> Any:
        raise ValueError(name)

    try:
        value = json.loads(raw, parse_constant=reject)
    except ValueError:
        return raw
    if isinstance(value, float) and not math.isfinite(value):
        return raw
    return value


def parse_set_options(items: Sequence[str], diags: Diagnostics) -> dict[str, Any]:
    """`--set NAME=VALUE` items → a placeholder map; VALUE is JSON when it parses as JSON, else a string."""
    values: dict[str, Any] = {}
    for item in items:
        name, sep, raw = item.partition("=")
        name = name.strip()
        if name.startswith("{{") and name.endswith("}}"):
            name = name[2:-2].strip()  # accept --set '{{NAME}}=...' as well
        if not sep or not name:
            diags.add(
                "TM305",
                Severity.ERROR,
                f"--set {item!r}: expected NAME=VALUE",
                hint="e.g. --set MAX_SPEED=1.5 or --set robotName=rb1_base_a",
                file="--set",
            )
            continue
        if name in values:
            diags.add(
                "TM306",
                Severity.WARNING,
                f"--set {name} given more than once: the last value wins",
                file="--set",
            )
        values[name] = _parse_value(raw)
    return values


@cache
def _map_loader() -> Any:
    """Safe YAML that keeps dates as strings (they reach the TD as written) and rejects duplicate keys.

    Built on first use: PyYAML is only imported when a YAML value map is read.
    """
    import yaml  # type: ignore[import-untyped, unused-ignore]  # types-PyYAML is a test extra

    class MapLoader(yaml.SafeLoader):  # type: ignore[misc, unused-ignore]  # Any without types-PyYAML
        def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Hashable, Any]:
            seen: set[Any] = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                if isinstance(key, Hashable):
                    if key in seen:
                        raise yaml.constructor.ConstructorError(
                            None, None, f"duplicate key {key!r}", key_node.start_mark
                        )
                    seen.add(key)
            mapping: dict[Hashable, Any] = super().construct_mapping(node, deep)
            return mapping

    MapLoader.yaml_implicit_resolvers = {
        first: [(tag, rx) for tag, rx in resolvers if tag != "tag:yaml.org,2002:timestamp"]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
    }
    return MapLoader


def _json_problem(value: Any, pointer: str) -> tuple[str, str] | None:
    """(pointer, what) of the first value JSON cannot represent, if any."""
    if isinstance(value, dict):
        for key, item in value.items():
            if not isinstance(key, str):
                return pointer, f"key {key!r} is not a string"
            found = _json_problem(item, pointer_join(pointer, key))
            if found:
                return found
        return None
    if isinstance(value, list):
        for i, item in enumerate(value):
            found = _json_problem(item, pointer_join(pointer, i))
            if found:
                return found
        return None
    if isinstance(value, float) and not math.isfinite(value):
        return pointer, f"{value} is not a JSON number"
    if value is None or isinstance(value, (str, int, float, bool)):
        return None
    return pointer, f"{type(value).__name__} values are not JSON"


def load_placeholder_map(path: Path, diags: Diagnostics) -> dict[str, Any] | None:
    """Read a `--values` file (.json, .yaml or .yml): one object of placeholder name → value."""
    name = str(path)
    suffix = path.suffix.lower()
    before = len(diags.errors())
    data: Any
    if suffix == ".json":
        doc = load_path(name, diags)
        if doc is None or len(diags.errors()) > before:
            return None
        data = doc.data
    elif suffix in (".yaml", ".yml"):
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            diags.add("TM307", Severity.ERROR, f"cannot read {name}: {reason}", file=name)
            return None
        import yaml  # type: ignore[import-untyped, unused-ignore]  # types-PyYAML is a test extra

        try:
            data = yaml.load(text, Loader=_map_loader())
        except (yaml.YAMLError, ValueError, TypeError) as exc:  # bad !!int/!!float raise ValueError
            mark = getattr(exc, "problem_mark", None)
            problem = getattr(exc, "problem", None) or str(exc)
            line, col = (mark.line + 1, mark.column + 1) if mark is not None else (None, None)
            diags.append(Diagnostic("TM307", Severity.ERROR, f"invalid YAML: {problem}", "", None, name, line, col))
            return None
        except RecursionError:
            diags.add("TM307", Severity.ERROR, "YAML nesting is too deep to process", file=name)
            return None
    else:
        diags.add(
            "TM307",
            Severity.ERROR,
            f"cannot tell the format of {name} from its extension {suffix or '(none)'}",
            hint="name the placeholder map *.json, *.yaml or *.yml",
            file=name,
        )
        return None
    if not isinstance(data, dict):
        got = "empty" if data is None else f"a {type(data).__name__}"
        diags.add(
            "TM308",
            Severity.ERROR,
            f"a placeholder map must be an object of NAME: value, but {name} is {got}",
            hint='e.g. {"robotName": "rb1_base_a", "MAX_SPEED": 1.5}',
            file=name,
        )
        return None
    try:
        problem = _json_problem(data, "")
    except RecursionError:
        problem = ("", "nesting is too deep (or a value contains itself)")
    if problem is not None:
        diags.add("TM308", Severity.ERROR, f"placeholder map {name}: {problem[1]}", problem[0], file=name)
        return None
    return data
