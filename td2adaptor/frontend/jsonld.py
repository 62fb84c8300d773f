"""JSON-LD processing of a TD, strictly offline.

A TD names its vocabulary by context URLs. Fetching them would make validation depend on the network (and
leak what is being validated), so only the contexts td2adaptor bundles are served: its own rendition of the
TD 1.1 context (`schemas/td-context-1.1.jsonld`, for both W3C URLs) and the ROS binding context. Any other
context URL is never fetched: it is reported (TD251) and treated as an empty context, so expansion goes on
and terms it would have defined are simply dropped, as the Thingweb Playground does.

pyld is imported inside the functions (`_pyld`): it is only needed when JSON-LD is asked for, and importing
it costs CLI start-up time.
"""

from __future__ import annotations

import functools
import json
import re
import sys
from collections.abc import Callable, Mapping
from typing import Any

from td2adaptor.diagnostics import Diagnostics, pointer_join
from td2adaptor.diagnostics.catalogue import meanings
from td2adaptor.frontend.bundled import load_schema
from td2adaptor.frontend.jsonsrc import JsonDocument

CODES: dict[str, str] = meanings("TD25")  # the codes this module reports (see the catalogue)

TD_CONTEXT_V1 = "https://www.w3.org/2019/wot/td/v1"
TD_CONTEXT_V11 = "https://www.w3.org/2022/wot/td/v1.1"
ROSV_CONTEXT = "https://td2adaptor.dev/ns/rosv/v1"

# context URL -> bundled file in schemas/; the 2019 URL serves the same (1.1) vocabulary as the 2022 one
BUNDLED_CONTEXTS: dict[str, str] = {
    TD_CONTEXT_V1: "td-context-1.1.jsonld",
    TD_CONTEXT_V11: "td-context-1.1.jsonld",
    ROSV_CONTEXT: "rosv-context-v1.jsonld",
}

# used as JSON-LD base when the TD has no absolute `id`: pyld 3.3 drops every affordance name without a base
DEFAULT_BASE = "urn:td2adaptor:anonymous"

_ABSOLUTE_IRI = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:[^\s]*$")
# JSON-LD 1.1 API error codes raised while processing a context (the rest concern the document itself)
_CONTEXT_ERRORS = frozenset(
    {
        "invalid @version value",
        "invalid vocab mapping",
        "invalid base IRI",
        "invalid default language",
        "invalid base direction",
        "invalid @propagate value",
        "invalid @import value",
        "invalid @prefix value",
        "invalid term definition",
        "invalid IRI mapping",
        "invalid keyword alias",
        "invalid container mapping",
        "invalid type mapping",
        "invalid language mapping",
        "invalid reverse property",
        "invalid scoped context",
        "invalid protected mode",
        "protected term redefinition",
        "keyword redefinition",
        "cyclic IRI mapping",
        "processing mode conflict",
    }
)
_TD_LIKE = re.compile(r"^https?://(www\.)?w3\.org/(ns/td|20\d\d/wot/td)", re.I)


#: pyld modules that only serve documents from the network or the file system (this module serves its own)
_PYLD_LOADERS = ("pyld.documentloader.requests", "pyld.documentloader.aiohttp")


def _pyld() -> Any:
    """pyld's `jsonld` module, imported without the document loaders td2adaptor never uses.

    `import pyld` imports every loader pyld has (asyncio, urllib.request: half of pyld's ~70 ms import, and
    `requests` wherever it is installed), and `pyld.jsonld` makes one of them its default. Every call here
    passes its own `documentLoader`, so the package's `__init__` is skipped (its submodules import as usual)
    and the network loaders are hidden while `jsonld` picks its default: it falls back to its dummy loader,
    as on a machine without requests and aiohttp. Whatever goes wrong, pyld is imported the ordinary way.
    """
    loaded = sys.modules.get("pyld.jsonld")
    if loaded is not None:
        return loaded
    if "pyld" not in sys.modules:
        try:
            import importlib.util

            spec = importlib.util.find_spec("pyld")
            if spec is not None and spec.submodule_search_locations is not None:
                sys.modules["pyld"] = importlib.util.module_from_spec(spec)
                hidden = {name: sys.modules.pop(name, None) for name in _PYLD_LOADERS}
                for name in _PYLD_LOADERS:
                    sys.modules[name] = None  # type: ignore[assignment]  # None: "cannot be imported"
                try:
                    from pyld import jsonld

                    return jsonld
                finally:
                    for name, module in hidden.items():
                        del sys.modules[name]
                        if module is not None:
                            sys.modules[name] = module
        except Exception:  # noqa: BLE001 - any surprise: forget the partial import, import as pyld expects
            for name in [n for n in sys.modules if n == "pyld" or n.startswith("pyld.")]:
                del sys.modules[name]
    from pyld import jsonld

    return jsonld


class OfflineLoader:
    """A pyld document loader that never touches the network.

    Serves `documents` (URL -> parsed JSON-LD document); every other URL is recorded in `refused` and answered
    with an empty context, which lets processing continue instead of failing on the first unknown URL.
    """

    def __init__(self, documents: Mapping[str, Any] | None = None) -> None:
        if documents is None:
            documents = {url: load_schema(name) for url, name in BUNDLED_CONTEXTS.items()}
        self.documents: dict[str, Any] = dict(documents)
        self.refused: list[str] = []

    def __call__(self, url: str, options: Any = None) -> dict[str, Any]:
        document = self.documents.get(url)
        if document is None:
            if url not in self.refused:
                self.refused.append(url)
            document = {"@context": {}}
        return {
            "contentType": "application/ld+json",
            "contextUrl": None,
            "documentUrl": url,
            "document": document,
        }


def _resolver(loader: OfflineLoader) -> Any:
    """A pyld context resolver that keys inline contexts by sorted-key JSON instead of JCS.

    pyld looks every scoped context up again for each node it applies to, canonicalising the context object
    (pure Python JCS) just to make a cache key: that was 40% of expanding a 1,000-affordance TD. Any
    injective serialisation is as good a key; `json.dumps(sort_keys=True)` is C code. The cache is per
    call, so documents served by one loader never leak into another's processing.
    """
    import json

    _pyld()  # pyld's package, imported lightly, before its submodules
    from pyld.context_resolver import ContextResolver
    from pyld.resolved_context import ResolvedContext

    class Resolver(ContextResolver):  # type: ignore[misc]
        # The same scoped-context dict comes back for every node it applies to: its key is remembered by
        # identity (the dict is kept alive beside it, so its id cannot be reused during this call).
        keys: dict[int, tuple[Any, str | None]] = {}

        def resolve(self, active_ctx: Any, context: Any, base: Any, cycles: Any = None) -> Any:
            if isinstance(context, dict) and "@context" in context:
                context = context["@context"]
            resolved = []
            for ctx in context if isinstance(context, list) else [context]:
                known = self.keys.get(id(ctx))
                if known is not None and known[0] is ctx:
                    key = known[1]
                else:
                    try:
                        key = json.dumps(ctx, sort_keys=True, separators=(",", ":")) if type(ctx) is dict else None
                    except (TypeError, ValueError, RecursionError):
                        key = None
                    self.keys[id(ctx)] = (ctx, key)
                if key is None:  # URLs, null, anything unusual: pyld's own way
                    resolved.extend(super().resolve(active_ctx, ctx, base, cycles))
                    continue
                found = self._get(key)
                if not found:
                    found = self._cache_resolved_context(key, ResolvedContext(ctx), "static")
                resolved.append(found)
            return resolved

    return Resolver({}, loader)


def base_iri(data: Any) -> str:
    """The JSON-LD base for a TD: its `id` when that is an absolute IRI, else a fixed URN (never empty)."""
    ident = data.get("id") if isinstance(data, dict) else None
    if isinstance(ident, str) and _ABSOLUTE_IRI.match(ident):
        return ident
    return DEFAULT_BASE


def expand(doc: JsonDocument, diags: Diagnostics, *, loader: OfflineLoader | None = None) -> list[Any] | None:
    """Expanded JSON-LD of `doc`, or None after reporting why it cannot be processed."""
    jsonld = _pyld()

    if not isinstance(doc.data, (dict, list)):
        # pyld would take a string for the URL of a document to fetch
        diags.error("TD252", f"a JSON-LD document is an object or an array, not {type(doc.data).__name__}")
        return None
    loader = loader if loader is not None else OfflineLoader()
    options = {"documentLoader": loader, "base": base_iri(doc.data), "contextResolver": _resolver(loader)}
    try:
        expanded = jsonld.expand(doc.data, options)
    except Exception as exc:  # any processor failure becomes a diagnostic, never a traceback
        _report_refused(doc, loader, diags)
        _report_failure(doc, exc, diags)
        return None
    _report_refused(doc, loader, diags)
    result: list[Any] = expanded
    return result


def check(doc: JsonDocument, diags: Diagnostics) -> None:
    """Report what `expand(doc, diags)` reports, with less work when a TD has many alike affordances.

    Expansion fails, or not, on an affordance for reasons its layout gives (keys, nesting, non-string
    values, keyword values, @type values) and never for the text of an ordinary string: a description, a
    form's href or a ROS name expand the same way whatever they say. So when the TD uses only bundled
    contexts, pyld first expands one representative of each group of affordances that differ only in such
    strings. That succeeding without a diagnostic means the whole TD does; anything else (an error, a
    refused context) and the whole TD is expanded, so every reported diagnostic comes from the full run.
    """
    reduced = _representatives(doc.data)
    if reduced is not None:
        loader = OfflineLoader()
        found = Diagnostics()
        stand_in = JsonDocument(doc.name, doc.text, reduced, doc.path)
        if expand(stand_in, found, loader=loader) is not None and not found.items and not loader.refused:
            return
    expand(doc, diags)


_AFFORDANCE_MAPS = ("properties", "actions", "events")
_ANY_STRING = "_"  # what a group's strings are compared as (never a kept string: those are "" or "@...")


@functools.cache
def _keyword_aliases() -> frozenset[str]:
    """Every term that any bundled context (scoped ones included) maps to a keyword or defines in reverse."""
    found: set[str] = set()
    stack: list[Any] = [load_schema(name) for name in set(BUNDLED_CONTEXTS.values())]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            context = node.get("@context")
            if isinstance(context, dict):
                for term, definition in context.items():
                    target = definition.get("@id", "") if isinstance(definition, dict) else definition
                    if (isinstance(target, str) and target.startswith("@")) or (
                        isinstance(definition, dict) and "@reverse" in definition
                    ):
                        found.add(term)
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
    return frozenset(found)


def _representatives(data: Any) -> dict[str, Any] | None:
    """`data` with one affordance of each group of alike ones, or None when grouping is not known safe.

    Safe when every context is a bundled one named at the top (no inline context can make a key a keyword
    alias or give a term a base); an affordance holding a context anywhere, or named like a keyword, is
    kept on its own. Within an affordance, keys, nesting and every non-string value are compared as they
    are, and so is everything under a keyword or a keyword alias (`@type`, `type`, `id`, `@context`, ...);
    other strings count as equal unless they are empty or look like a keyword.
    """
    if not isinstance(data, dict):
        return None
    contexts = data.get("@context")
    contexts = contexts if isinstance(contexts, list) else [contexts]
    if not all(isinstance(c, str) and c in BUNDLED_CONTEXTS for c in contexts):
        return None
    aliases = _keyword_aliases()

    def kept(key: str) -> bool:
        return key.startswith("@") or key in aliases or (":" in key and key.split(":", 1)[0] in aliases)

    def shape(value: Any) -> Any:
        if isinstance(value, str):
            return value if not value or value.startswith("@") else _ANY_STRING
        if isinstance(value, dict):
            return {k: (v if kept(k) else shape(v)) for k, v in value.items()}
        if isinstance(value, list):
            return [shape(v) for v in value]
        return value

    try:
        return _grouped(data, shape)
    except (TypeError, ValueError, RecursionError):  # not plain JSON data: expanded as it is
        return None


def _grouped(data: dict[str, Any], shape: Callable[[Any], Any]) -> dict[str, Any]:
    reduced = dict(data)
    for kind in _AFFORDANCE_MAPS:
        affordances = data.get(kind)
        if not isinstance(affordances, dict) or len(affordances) < 2:
            continue
        seen: set[str] = set()
        chosen: dict[str, Any] = {}
        for name, affordance in affordances.items():
            group = json.dumps(shape(affordance))
            # keys and kept strings are written as they are: a context anywhere shows as "@context"
            if name.startswith("@") or '"@context"' in group:  # expanded as it is, not as one of a group
                chosen[name] = affordance
                continue
            if group not in seen:
                seen.add(group)
                chosen[name] = affordance
        reduced[kind] = chosen
    return reduced


def to_rdf(
    doc: JsonDocument, diags: Diagnostics, *, canonical: bool = False, loader: OfflineLoader | None = None
) -> str | None:
    """The TD's RDF dataset as N-Quads; `canonical` relabels blank nodes (URDNA2015) and sorts the lines.

    Canonical output is what two documents must share to say the same thing in RDF.
    """
    jsonld = _pyld()
    loader = loader if loader is not None else OfflineLoader()
    expanded = expand(doc, diags, loader=loader)
    if expanded is None:
        return None
    options: dict[str, Any] = {
        "base": base_iri(doc.data),
        "format": "application/n-quads",
        "documentLoader": loader,
        "contextResolver": _resolver(loader),
    }
    try:
        if canonical:
            nquads = jsonld.normalize(expanded, {**options, "algorithm": "URDNA2015"})
        else:
            nquads = jsonld.to_rdf(expanded, options)
    except Exception as exc:  # see expand()
        _report_failure(doc, exc, diags)
        return None
    return str(nquads)


def _report_refused(doc: JsonDocument, loader: OfflineLoader, diags: Diagnostics) -> None:
    for url in loader.refused:
        hint = "td2adaptor never fetches contexts; put the terms you need in an inline context object"
        if _TD_LIKE.match(url):
            hint = f"use the TD 1.1 context {TD_CONTEXT_V11!r}"
        pointer, written = _find_context_reference(doc.data, url)
        shown = repr(url) if written in (None, url) else f"{written!r} (resolved to {url!r})"
        diags.warning(
            "TD251",
            f"JSON-LD context {shown} is not available offline and was not fetched; the terms it defines are ignored",
            pointer,
            hint,
        )


def _report_failure(doc: JsonDocument, exc: Exception, diags: Diagnostics) -> None:
    jsonld = _pyld()
    error = _innermost_jsonld_error(exc, jsonld.JsonLdError)
    if error is None:
        if isinstance(exc, RecursionError):
            diags.error("TD253", "JSON-LD processing failed: the document is nested too deeply", "")
        else:
            diags.error(
                "TD253",
                f"JSON-LD processing failed: {type(exc).__name__}: {exc}",
                "",
                "please report this as a td2adaptor bug, with the document",
            )
        return
    code = getattr(error, "code", None) or getattr(error, "type", "")
    message = str(error.args[0]) if error.args else "invalid JSON-LD"
    details = getattr(error, "details", None)
    if isinstance(details, dict):
        shown = {k: v for k, v in details.items() if isinstance(v, (str, int, float, bool)) and len(str(v)) < 200}
        if shown:
            message += " (" + ", ".join(f"{k}: {v!r}" for k, v in shown.items()) + ")"
    pointer = "/@context" if str(code) in _CONTEXT_ERRORS or "context" in str(code) else ""
    if pointer and not (isinstance(doc.data, dict) and "@context" in doc.data):
        pointer = ""
    diags.error("TD252", f"JSON-LD error [{code}]: {message}", pointer, _hint_for(str(code)))


def _hint_for(code: str) -> str | None:
    if "term definition" in code or "IRI mapping" in code:
        return "every term in an inline @context must map to an absolute IRI, a compact IRI or a keyword"
    if "context" in code:
        return "@context must be a URL, an object or an array of those"
    return None


def _innermost_jsonld_error(exc: BaseException, error_type: type[BaseException]) -> Any:
    """pyld wraps the error that explains a failure (e.g. to_rdf wraps expand's); find the deepest one."""
    found: BaseException | None = None
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if isinstance(current, error_type):
            found = current
        current = current.__cause__
    return found


def _find_context_reference(data: Any, url: str) -> tuple[str, str | None]:
    """Where the document names context `url`: (JSON pointer, the reference as written).

    pyld hands the loader URLs already resolved against the base, so a relative reference is matched by
    its ending. Without a match: the top-level `@context` (or the root), and None.
    """
    candidates: list[tuple[str, str]] = []
    stack: list[tuple[str, Any]] = [("", data)]
    while stack:
        pointer, value = stack.pop()
        if isinstance(value, dict):
            for key, child in value.items():
                child_ptr = pointer_join(pointer, key)
                if key == "@context":
                    entries = child if isinstance(child, list) else [child]
                    for i, item in enumerate(entries):
                        if isinstance(item, str):
                            candidates.append((pointer_join(child_ptr, i) if child is entries else child_ptr, item))
                stack.append((child_ptr, child))
        elif isinstance(value, list):
            stack.extend((pointer_join(pointer, i), item) for i, item in enumerate(value))
    for pointer, item in candidates:
        if item == url:
            return pointer, item
    for pointer, item in candidates:
        if item and not _ABSOLUTE_IRI.match(item) and url.endswith(item.lstrip("./")):
            return pointer, item
    if isinstance(data, dict) and "@context" in data:
        return "/@context", None
    return "", None
