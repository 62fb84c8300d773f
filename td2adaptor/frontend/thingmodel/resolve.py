"""Resolving `tm:ref` imports and `tm:extends` parents across local files, detecting cycles."""

from __future__ import annotations

import copy
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity, pointer_join
from td2adaptor.frontend.jsonsrc import JsonDocument, parse_json
from td2adaptor.frontend.thingmodel.common import (
    AFFORDANCE_KINDS,
    MISSING,
    is_thing_model,
    lookup,
    merge_patch,
    union,
)

_BY_NAME_REPLACE = ("securityDefinitions", "schemaDefinitions", "uriVariables")
_UNIONS = ("@context", "@type", "tm:optional")
# refs are expanded anew at each use, so a chain of refs that each import the next one twice grows
# exponentially: past this many imports the model is rejected instead of exhausting memory
MAX_REF_IMPORTS = 10_000


class Resolver:
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
        if imported is MISSING:
            return local
        return merge_patch(imported, local) if local else imported  # a bare ref imports any JSON value

    def ref_target(self, ref: Any, key: str, pointer: str) -> Any:
        """The expanded definition a `tm:ref` points to, or `MISSING` (after reporting why)."""
        if not isinstance(ref, str) or "#" not in ref:
            self.report(
                key,
                "TM320",
                Severity.ERROR,
                f"tm:ref must be a string '<file>#<json-pointer>', not {json.dumps(ref)}",
                pointer,
                'e.g. "tm:ref": "base.tm.json#/properties/battery"',
            )
            return MISSING
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
            return MISSING
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
                return MISSING
            if kind == "unsupported" or path is None:
                self.report(
                    key,
                    "TM320",
                    Severity.ERROR,
                    f"tm:ref {ref!r}: only local files and http(s) are understood",
                    pointer,
                )
                return MISSING
            target_key = self.load(path, key, pointer, "model file of tm:ref")
        if target_key is None:
            return MISSING
        node = (target_key, target_pointer)
        if node in self.ref_stack:
            chain = self.ref_stack[self.ref_stack.index(node) :] + [node]
            cycle = frozenset(chain)
            if cycle not in self.cycles:
                self.cycles.add(cycle)
                shown = " → ".join(f"{self.display(k)}#{p}" for k, p in chain)
                self.report(key, "TM322", Severity.ERROR, f"tm:ref cycle: {shown}", pointer)
            return MISSING
        doc = self.docs[target_key]
        assert doc is not None
        found = lookup(doc.data, target_pointer)
        if found is MISSING:
            self.report(
                key,
                "TM321",
                Severity.ERROR,
                f"tm:ref {ref!r}: {self.display(target_key)} has nothing at {target_pointer or '/'}",
                pointer,
            )
            return MISSING
        self.imports += 1
        if self.imports > MAX_REF_IMPORTS:
            self.report(
                self.root_key,
                "TM323",
                Severity.ERROR,
                f"more than {MAX_REF_IMPORTS} tm:ref imports: the refs multiply out of bounds",
            )
            return MISSING
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
    """The child model laid over its parent (semantics in the package docstring)."""
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
            result[key] = union(old, value)
        else:
            result[key] = copy.deepcopy(value)
    return result
