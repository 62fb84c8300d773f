"""Injection attempts against every TD string that can reach generated code.

Each payload tries to end the literal or comment it lands in (Python, C/C++, XML, CMake, setup.cfg, YAML,
JSON) and run or declare something. `MARK` appears in every payload: after generation it may only ever be
inside a string literal or a comment, never in code.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

MARK = "PWNED"

PAYLOADS = [
    f'"""\nimport os; os.system("touch /tmp/{MARK}")\n"""',
    f"'''\n__import__('os').system('{MARK}')\n'''",
    f'\\"; {MARK}(); x = "',
    f"*/ int {MARK}() {{ return 0; }} /*",
    f"\n#include <{MARK}.h>\n",
    f"??/\n{MARK}();",
    f'"); system("{MARK}"); //',
    f"</description><exec_depend>{MARK}</exec_depend><description>",
    f"]]><!-- {MARK} --><![CDATA[",
    f'\n[{MARK}]\nscript = "x"\n',
    f"\r\n{MARK}: !!python/object/apply:os.system ['id']",
    f"${{{MARK}}} $({MARK}) `{MARK}`",
    f"\u2028{MARK}\u2029\x00\x1b[31m",
    f"\\\n{MARK} = 1",
    f"{{{{robotName}}}} {MARK} {{% raw %}}{{{{ {MARK} }}}}",
]

BAD_NAMES = ["class", "import os", "a-b", "__init__", "9x", f"x;{MARK}", "", "namespace", f"{MARK}\n"]


def _text_positions(td: dict[str, Any]) -> Iterator[Callable[[dict[str, Any], str], None]]:
    """Setters for every free-text slot: titles, descriptions (all languages), enums, defaults, constants."""

    def setter(path: list[Any], key: str) -> Callable[[dict[str, Any], str], None]:
        def put(doc: dict[str, Any], value: str) -> None:
            node: Any = doc
            for p in path:
                node = node[p]
            node[key] = value

        return put

    yield setter([], "title")
    yield setter([], "description")
    yield lambda doc, v: doc.__setitem__("descriptions", {"en": v, "de": v + " (de)", "ja": v + " 日本"})
    for group in ("actions", "properties"):
        for name in td[group]:
            yield setter([group, name], "title")
            yield setter([group, name], "description")
            yield lambda doc, v, g=group, n=name: doc[g][n].__setitem__("titles", {"en": v, "fr": v})
    yield lambda doc, v: doc["properties"]["door"]["properties"]["data"].__setitem__("default", v)
    yield lambda doc, v: doc["properties"]["door"]["properties"]["data"].__setitem__("enum", [v, "x"])


def variants(base: Path) -> Iterator[tuple[str, dict[str, Any]]]:
    """(label, TD) pairs: each payload in each text slot of the RB-1 TD (payloads rotated over slots)."""
    td = json.loads(base.read_text())
    setters = list(_text_positions(td))
    for i in range(len(PAYLOADS)):
        doc = copy.deepcopy(td)
        for j, put in enumerate(setters):
            put(doc, PAYLOADS[(i + j) % len(PAYLOADS)])
        yield f"payload{i}", doc


def name_variants(base: Path) -> Iterator[tuple[str, dict[str, Any]]]:
    """Hostile affordance, component and ROS names: each must be rejected (never mangled into code)."""
    td = json.loads(base.read_text())
    for i, bad in enumerate(BAD_NAMES):
        doc = copy.deepcopy(td)
        doc["actions"][bad] = doc["actions"].pop("gotoRun")
        doc["actions"]["gotoQuery"]["rosv:component"] = "GoToComponent"
        yield f"action-name{i}", doc
        doc = copy.deepcopy(td)
        doc["properties"]["door"]["rosv:component"] = bad
        yield f"component-name{i}", doc
        if bad in ("class", "namespace"):
            continue  # valid ROS names (keywords only matter for identifiers)
        doc = copy.deepcopy(td)
        doc["properties"]["door"]["forms"][0]["rosv:name"] = "/door1/" + bad
        yield f"ros-name{i}", doc
