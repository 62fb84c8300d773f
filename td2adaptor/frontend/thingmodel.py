"""Thing Model → Thing Description instantiation, and checking a TD against the model it links.

A robot vendor describes a robot *type* once as a Thing Model (TM) and every robot of that type becomes a TD
by filling in placeholders. Instantiation runs in this order, so that each step sees what it needs:

1. `tm:ref` imports are expanded in every file as written (hrefs relative to the file holding them; `#/...`
   points into the same file as written, not into what it inherits); the local keys of the referencing
   object are applied to the imported definition as a JSON Merge Patch (RFC 7396: objects merge
   recursively, `null` deletes, arrays and scalars replace).
2. `tm:extends` parents are resolved recursively (local files only: td2adaptor never goes to the network) and
   merged under the child: affordances (`properties`/`actions`/`events`) merge by name, and an affordance
   both define is the parent's definition merge-patched by the child's, so a child can narrow one field
   (`"dim": {"maximum": 200}`) or delete one (`null`) without repeating the rest; `securityDefinitions`,
   `schemaDefinitions` and `uriVariables` merge by name with the child's entry replacing the parent's whole;
   `links`, `@context`, `@type` and `tm:optional` are ordered unions; any other key is the child's if it
   has one. With several parents, later ones win over earlier ones.
3. `tm:optional` affordances the user did not select are dropped (before substitution, so their
   placeholders need no values).
4. `{{NAME}}` placeholders are substituted: a string that is exactly one placeholder takes the typed value,
   others are replaced textually (non-strings as compact JSON), in object keys too.
5. The result is turned into a TD: `@type`, `@context`, the `rel: type` link, security defaults.

Every problem is a diagnostic (codes in `CODES`); nothing raises on bad input.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
from collections.abc import Callable, Collection, Hashable, Mapping, Sequence
from functools import cache
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity, pointer_join, pointer_tokens
from td2adaptor.frontend.jsonsrc import JsonDocument, load_path, parse_json

CODES: dict[str, str] = {
    "TM300": "the document to instantiate is not a Thing Model",
    "TM301": "placeholders without a value",
    "TM302": "runtime placeholders left in place",
    "TM303": "placeholder values not used by the model",
    "TM304": "two keys of an object became equal after placeholder substitution",
    "TM305": "malformed --set item",
    "TM306": "placeholder given more than once",
    "TM307": "placeholder map file cannot be read or parsed",
    "TM308": "placeholder map has the wrong shape",
    "TM309": "model too deeply nested to process",
    "TM310": "referenced Thing Model file not found",
    "TM311": "remote Thing Model not fetched",
    "TM312": "tm:extends cycle",
    "TM313": "malformed tm:extends link",
    "TM314": "extended document is not a Thing Model",
    "TM320": "malformed tm:ref",
    "TM321": "tm:ref target not found",
    "TM322": "tm:ref cycle",
    "TM323": "too many tm:ref imports",
    "TM330": "malformed tm:optional",
    "TM331": "tm:optional entry does not point to a whole affordance",
    "TM332": "selected optional affordance is not declared optional",
    "TM333": "optional affordances left out",
    "TM340": "@context adjusted for a Thing Description",
    "TM341": "no security in the model: nosec added",
    "TM342": "model has only part of the security configuration",
    "TM343": "affordance without forms",
    "TM344": "model has no title",
    "TM345": "instance version added",
    "TM346": "version is not an object",
    "TM347": "tm:submodel links are not instantiated",
    "TM348": "Thing Model terms dropped",
    "TM349": "no rel=type link added",
    "TM350": "linked Thing Model not fetched",
    "TM351": "linked Thing Model cannot be used",
    "TM352": "affordance of the linked Thing Model missing in the TD",
    "TM353": "affordance data type differs from the linked Thing Model",
}

TM_TYPE = "tm:ThingModel"
TM_TYPE_IRI = "https://www.w3.org/2019/wot/tm#ThingModel"
TD_CONTEXT_V1 = "https://www.w3.org/2019/wot/td/v1"
TD_CONTEXT_V11 = "https://www.w3.org/2022/wot/td/v1.1"
TM_MEDIA_TYPE = "application/tm+json"
AFFORDANCE_KINDS = ("properties", "actions", "events")
_KIND = {"properties": "property", "actions": "action", "events": "event"}
_BY_NAME_REPLACE = ("securityDefinitions", "schemaDefinitions", "uriVariables")
_UNIONS = ("@context", "@type", "tm:optional")
# the order of top-level TD members in the output, so that generated TDs read like hand-written ones
_TD_ORDER = (
    "@context",
    "@type",
    "id",
    "title",
    "titles",
    "description",
    "descriptions",
    "version",
    "created",
    "modified",
    "support",
    "base",
    "securityDefinitions",
    "security",
    "profile",
    "schemaDefinitions",
    "uriVariables",
    # properties/actions/events keep the model's own order: it decides the order of generated classes
    "forms",
    "links",
)
# `{{NAME}}`: printable ASCII as the TM schema's placeholder-pattern says, but no braces, so that
# "{{A}} and {{B}}" is two placeholders, not one named "A}} and {{B"
_PLACEHOLDER = re.compile(r"\{\{([ -z|~]+)\}\}")
_MISSING: Any = object()
# refs are expanded anew at each use, so a chain of refs that each import the next one twice grows
# exponentially: past this many imports the model is rejected instead of exhausting memory
MAX_REF_IMPORTS = 10_000


# ---------------------------------------------------------------------------------------------------------
# small JSON helpers


def is_thing_model(data: object) -> bool:
    """True if `@type` declares a Thing Model: that is what tells a TM from a TD."""
    if not isinstance(data, Mapping):
        return False
    types = data.get("@type")
    items = types if isinstance(types, list) else [types]
    return any(t in (TM_TYPE, TM_TYPE_IRI) for t in items)


def merge_patch(target: Any, patch: Any) -> Any:
    """RFC 7396 JSON Merge Patch, without touching either argument."""
    if not isinstance(patch, dict):
        return copy.deepcopy(patch)
    result: dict[str, Any] = dict(target) if isinstance(target, dict) else {}
    for key, value in patch.items():
        if value is None:
            result.pop(key, None)
        else:
            result[key] = merge_patch(result.get(key), value)
    return result


def _lookup(data: Any, pointer: str) -> Any:
    """The value at a JSON pointer, or `_MISSING`."""
    node = data
    for tok in pointer_tokens(pointer):
        if isinstance(node, dict) and tok in node:
            node = node[tok]
        elif isinstance(node, list) and tok.isdigit() and int(tok) < len(node):
            node = node[int(tok)]
        else:
            return _MISSING
    return node


def _as_list(value: Any) -> list[Any]:
    return list(value) if isinstance(value, list) else [value]


def _union(first: Any, second: Any) -> Any:
    """Ordered union of two values that may each be a list or a single item (a single item stays single)."""
    out: list[Any] = []
    for item in _as_list(first) + _as_list(second):
        if item not in out:
            out.append(copy.deepcopy(item))
    if len(out) == 1 and not isinstance(first, list) and not isinstance(second, list):
        return out[0]
    return out


def _compact(value: Any) -> str:
    """How a value reads inside a string: strings as they are, anything else as compact JSON."""
    if isinstance(value, str):
        return value
    return json.dumps(value, separators=(",", ":"), ensure_ascii=False)


def _names(names: Sequence[str]) -> str:
    return ", ".join(names)


# ---------------------------------------------------------------------------------------------------------
# placeholder values from the command line and from files


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


# ---------------------------------------------------------------------------------------------------------
# resolving tm:extends and tm:ref across files


class _Resolver:
    """Loads the files a model refers to and expands `tm:ref` and `tm:extends`, detecting cycles.

    Files are keyed by their resolved path (the root by its name when it came from stdin); they are shown
    relative to the root's folder, so messages do not depend on where the project is checked out.
    """

    def __init__(self, root: JsonDocument, diags: Diagnostics, *, remote_severity: Severity) -> None:
        self.diags = diags
        self.remote_severity = remote_severity
        self.root_dir = root.path.resolve().parent if root.path is not None else Path.cwd()
        self.root_key = str(root.path.resolve()) if root.path is not None else root.name
        self.root_is_stdin = root.path is None
        self.docs: dict[str, JsonDocument | None] = {self.root_key: root}
        self.models: dict[str, dict[str, Any]] = {}
        self.extends_stack: list[str] = []
        self.ref_stack: list[tuple[str, str]] = []
        self.reported: set[tuple[str, str, str, str]] = set()
        self.cycles: set[frozenset[tuple[str, str]]] = set()
        self.imports = 0

    # -- reporting

    def display(self, key: str) -> str:
        if key == self.root_key and self.root_is_stdin:
            return key
        return Path(os.path.relpath(key, self.root_dir)).as_posix()

    def report(
        self,
        key: str,
        code: str,
        severity: Severity,
        message: str,
        pointer: str = "",
        hint: str | None = None,
    ) -> None:
        """Report once; a diagnostic in the root is left for the caller to locate, others are located here."""
        ident = (code, key, pointer, message)
        if ident in self.reported:
            return
        self.reported.add(ident)
        if key == self.root_key:
            self.diags.add(code, severity, message, pointer, hint)
            return
        diag = Diagnostic(code, severity, message, pointer, hint)
        doc = self.docs.get(key)
        self.diags.append(doc.locate(diag) if doc is not None else diag)

    # -- files

    def base_dir(self, key: str) -> Path:
        doc = self.docs.get(key)
        return doc.path.resolve().parent if doc is not None and doc.path is not None else Path.cwd()

    def classify(self, href: str, key: str) -> tuple[str, Path | None]:
        """("local", path) | ("remote", None) | ("unsupported", None) for an href found in file `key`."""
        try:
            parts = urlsplit(href)
            scheme = parts.scheme.lower()
            if scheme in ("http", "https"):
                return "remote", None
            if scheme == "file":
                from urllib.request import url2pathname

                return "local", Path(url2pathname(parts.path)).resolve()
            if len(scheme) > 1:
                return "unsupported", None
            return "local", (self.base_dir(key) / unquote(href.split("#", 1)[0])).resolve()
        except (ValueError, OSError):  # malformed URL, NUL in a path
            return "unsupported", None

    def load(self, path: Path, key: str, pointer: str, what: str) -> str | None:
        """Load a local file once; report it as not found at `pointer` of file `key` if missing."""
        target = str(path)
        if target in self.docs:
            return target if self.docs[target] is not None else None
        shown = self.display(target)
        if not path.is_file():
            self.report(key, "TM310", Severity.ERROR, f"{what} {shown} not found", pointer)
            self.docs[target] = None
            return None
        try:
            raw = path.read_bytes()
        except OSError as exc:
            self.report(key, "TM310", Severity.ERROR, f"{what} {shown} cannot be read: {exc.strerror or exc}", pointer)
            self.docs[target] = None
            return None
        self.docs[target] = parse_json(raw, shown, self.diags, path=path)
        return target if self.docs[target] is not None else None

    # -- tm:ref

    def expand_refs(self, value: Any, key: str, pointer: str) -> Any:
        """A copy of `value` (found at `pointer` of file `key`) with every `tm:ref` imported."""
        if isinstance(value, list):
            return [self.expand_refs(v, key, pointer_join(pointer, i)) for i, v in enumerate(value)]
        if not isinstance(value, dict):
            return value
        local = {k: self.expand_refs(v, key, pointer_join(pointer, k)) for k, v in value.items() if k != "tm:ref"}
        if "tm:ref" not in value:
            return local
        imported = self.ref_target(value["tm:ref"], key, pointer_join(pointer, "tm:ref"))
        if imported is _MISSING:
            return local
        return merge_patch(imported, local) if local else imported  # a bare ref imports any JSON value

    def ref_target(self, ref: Any, key: str, pointer: str) -> Any:
        """The expanded definition a `tm:ref` points to, or `_MISSING` (after reporting why)."""
        if not isinstance(ref, str) or "#" not in ref:
            self.report(
                key,
                "TM320",
                Severity.ERROR,
                f"tm:ref must be a string '<file>#<json-pointer>', not {json.dumps(ref)}",
                pointer,
                'e.g. "tm:ref": "base.tm.json#/properties/battery"',
            )
            return _MISSING
        href, fragment = ref.split("#", 1)
        target_pointer = unquote(fragment)
        if target_pointer and not target_pointer.startswith("/"):
            self.report(
                key,
                "TM320",
                Severity.ERROR,
                f"tm:ref {ref!r}: the part after '#' must be a JSON pointer",
                pointer,
            )
            return _MISSING
        target_key: str | None = key
        if href:
            kind, path = self.classify(href, key)
            if kind == "remote":
                self.report(
                    key,
                    "TM311",
                    self.remote_severity,
                    f"tm:ref {ref!r} points to a remote model, not fetched (td2adaptor works offline)",
                    pointer,
                    "download the model next to this one and refer to it by a relative path",
                )
                return _MISSING
            if kind == "unsupported" or path is None:
                self.report(
                    key,
                    "TM320",
                    Severity.ERROR,
                    f"tm:ref {ref!r}: only local files and http(s) are understood",
                    pointer,
                )
                return _MISSING
            target_key = self.load(path, key, pointer, "model file of tm:ref")
        if target_key is None:
            return _MISSING
        node = (target_key, target_pointer)
        if node in self.ref_stack:
            chain = self.ref_stack[self.ref_stack.index(node) :] + [node]
            cycle = frozenset(chain)
            if cycle not in self.cycles:
                self.cycles.add(cycle)
                shown = " → ".join(f"{self.display(k)}#{p}" for k, p in chain)
                self.report(key, "TM322", Severity.ERROR, f"tm:ref cycle: {shown}", pointer)
            return _MISSING
        doc = self.docs[target_key]
        assert doc is not None
        found = _lookup(doc.data, target_pointer)
        if found is _MISSING:
            self.report(
                key,
                "TM321",
                Severity.ERROR,
                f"tm:ref {ref!r}: {self.display(target_key)} has nothing at {target_pointer or '/'}",
                pointer,
            )
            return _MISSING
        self.imports += 1
        if self.imports > MAX_REF_IMPORTS:
            self.report(
                self.root_key,
                "TM323",
                Severity.ERROR,
                f"more than {MAX_REF_IMPORTS} tm:ref imports: the refs multiply out of bounds",
            )
            return _MISSING
        self.ref_stack.append(node)
        try:
            return self.expand_refs(found, target_key, target_pointer)
        finally:
            self.ref_stack.pop()

    # -- tm:extends

    def model(self, key: str) -> dict[str, Any]:
        """The model in file `key` with its refs expanded and its parents merged in (memoised)."""
        if key in self.models:
            return copy.deepcopy(self.models[key])
        doc = self.docs[key]
        assert doc is not None
        own = self.expand_refs(doc.data, key, "")
        if not isinstance(own, dict):
            return {}
        self.extends_stack.append(key)
        try:
            inherited: dict[str, Any] | None = None
            for parent in self.parents(own, key):
                inherited = parent if inherited is None else merge_extends(inherited, parent)
        finally:
            self.extends_stack.pop()
        if isinstance(own.get("links"), list):
            own["links"] = [lk for lk in own["links"] if not (isinstance(lk, dict) and lk.get("rel") == "tm:extends")]
        result = own if inherited is None else merge_extends(inherited, own)
        self.models[key] = result
        return copy.deepcopy(result)

    def parents(self, own: dict[str, Any], key: str) -> list[dict[str, Any]]:
        """The resolved models of the `tm:extends` links of one file, in link order."""
        out: list[dict[str, Any]] = []
        links = own.get("links")
        if not isinstance(links, list):
            return out
        for i, link in enumerate(links):
            if not (isinstance(link, dict) and link.get("rel") == "tm:extends"):
                continue
            ptr = pointer_join("", "links", i)
            href = link.get("href")
            if not isinstance(href, str) or not href:
                self.report(key, "TM313", Severity.ERROR, "tm:extends link without an href", ptr)
                continue
            kind, path = self.classify(href, key)
            if kind == "remote":
                self.report(
                    key,
                    "TM311",
                    self.remote_severity,
                    f"extended Thing Model {href} cannot be resolved: "
                    "remote models are not fetched (td2adaptor works offline)",
                    pointer_join(ptr, "href"),
                    "download the parent model and extend it by a relative path",
                )
                continue
            if kind == "unsupported" or path is None:
                self.report(
                    key,
                    "TM313",
                    Severity.ERROR,
                    f"tm:extends href {href!r}: only local files are understood",
                    pointer_join(ptr, "href"),
                )
                continue
            target = str(path)
            if target in self.extends_stack:
                chain = self.extends_stack[self.extends_stack.index(target) :] + [target]
                shown = " → ".join(self.display(k) for k in chain)
                self.report(key, "TM312", Severity.ERROR, f"tm:extends cycle: {shown}", pointer_join(ptr, "href"))
                continue
            loaded = self.load(path, key, pointer_join(ptr, "href"), "extended Thing Model")
            if loaded is None:
                continue
            parent_doc = self.docs[loaded]
            if parent_doc is not None and not is_thing_model(parent_doc.data):
                self.report(
                    key,
                    "TM314",
                    Severity.WARNING,
                    f"extended {self.display(loaded)} is not a Thing Model (no tm:ThingModel in @type)",
                    pointer_join(ptr, "href"),
                )
            out.append(self.model(loaded))
        return out


def merge_extends(parent: Mapping[str, Any], child: Mapping[str, Any]) -> dict[str, Any]:
    """The child model laid over its parent (semantics in the module docstring)."""
    result: dict[str, Any] = copy.deepcopy(dict(parent))
    for key, value in child.items():
        old = result.get(key)
        if key in AFFORDANCE_KINDS and isinstance(old, dict) and isinstance(value, dict):
            merged = dict(old)
            for name, aff in value.items():
                if aff is None:
                    merged.pop(name, None)
                elif isinstance(merged.get(name), dict) and isinstance(aff, dict):
                    merged[name] = merge_patch(merged[name], aff)
                else:
                    merged[name] = copy.deepcopy(aff)
            result[key] = merged
        elif key in _BY_NAME_REPLACE and isinstance(old, dict) and isinstance(value, dict):
            merged = dict(old)
            for name, entry in value.items():
                if entry is None:
                    merged.pop(name, None)
                else:
                    merged[name] = copy.deepcopy(entry)
            result[key] = merged
        elif key == "links" and isinstance(old, list) and isinstance(value, list):
            result[key] = old + [copy.deepcopy(lk) for lk in value if lk not in old]
        elif key in _UNIONS and key in result:
            result[key] = _union(old, value)
        else:
            result[key] = copy.deepcopy(value)
    return result


# ---------------------------------------------------------------------------------------------------------
# tm:optional


def _optional_affordances(
    model: Mapping[str, Any], report: Callable[[str, str, str], None] | None
) -> list[tuple[str, str]]:
    """(kind, name) of the affordances `tm:optional` names; bad entries are reported if `report` is given."""
    entries = model.get("tm:optional")
    if entries is None:
        return []
    if not isinstance(entries, list):
        if report:
            report(
                "TM330",
                'tm:optional must be an array of JSON pointers such as "/properties/battery"',
                "/tm:optional",
            )
        return []
    out: list[tuple[str, str]] = []
    for i, entry in enumerate(entries):
        ptr = pointer_join("", "tm:optional", i)
        if not isinstance(entry, str):
            if report:
                report("TM330", f"tm:optional entry {json.dumps(entry)} is not a JSON pointer string", ptr)
            continue
        tokens = pointer_tokens(entry[1:] if entry.startswith("#") else entry)
        if (
            len(tokens) == 2
            and tokens[0] in AFFORDANCE_KINDS
            and isinstance(model.get(tokens[0]), dict)
            and tokens[1] in model[tokens[0]]
        ):
            if (tokens[0], tokens[1]) not in out:
                out.append((tokens[0], tokens[1]))
        elif report:
            report(
                "TM331",
                f"tm:optional entry {entry!r} does not point to an affordance of the model",
                ptr,
            )
    return out


def _select_optional(
    model: dict[str, Any],
    include_optional: bool | Collection[str],
    error: Callable[[str, str, str], None],
    diags: Diagnostics,
) -> None:
    """Drop the optional affordances that were not asked for, and the `tm:optional` key itself."""
    optional = _optional_affordances(model, error)
    model.pop("tm:optional", None)
    if include_optional is True:
        return
    selected: set[tuple[str, str]] = set()
    if include_optional is not False:
        wanted = [include_optional] if isinstance(include_optional, str) else list(include_optional)
        for item in wanted:
            if item.startswith(("/", "#/")):
                tokens = pointer_tokens(item[1:] if item.startswith("#") else item)
                matches = [o for o in optional if len(tokens) == 2 and o == (tokens[0], tokens[1])]
            else:
                matches = [o for o in optional if o[1] == item]
            if not matches:
                declared = _names([f"/{k}/{n}" for k, n in optional]) or "none"
                error("TM332", f"{item!r} is not an optional affordance of the model (optional: {declared})", "")
            selected.update(matches)
    dropped = [o for o in optional if o not in selected]
    for kind, name in dropped:
        model[kind].pop(name, None)
    if dropped:
        diags.info("TM333", "optional affordances left out: " + _names([f"/{k}/{n}" for k, n in dropped]))


# ---------------------------------------------------------------------------------------------------------
# placeholders


class _Substitution:
    """One pass of `{{NAME}}` substitution over a model, remembering what was missing, kept and used."""

    def __init__(self, values: Mapping[str, Any], keep: Collection[str]) -> None:
        self.values = values
        self.keep = set(keep)
        self.missing: dict[str, str] = {}
        self.kept: dict[str, str] = {}
        self.used: set[str] = set()
        self.collisions: list[tuple[str, str]] = []

    def name_of(self, match: re.Match[str]) -> str:
        return match.group(1).strip()

    def lookup(self, name: str, pointer: str) -> Any:
        if name in self.values:
            self.used.add(name)
            return self.values[name]
        if name in self.keep:
            self.kept.setdefault(name, pointer)
        else:
            self.missing.setdefault(name, pointer)
        return _MISSING

    def text(self, s: str, pointer: str) -> str:
        def repl(m: re.Match[str]) -> str:
            name = self.name_of(m)
            value = self.lookup(name, pointer) if name else _MISSING
            return m.group(0) if value is _MISSING else _compact(value)

        return _PLACEHOLDER.sub(repl, s)

    def value(self, v: Any, pointer: str) -> Any:
        if isinstance(v, str):
            whole = _PLACEHOLDER.fullmatch(v)
            if whole and self.name_of(whole):
                found = self.lookup(self.name_of(whole), pointer)
                return v if found is _MISSING else copy.deepcopy(found)
            return self.text(v, pointer)
        if isinstance(v, list):
            return [self.value(item, pointer_join(pointer, i)) for i, item in enumerate(v)]
        if isinstance(v, dict):
            out: dict[str, Any] = {}
            for key, item in v.items():
                ptr = pointer_join(pointer, key)
                new_key = self.text(key, ptr)
                if new_key in out:
                    self.collisions.append((ptr, new_key))
                out[new_key] = self.value(item, ptr)
            return out
        return v


# ---------------------------------------------------------------------------------------------------------
# TM → TD


def _td_type(value: Any) -> Any:
    """`@type` with tm:ThingModel replaced by Thing (other types kept)."""
    items = _as_list(value) if value is not None else []
    out: list[Any] = []
    for item in items:
        item = "Thing" if item in (TM_TYPE, TM_TYPE_IRI) else item
        if item not in out:
            out.append(item)
    if "Thing" not in out:
        out.insert(0, "Thing")
    return out[0] if len(out) == 1 else out


def _td_context(value: Any, info: Callable[[str], object]) -> Any:
    """An `@context` a TD 1.1 accepts: TD URIs first (v1 before v1.1), TM-only context URIs dropped."""
    td_uris = (TD_CONTEXT_V1, TD_CONTEXT_V11)
    items = _as_list(value) if value is not None else []
    tm_only = [c for c in items if isinstance(c, str) and c.startswith("https://www.w3.org/") and "/wot/tm" in c]
    kept = [c for c in items if c not in tm_only]
    heads = [c for c in td_uris if c in kept] or [TD_CONTEXT_V11]
    result = heads + [c for c in kept if c not in td_uris]
    if tm_only:
        info(f"@context: dropped the Thing Model context {_names(tm_only)}")
    if not any(c in td_uris for c in kept):
        info(f"@context: added {TD_CONTEXT_V11}, which a TD requires")
    elif result != kept:
        info("@context: the TD context URIs moved to the front, as a TD requires")
    if isinstance(value, str) and result == [value]:
        return value
    return result


def _finish_td(
    td: dict[str, Any],
    model_href: str | None,
    diags: Diagnostics,
) -> None:
    """Turn a substituted model into a TD in place: types, context, links, versions, security, checks."""

    td["@type"] = _td_type(td.get("@type"))
    td["@context"] = _td_context(td.get("@context"), lambda msg: diags.info("TM340", msg, "/@context"))

    dropped = sorted(k for k in td if k.startswith("tm:"))
    for kind in AFFORDANCE_KINDS:
        affs = td.get(kind)
        if isinstance(affs, dict):
            for name, aff in affs.items():
                if isinstance(aff, dict):
                    for k in [k for k in aff if k.startswith("tm:")]:
                        del aff[k]
                        dropped.append(f"{kind}/{name}/{k}")
    for k in [k for k in td if k.startswith("tm:")]:
        del td[k]
    if dropped:
        diags.info("TM348", "Thing Model terms dropped from the TD: " + _names(dropped))

    links = [lk for lk in _as_list(td.get("links", [])) if isinstance(lk, dict)]
    links = [lk for lk in links if lk.get("rel") not in ("tm:extends", "type")]
    submodels = [i for i, lk in enumerate(links) if lk.get("rel") == "tm:submodel"]
    if submodels:
        diags.warning(
            "TM347",
            f"{len(submodels)} tm:submodel link(s) kept as they are: submodels are not instantiated",
            "/links",
            'instantiate each submodel on its own and link the TDs with rel "item"',
        )
    if model_href:
        links.append({"rel": "type", "href": model_href, "type": TM_MEDIA_TYPE})
    else:
        diags.info("TM349", "no rel=type link to the model added: the model has no file name")
    if links:
        td["links"] = links
    else:
        td.pop("links", None)

    version = td.get("version")
    if isinstance(version, dict):
        if not isinstance(version.get("instance"), str):
            model_version = version.get("model")
            version["instance"] = model_version if isinstance(model_version, str) else "1.0.0"
            diags.info(
                "TM345",
                f"version.instance set to {version['instance']!r}: a TD's version names its instance",
                "/version",
            )
    elif version is not None:
        diags.warning(
            "TM346",
            f"version is {json.dumps(version)}, but a TD needs an object with 'instance'",
            "/version",
            'e.g. "version": {"instance": "1.0.0", "model": "1.0.0"}',
        )

    if not isinstance(td.get("title"), str):
        diags.warning("TM344", "the model has no title, which a TD requires", "", "add a title to the Thing Model")

    has_defs = isinstance(td.get("securityDefinitions"), dict) and bool(td["securityDefinitions"])
    has_security = "security" in td
    if not has_defs and not has_security:
        td["securityDefinitions"] = {"nosec_sc": {"scheme": "nosec"}}
        td["security"] = "nosec_sc"
        diags.info(
            "TM341",
            "the model declares no security: added securityDefinitions nosec_sc and security nosec_sc",
        )
    elif not has_defs or not has_security:
        missing = "security" if has_defs else "securityDefinitions"
        diags.warning(
            "TM342",
            f"the model has no {missing}, which a TD requires",
            "",
            f"add {missing} to the Thing Model",
        )

    for kind in AFFORDANCE_KINDS:
        affs = td.get(kind)
        if not isinstance(affs, dict):
            continue
        for name, aff in affs.items():
            if isinstance(aff, dict) and not aff.get("forms"):
                diags.warning(
                    "TM343",
                    f"{_KIND[kind]} {name!r} has no forms, which a TD requires",
                    pointer_join("", kind, name),
                    "add the forms (how to reach it) to the Thing Model",
                )


def instantiate(
    doc: JsonDocument,
    values: Mapping[str, Any],
    diags: Diagnostics,
    *,
    keep: Collection[str] = ("robotName",),
    include_optional: bool | Collection[str] = True,
    model_href: str | None = None,
) -> dict[str, Any] | None:
    """Instantiate the Thing Model `doc` into a TD dict; None (with errors reported) when that fails.

    `values` fills the `{{NAME}}` placeholders; names in `keep` may stay unfilled (runtime placeholders such
    as the robot namespace). `include_optional` selects `tm:optional` affordances: all, none, or those
    named by pointer (`/properties/battery`) or name (`battery`). `model_href` is the href of the added
    `rel: type` link (the CLI passes the model's path relative to the output); by default the model's file
    name, so output never depends on absolute paths.
    """
    before = len(diags.errors())
    if not is_thing_model(doc.data):
        diags.error(
            "TM300",
            'not a Thing Model: @type does not contain "tm:ThingModel"',
            "/@type" if isinstance(doc.data, dict) and "@type" in doc.data else "",
            "only a Thing Model can be instantiated; a Thing Description is already an instance",
        )
        return None
    if model_href is None:
        model_href = doc.path.name if doc.path is not None else None
    try:
        resolver = _Resolver(doc, diags, remote_severity=Severity.ERROR)
        model = resolver.model(resolver.root_key)

        def error(code: str, message: str, pointer: str) -> None:
            diags.error(code, message, pointer)

        _select_optional(model, include_optional, error, diags)

        subst = _Substitution(values, keep)
        td: dict[str, Any] = subst.value(model, "")
        for ptr, key in subst.collisions:
            diags.error("TM304", f"two keys became {key!r} after placeholder substitution", ptr)
        if subst.missing:
            listed = _names([f"{n} (at {p or '/'})" for n, p in subst.missing.items()])
            diags.error(
                "TM301",
                f"no value for {len(subst.missing)} placeholder(s): {listed}",
                next(iter(subst.missing.values())),
                "give each with --set NAME=VALUE or in a --values file",
            )
        if subst.kept:
            diags.info(
                "TM302",
                "runtime placeholder(s) left in place: " + _names(["{{" + n + "}}" for n in subst.kept]),
                next(iter(subst.kept.values())),
            )
        unused = sorted(set(values) - subst.used)
        if unused:
            diags.info("TM303", "values given but not used by the model: " + _names(unused))
        _finish_td(td, model_href, diags)
        td = {k: td[k] for k in _TD_ORDER if k in td} | {k: v for k, v in td.items() if k not in _TD_ORDER}
    except RecursionError:
        diags.error("TM309", "the model is too deeply nested to instantiate")
        return None
    if len(diags.errors()) > before:
        return None
    return td


# ---------------------------------------------------------------------------------------------------------
# TD → the model it links


def _data_type(kind: str, aff: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """(member, type) pairs worth comparing between a model's affordance and a TD's."""
    if kind == "properties":
        return [("type", aff.get("type"))]
    if kind == "actions":
        return [(m, aff[m].get("type")) for m in ("input", "output") if isinstance(aff.get(m), dict)]
    return [("data", aff["data"].get("type"))] if isinstance(aff.get("data"), dict) else []


def _name_pattern(name: str) -> re.Pattern[str]:
    """Affordance names in a model may hold placeholders: match them against any text."""
    parts = _PLACEHOLDER.split(name)
    return re.compile("".join(re.escape(p) if i % 2 == 0 else ".+" for i, p in enumerate(parts)) + r"\Z")


def check_against_model(td_doc: JsonDocument, diags: Diagnostics) -> None:
    """A TD that links its Thing Model (`rel: type`) must offer every mandatory affordance of it.

    Only local models are read; a remote one gets a single warning, because td2adaptor works offline.
    """
    data = td_doc.data
    if not isinstance(data, dict) or is_thing_model(data) or not isinstance(data.get("links"), list):
        return
    resolver = _Resolver(td_doc, diags, remote_severity=Severity.WARNING)
    for i, link in enumerate(data["links"]):
        if not (isinstance(link, dict) and link.get("rel") == "type" and isinstance(link.get("href"), str)):
            continue
        href: str = link["href"]
        ptr = pointer_join("", "links", i, "href")
        kind, path = resolver.classify(href, resolver.root_key)
        if kind != "local" or path is None:
            diags.warning(
                "TM350",
                f"linked Thing Model {href} not fetched (offline); conformance to it not checked",
                ptr,
            )
            continue
        key = resolver.load(path, resolver.root_key, ptr, "linked Thing Model")
        if key is None:
            continue
        tm_doc = resolver.docs[key]
        if tm_doc is None or not isinstance(tm_doc.data, dict):
            diags.error("TM351", f"linked Thing Model {href} is not a JSON object", ptr)
            continue
        model = resolver.model(key)
        optional = set(_optional_affordances(model, None))
        _compare(model, data, optional, href, diags)


def _compare(
    model: Mapping[str, Any],
    td: Mapping[str, Any],
    optional: set[tuple[str, str]],
    href: str,
    diags: Diagnostics,
) -> None:
    """Report the model's mandatory affordances the TD lacks, and data types that contradict the model."""
    for kind in AFFORDANCE_KINDS:
        affs = model.get(kind)
        if not isinstance(affs, dict):
            continue
        td_affs = td.get(kind) if isinstance(td.get(kind), dict) else {}
        assert isinstance(td_affs, dict)
        for name, aff in affs.items():
            pattern = _name_pattern(name)
            matches = [n for n in td_affs if pattern.match(n)]
            if not matches:
                if (kind, name) not in optional:
                    diags.error(
                        "TM352",
                        f"{kind}/{name} of the linked Thing Model {href} is missing",
                        pointer_join("", kind) if kind in td else "",
                        "the model marks it mandatory (it is not in tm:optional)",
                    )
                continue
            for td_name in matches:
                _compare_types(kind, td_name, aff, td_affs[td_name], href, diags)


def _compare_types(kind: str, td_name: str, aff: Any, td_aff: Any, href: str, diags: Diagnostics) -> None:
    """A TD may narrow the model (integer for number) but not contradict its data types."""
    if not isinstance(aff, dict) or not isinstance(td_aff, dict):
        return
    want = dict(_data_type(kind, aff))
    for member, got in _data_type(kind, td_aff):
        expected = want.get(member)
        if not isinstance(expected, str) or "{{" in expected or not isinstance(got, str):
            continue
        if got != expected and not (expected == "number" and got == "integer"):
            diags.error(
                "TM353",
                f"{kind}/{td_name} has type {got!r}, the linked Thing Model {href} says {expected!r}",
                pointer_join("", kind, td_name, *(() if member == "type" else (member,)), "type"),
            )
