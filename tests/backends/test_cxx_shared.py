"""The layer C/C++ backends share (`backends/_cxx`): mros is built on it rather than owning it, it knows
nothing of mROS, and it is no backend of its own."""

from __future__ import annotations

from pathlib import Path

import td2adaptor.backends._cxx as cxx
from td2adaptor.backends import registry
from td2adaptor.backends._cxx import names, ros1wire
from td2adaptor.backends.mros import limits
from td2adaptor.backends.mros import types as mros_types


def test_mros_uses_the_shared_layer() -> None:
    assert mros_types.PRIMITIVES is names.PRIMITIVES and mros_types.CPP_KEYWORDS is names.CPP_KEYWORDS
    assert mros_types.comment is names.comment
    assert names.C_MACROS <= mros_types.MACRO_LIKE
    assert limits.full_definition is ros1wire.full_definition and limits.header_size is ros1wire.header_size


def test_it_knows_nothing_of_mros() -> None:
    """What a second C/C++ backend would import must not carry mROS's or TOPPERS's names."""
    for path in Path(cxx.__file__).parent.glob("*.py"):
        code = path.read_text(encoding="utf-8")
        assert "backends.mros" not in code and "TOPPERS" not in code and "E_OK" not in code, path.name
    assert not names.c_macro_like("E_OK") and mros_types.macro_like("E_OK")
    assert not names.c_macro_like("TSK_SELF") and mros_types.macro_like("TSK_SELF")
    assert all(names.c_macro_like(n) for n in ("errno", "INT8_MAX", "UINT_LEAST16_MAX", "M_PI", "DBL_MAX", "_Tag"))
    assert not names.c_macro_like("speed")


def test_mangling_avoids_reserved_macro_like_and_taken_names() -> None:
    reserved = names.CPP_KEYWORDS
    assert names.mangle("speed", reserved, set(), names.c_macro_like) == "speed"
    assert names.mangle("class", reserved, set(), names.c_macro_like) == "class_"
    assert names.mangle("class", reserved, {"class_"}, names.c_macro_like) == "class_m"
    assert names.mangle("errno", reserved, set(), names.c_macro_like) == "errno_"


def test_a_connection_header_counts_each_field_and_its_length() -> None:
    fields = ros1wire.subscriber_request("/t", "std_msgs/String", "x" * 32, "string data\n", "/n")
    assert ros1wire.header_size(fields) == sum(4 + len(f"{k}={v}") for k, v in fields.items())
    assert "message_definition" in fields and "latching" in ros1wire.publisher_reply("/t", "a/B", "m", "", "/n")


def test_it_is_no_backend() -> None:
    assert "_cxx" not in registry.modules() and "_python" not in registry.modules()
