"""TD 1.1's terms at each position of a Thing Description, and the JSON Schema keywords a TD data schema lacks.

The front end warns about members outside them (`frontend.terms`); the model's exposed TD keeps the data
schemas it writes within them (`model.exposed`). Facts about TDs, so the model owns them and the front end
reads them from here.
"""

from __future__ import annotations

_COMMON = frozenset({"@type", "title", "titles", "description", "descriptions"})
THING = _COMMON | {
    "@context",
    "id",
    "version",
    "created",
    "modified",
    "support",
    "base",
    "properties",
    "actions",
    "events",
    "links",
    "forms",
    "security",
    "securityDefinitions",
    "schemaDefinitions",
    "profile",
    "uriVariables",
}
DATA_SCHEMA = _COMMON | {
    "const",
    "default",
    "unit",
    "oneOf",
    "allOf",
    "anyOf",
    "enum",
    "readOnly",
    "writeOnly",
    "format",
    "type",
    "contentEncoding",
    "contentMediaType",
    "pattern",
    "minLength",
    "maxLength",
    "minimum",
    "maximum",
    "exclusiveMinimum",
    "exclusiveMaximum",
    "multipleOf",
    "items",
    "minItems",
    "maxItems",
    "properties",
    "required",
}
_AFFORDANCE = _COMMON | {"forms", "uriVariables"}
PROPERTY = _AFFORDANCE | DATA_SCHEMA | {"observable"}
ACTION = _AFFORDANCE | {"input", "output", "safe", "idempotent", "synchronous"}
EVENT = _AFFORDANCE | {"subscription", "data", "dataResponse", "cancellation"}
FORM = frozenset(
    {
        "href",
        "contentType",
        "contentCoding",
        "security",
        "scopes",
        "response",
        "additionalResponses",
        "subprotocol",
        "op",
    }
)
EXPECTED_RESPONSE = frozenset({"contentType"})
ADDITIONAL_RESPONSE = frozenset({"contentType", "schema", "success"})
LINK = frozenset({"href", "type", "rel", "anchor", "sizes", "hreflang", "instanceName"})
VERSION = frozenset({"instance", "model"})
SECURITY_COMMON = frozenset({"@type", "description", "descriptions", "proxy", "scheme"})
SECURITY: dict[str, frozenset[str]] = {
    "nosec": SECURITY_COMMON,
    "auto": SECURITY_COMMON,
    "combo": SECURITY_COMMON | {"oneOf", "allOf"},
    "basic": SECURITY_COMMON | {"in", "name"},
    "digest": SECURITY_COMMON | {"qop", "in", "name"},
    "apikey": SECURITY_COMMON | {"in", "name"},
    "bearer": SECURITY_COMMON | {"authorization", "alg", "format", "in", "name"},
    "psk": SECURITY_COMMON | {"identity"},
    "oauth2": SECURITY_COMMON | {"authorization", "token", "refresh", "scopes", "flow"},
}
ANY_SECURITY = frozenset().union(*SECURITY.values())
ALL_TERMS = THING | PROPERTY | ACTION | EVENT | FORM | ADDITIONAL_RESPONSE | LINK | VERSION | ANY_SECURITY

# JSON Schema keywords a TD data schema does not have (a common source of "unknown" members)
JSON_SCHEMA_ONLY = frozenset(
    {
        "$schema",
        "$id",
        "$ref",
        "$defs",
        "definitions",
        "additionalItems",
        "additionalProperties",
        "patternProperties",
        "propertyNames",
        "minProperties",
        "maxProperties",
        "dependencies",
        "dependentRequired",
        "dependentSchemas",
        "prefixItems",
        "contains",
        "minContains",
        "maxContains",
        "uniqueItems",
        "not",
        "if",
        "then",
        "else",
        "examples",
        "deprecated",
    }
)
