"""The front end as a library: load any supported input, validate it, lower it into the canonical model.

Stages append diagnostics to one collector; at the end every diagnostic is located (file:line:col) in the
document it is about and sorted into input order. Nothing here prints or exits: the CLI does that.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO, Literal

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity, escalate
from td2adaptor.frontend.jsonsrc import DEFAULT_MAX_BYTES, JsonDocument, load_path

if TYPE_CHECKING:  # loaded when something is compiled: a result-cache hit needs none of it (start-up time)
    from td2adaptor.frontend.legacy import LegacyInput
    from td2adaptor.model import Model

Source = str | Path
InputKind = Literal["td", "tm", "legacy"]

#: Schema errors that the reference system's real TD is known to have; accepted there with a warning.
#: Bounds time and memory on hostile input (about 0.5 ms of compile time per affordance).
DEFAULT_MAX_AFFORDANCES = 20_000

_REFERENCE_TOLERATED = re.compile(r"^/(@context(/\d+)?|created|modified|links/\d+(/href)?)$")


@dataclass
class Input:
    """A loaded input: the TD to lower and the documents diagnostics refer to."""

    kind: InputKind
    docs: list[JsonDocument]
    td: dict[str, Any] | None
    legacy: LegacyInput | None = None
    placeholders: Mapping[str, Any] = field(default_factory=dict)

    @property
    def doc(self) -> JsonDocument:
        return self.docs[0]


@dataclass(frozen=True)
class Result:
    model: Model | None
    diagnostics: tuple[Diagnostic, ...]
    input: Input | None = None

    @property
    def ok(self) -> bool:
        return not any(d.severity is Severity.ERROR for d in self.diagnostics)

    @property
    def dialects(self) -> frozenset[str]:
        from td2adaptor.frontend.extract import extract

        if self.input is None or self.input.td is None:
            return frozenset()
        return frozenset(r.dialect for r in extract(self.input.td, Diagnostics()))


def _sources(sources: Source | Sequence[Source]) -> list[str]:
    if isinstance(sources, (str, Path)):
        return [str(sources)]
    return [str(s) for s in sources]


def load(
    sources: Source | Sequence[Source],
    diags: Diagnostics,
    *,
    values: Mapping[str, Any] | None = None,
    keep: Sequence[str] = ("robotName",),
    stdin: BinaryIO | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> Input | None:
    """Read a TD, a Thing Model (instantiated with `values`) or legacy config files (several are merged)."""
    paths = _sources(sources)
    docs = []
    for p in paths:
        doc = load_path(p, diags, stdin=stdin, max_bytes=max_bytes)
        if doc is None:
            return None
        docs.append(doc)
    if not docs:
        diags.add("TD000", Severity.ERROR, "no input given", file="<input>")
        return None
    from td2adaptor.frontend.legacy import is_legacy, to_reference_td

    legacy = [is_legacy(d.data) for d in docs]
    if all(legacy):
        lin = to_reference_td(docs, diags)
        return Input("legacy", docs, lin.td, lin)
    if len(docs) > 1:
        diags.add(
            "TD008",
            Severity.ERROR,
            "several inputs can only be legacy RosClasses config files (service.json, topic.json)",
            hint="give one Thing Description or Thing Model",
            file=docs[0].name,
        )
        return None
    doc = docs[0]
    if not isinstance(doc.data, dict):
        kind = "null" if doc.data is None else type(doc.data).__name__
        local = Diagnostics()
        local.error("TD009", f"a Thing Description is a JSON object, not {kind}")
        diags.extend(doc.locate(d) for d in local)
        return None
    from td2adaptor.frontend.thingmodel import is_thing_model

    if is_thing_model(doc.data):
        from td2adaptor.frontend.conformance import check_tm
        from td2adaptor.frontend.thingmodel import instantiate

        local = Diagnostics()
        check_tm(doc, local)
        td = None if local.has_errors else instantiate(doc, values or {}, local, keep=keep)
        diags.extend(doc.locate(d) for d in local)
        return Input("tm", docs, td, placeholders=dict(values or {}))
    return Input("td", docs, doc.data)


def _td_checks(inp: Input, diags: Diagnostics, *, reference: bool, parallel: bool = False) -> Callable[[], None]:
    """TD 1.1 conformance, unknown terms, JSON-LD and linked-TM checks on the (instantiated) TD.

    With `parallel`, the JSON-LD stage runs in a forked child meanwhile (see `background`); its
    diagnostics are the same either way and are only used when the TD passed the schema. The returned
    `finish` adds them (and the linked-TM checks) to `diags`: the caller lowers the TD before calling it,
    so the child's work overlaps with lowering too.
    """
    from td2adaptor.compiler.background import Background
    from td2adaptor.frontend.conformance import check_td
    from td2adaptor.frontend.terms import check_terms
    from td2adaptor.frontend.thingmodel import check_against_model

    assert inp.td is not None
    doc = (
        inp.doc
        if inp.kind == "td"
        else JsonDocument(inp.doc.name, inp.doc.text, inp.td, inp.doc.path, unique_keys=inp.doc.unique_keys)
    )

    def jsonld() -> list[Diagnostic]:
        from td2adaptor.frontend.jsonld import check

        found = Diagnostics()
        check(doc, found)
        return list(found)

    background = Background(jsonld, enabled=parallel)
    local = Diagnostics()
    check_td(doc, local)
    for d in local:
        if reference and d.severity is Severity.ERROR and _REFERENCE_TOLERATED.match(d.pointer):
            d = replace(
                d,
                severity=Severity.WARNING,
                message=f"reference-dialect defect accepted: {d.message}",
                hint=d.hint or "'td2adaptor migrate' writes a conforming TD",
            )
        diags.append(d)
    check_terms(doc, diags)
    if local.has_errors:
        background.cancel()

    def finish() -> None:
        if not local.has_errors:
            diags.extend(background.result())
        if inp.kind == "td":
            check_against_model(doc, diags)

    return finish


def compile(  # noqa: A001 - the public name the docs promise
    sources: Source | Sequence[Source],
    *,
    interfaces: Sequence[Source] = (),
    values: Mapping[str, Any] | None = None,
    strict: bool = False,
    package: str | None = None,
    stdin: BinaryIO | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
    max_affordances: int = DEFAULT_MAX_AFFORDANCES,
    use_cache: bool = False,
    parallel: bool = False,
    need_model: bool = True,
) -> Result:
    """Load, validate and lower `sources` into the canonical model.

    `model` is None when there are errors; `diagnostics` always lists every problem found, in input order.
    With `use_cache`, an unchanged input is answered from the result cache (`Result.input` is then None);
    a caller that only reports diagnostics (`validate`) passes `need_model=False`, and a hit then leaves
    `model` None without loading the model's classes (start-up time).
    `parallel` lets the CLI run the JSON-LD stage in a forked child (same diagnostics, less wall time).
    """
    from td2adaptor.support import cache

    if use_cache and cache.cache_dir() is not None and "-" not in _sources(sources):
        import pickle

        from td2adaptor.compiler import resultcache

        srcs = _sources(sources)
        dirs = [Path(p) for p in interfaces]
        options = (sorted((values or {}).items()), strict, package, max_bytes, max_affordances)
        cache_key = resultcache.key(srcs, dirs, repr(options))

        computed: list[Model | None] = []

        def fresh() -> tuple[bytes | None, tuple[Diagnostic, ...]]:
            r = compile(
                srcs,
                interfaces=dirs,
                values=values,
                strict=strict,
                package=package,
                max_bytes=max_bytes,
                max_affordances=max_affordances,
                parallel=parallel,
            )
            computed.append(r.model)
            # the model is pickled apart, so that reading the entry loads only the diagnostics' classes
            blob = None if r.model is None else pickle.dumps(r.model, protocol=pickle.HIGHEST_PROTOCOL)
            return blob, r.diagnostics

        blob, diagnostics = resultcache.cached(cache_key, fresh)
        if computed:
            model = computed[0]
        else:
            model = pickle.loads(blob) if blob is not None and need_model else None
        return Result(model, diagnostics, None)
    from td2adaptor.frontend.extract import REFERENCE, extract
    from td2adaptor.lowering.lower import lower

    diags = Diagnostics()
    inp = load(sources, diags, values=values, stdin=stdin, max_bytes=max_bytes)
    model = None
    td_diags = Diagnostics()
    if inp is not None and inp.td is not None and _too_many_affordances(inp, td_diags, max_affordances):
        inp.td = None
    if inp is not None and inp.td is not None:
        raws = extract(inp.td, td_diags)
        finish = None
        if inp.kind != "legacy":
            reference = any(r.dialect == REFERENCE for r in raws)
            finish = _td_checks(inp, td_diags, reference=reference, parallel=parallel)
        fallback = Path(inp.doc.name).stem if inp.doc.path else "thing"
        lowered = Diagnostics()
        model = lower(
            inp.td,
            raws,
            lowered,
            interface_dirs=[Path(p) for p in interfaces],
            package=package,
            fallback_title=fallback,
        )
        if model is not None and inp.kind == "tm" and model.thing.description:
            # the description is the Thing Model's: a robot's TD made from the model does not repeat it
            model = replace(model, thing=replace(model.thing, model_description=True))
        if finish is not None:
            finish()
        td_diags.extend(lowered)
    located = list(diags) + [_locate(inp, d) for d in td_diags]
    if strict:
        located = escalate(located)
    ordered = _in_input_order(located, inp)
    if any(d.severity is Severity.ERROR for d in ordered):
        model = None
    return Result(model, tuple(ordered), inp)


def _too_many_affordances(inp: Input, diags: Diagnostics, limit: int) -> bool:
    assert inp.td is not None
    count = sum(len(v) for k, v in inp.td.items() if k in ("properties", "actions", "events") and isinstance(v, dict))
    if count > limit:
        diags.error(
            "TD010",
            f"the TD has {count} affordances, more than the limit of {limit}",
            hint="raise it with --max-affordances if this TD is really that large",
        )
        return True
    return False


def validate(sources: Source | Sequence[Source], **options: Any) -> list[Diagnostic]:
    """Every diagnostic for `sources` (see `compile` for the options)."""
    return list(compile(sources, **options).diagnostics)


def _locate(inp: Input | None, diag: Diagnostic) -> Diagnostic:
    if inp is None:
        return diag
    if diag.file and diag.file not in {d.name for d in inp.docs}:
        return diag  # about another document (a linked Thing Model, an interface file): located there
    if inp.legacy is not None:
        diag, doc = inp.legacy.remap(diag)
        return doc.locate(diag) if doc is not None else diag
    return inp.doc.locate(diag)


def _in_input_order(diags: list[Diagnostic], inp: Input | None) -> list[Diagnostic]:
    files = [d.name for d in inp.docs] if inp is not None else []

    def key(d: Diagnostic) -> tuple[int, int, int]:
        f = files.index(d.file) if d.file in files else len(files)
        return (f, d.line or 0, d.col or 0)

    return sorted(diags, key=key)
