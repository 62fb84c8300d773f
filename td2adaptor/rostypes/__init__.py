"""ROS interface types: name normalisation and the per-distribution type registry.

`registry` imports rosbags only when a registry is built, so importing this package stays cheap.
"""

from __future__ import annotations

from td2adaptor.diagnostics.catalogue import meanings
from td2adaptor.rostypes.names import (
    TypeName,
    action_part_names,
    is_valid_package_name,
    is_valid_type_name,
    normalize_type_name,
    parse_type_name,
    ros1_name,
    service_part_names,
    split_canonical,
)
from td2adaptor.rostypes.registry import TypeRegistry

CODES: dict[str, str] = meanings("TY")  # the TY5xx codes, texts in td2adaptor.diagnostics.catalogue

__all__ = [
    "CODES",
    "TypeName",
    "TypeRegistry",
    "action_part_names",
    "is_valid_package_name",
    "is_valid_type_name",
    "normalize_type_name",
    "parse_type_name",
    "ros1_name",
    "service_part_names",
    "split_canonical",
]
