"""Thing Model → Thing Description: resolve, select optional affordances, substitute, finish the TD."""

from __future__ import annotations

import json
from collections.abc import Callable, Collection, Mapping
from typing import Any

from td2adaptor.diagnostics import Diagnostics, Severity, pointer_join
from td2adaptor.frontend.jsonsrc import JsonDocument
from td2adaptor.frontend.thingmodel.common import (
    AFFORDANCE_KINDS,
    TD_CONTEXT_V1,
    TD_CONTEXT_V11,
    TM_MEDIA_TYPE,
    TM_TYPE,
    TM_TYPE_IRI,
    as_list,
    is_thing_model,
    join_names,
)
from td2adaptor.frontend.thingmodel.optional import select_optional
from td2adaptor.frontend.thingmodel.placeholders import Substitution
from td2adaptor.frontend.thingmodel.resolve import Resolver

_KIND = {"properties": "property", "actions": "action", "events": "event"}

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


def _td_type(value: Any) -> Any:
    """`@type` with tm:ThingModel replaced by Thing (other types kept)."""
    items = as_list(value) if value is not None else []
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
    items = as_list(value) if value is not None else []
    tm_only = [c for c in items if isinstance(c, str) and c.startswith("https://www.w3.org/") and "/wot/tm" in c]
    kept = [c for c in items if c not in tm_only]
    heads = [c for c in td_uris if c in kept] or [TD_CONTEXT_V11]
    result = heads + [c for c in kept if c not in td_uris]
    if tm_only:
        info(f"@context: dropped the Thing Model context {join_names(tm_only)}")
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
        diags.info("TM348", "Thing Model terms dropped from the TD: " + join_names(dropped))

    links = [lk for lk in as_list(td.get("links", [])) if isinstance(lk, dict)]
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
        resolver = Resolver(doc, diags, remote_severity=Severity.ERROR)
        model = resolver.model(resolver.root_key)

        def error(code: str, message: str, pointer: str) -> None:
            diags.error(code, message, pointer)

        select_optional(model, include_optional, error, diags)

        subst = Substitution(values, keep)
        td: dict[str, Any] = subst.value(model, "")
        for ptr, key in subst.collisions:
            diags.error("TM304", f"two keys became {key!r} after placeholder substitution", ptr)
        if subst.missing:
            listed = join_names(
                [f"{n} (at {', '.join(p or '/' for p in places)})" for n, places in subst.missing.items()]
            )
            diags.error(
                "TM301",
                f"no value for {len(subst.missing)} placeholder(s): {listed}",
                next(iter(subst.missing.values()))[0],
                "give each with --set NAME=VALUE or in a --values file",
            )
        if subst.kept:
            diags.info(
                "TM302",
                "runtime placeholder(s) left in place: " + join_names(["{{" + n + "}}" for n in subst.kept]),
                next(iter(subst.kept.values())),
            )
        unused = sorted(set(values) - subst.used)
        if unused:
            diags.info("TM303", "values given but not used by the model: " + join_names(unused))
        _finish_td(td, model_href, diags)
        td = {k: td[k] for k in _TD_ORDER if k in td} | {k: v for k, v in td.items() if k not in _TD_ORDER}
    except RecursionError:
        diags.error("TM309", "the model is too deeply nested to instantiate")
        return None
    if len(diags.errors()) > before:
        return None
    return td
