"""Property tests of the whole pipeline: valid binding TDs round-trip through gen; RB-1 mutations never trace.

A small sample here; `bench/fuzz.py` runs 10,000 cases.
"""

from __future__ import annotations

from typing import Any

from hypothesis import HealthCheck, given, settings

from tests.conftest import EXAMPLE
from tests.frontend.test_fuzz_frontend import mutated
from tests.fuzz.strategies import binding_tds, round_trip

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(binding_tds())
def test_valid_tds_generate_parseable_code(td: dict[str, Any]) -> None:
    round_trip(td)


@SETTINGS
@given(mutated())
def test_mutated_rb1_never_traces(data: bytes) -> None:
    import json

    try:
        td = json.loads(data)
    except ValueError:
        return
    round_trip(td, [EXAMPLE / "interfaces"], expect_valid=False)
