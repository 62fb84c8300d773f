"""Walking JSON Schemas and TD data schemas: every subschema, and the ones a strict consumer cannot type."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any


def subschemas(schema: Any, path: str = "") -> Iterator[tuple[str, dict[str, Any]]]:
    """Every (sub)schema of a JSON Schema or TD data schema, by the keywords that hold schemas."""
    if not isinstance(schema, dict):
        return
    yield path, schema
    for key in ("properties", "patternProperties", "$defs", "definitions", "dependentSchemas"):
        for name, sub in (schema.get(key) or {}).items():
            yield from subschemas(sub, f"{path}/{key}/{name}")
    for key in ("items", "additionalProperties", "unevaluatedProperties", "contains", "propertyNames", "not"):
        yield from subschemas(schema.get(key), f"{path}/{key}")
    for key in ("if", "then", "else", "input", "output", "data", "subscription", "cancellation", "uriVariables"):
        yield from subschemas(schema.get(key), f"{path}/{key}")
    for key in ("allOf", "anyOf", "oneOf", "prefixItems"):
        for i, sub in enumerate(schema.get(key) or []):
            yield from subschemas(sub, f"{path}/{key}/{i}")


def untyped(schema: Any) -> list[str]:
    return [p for p, s in subschemas(schema) if ("const" in s or "enum" in s) and "type" not in s]
