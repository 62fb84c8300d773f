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

Modules: `common` (constants, JSON helpers), `values` (placeholder values), `resolve` (steps 1-2),
`optional` (3), `placeholders` (4), `instantiate` (5 and the whole run), `check` (a TD against its model).
"""

from __future__ import annotations

from td2adaptor.diagnostics.catalogue import meanings
from td2adaptor.frontend.thingmodel.check import check_against_model
from td2adaptor.frontend.thingmodel.common import (
    AFFORDANCE_KINDS,
    TD_CONTEXT_V1,
    TD_CONTEXT_V11,
    TM_MEDIA_TYPE,
    TM_TYPE,
    TM_TYPE_IRI,
    is_thing_model,
    merge_patch,
)
from td2adaptor.frontend.thingmodel.instantiate import instantiate
from td2adaptor.frontend.thingmodel.resolve import MAX_REF_IMPORTS, merge_extends
from td2adaptor.frontend.thingmodel.values import load_placeholder_map, parse_set_options

CODES: dict[str, str] = meanings("TM")  # the TM3xx codes, texts in td2adaptor.diagnostics.catalogue

__all__ = [
    "AFFORDANCE_KINDS",
    "CODES",
    "MAX_REF_IMPORTS",
    "TD_CONTEXT_V1",
    "TD_CONTEXT_V11",
    "TM_MEDIA_TYPE",
    "TM_TYPE",
    "TM_TYPE_IRI",
    "check_against_model",
    "instantiate",
    "is_thing_model",
    "load_placeholder_map",
    "merge_extends",
    "merge_patch",
    "parse_set_options",
]
