"""The size table of docs/fleet.md (issue 35, item 16) is the code's: each "now" row's JSON as published,
compact JSON and triples are those of the example's published TD today (tests/tdsize.py computes them; the
directory's figures are made again by bench/td_size.py). And what the TD leaves out to stay small is only
what TD 1.1 and the W3C MQTT binding imply."""

from __future__ import annotations

import re

import pytest

from td2adaptor.model.exposed import DEFAULT_PACKET
from tests.conftest import REPO
from tests.tdsize import EXAMPLES, exposed, size

ROW = re.compile(
    r"^\| (?P<label>[^|]+?), now \| (?P<pretty>[\d,]+) B \| (?P<compact>[\d,]+) B \| (?P<triples>[\d,]+) \|"
)


def table() -> dict[str, tuple[int, int, int]]:
    """The "now" rows of docs/fleet.md's size table: label -> (JSON as published, compact JSON, triples)."""
    rows = {}
    for line in (REPO / "docs" / "fleet.md").read_text(encoding="utf-8").splitlines():
        match = ROW.match(line)
        if match:
            figures = (match["pretty"], match["compact"], match["triples"])
            rows[match["label"]] = tuple(int(f.replace(",", "")) for f in figures)
    return rows  # type: ignore[return-value]


@pytest.mark.parametrize("label", list(EXAMPLES))
def test_the_docs_size_table_is_the_published_tds(label: str) -> None:
    rows = table()
    assert label in rows, f"docs/fleet.md has no '{label}, now' row (bench/td_size.py makes it)"
    now = size(exposed(label))
    assert rows[label] == (now.pretty, now.compact, now.triples), "run bench/td_size.py and update the table"


@pytest.mark.parametrize("label", list(EXAMPLES))
def test_the_published_td_spells_out_no_default_and_one_form_per_subscription(label: str) -> None:
    td = exposed(label)
    defaults = {"readOnly": False, "writeOnly": False, "observable": False, "safe": False, "idempotent": False}
    for section in ("properties", "actions", "events"):
        for name, affordance in td.get(section, {}).items():
            assert not [k for k, v in defaults.items() if affordance.get(k) is v], (name, affordance)
            ops = [
                op
                for form in affordance["forms"]
                for op in ([form["op"]] if isinstance(form["op"], str) else form["op"])
            ]
            assert len(ops) == len(set(ops)), (name, ops)  # one form per operation
            for form in affordance["forms"]:
                assert "contentType" not in form, (name, form)
                form_ops = [form["op"]] if isinstance(form["op"], str) else form["op"]
                implied = all(op in DEFAULT_PACKET for op in form_ops)
                assert ("mqv:controlPacket" in form) != implied, (name, form)
            subscribe = {"subscribeevent", "observeproperty"} & set(ops)
            if subscribe:  # the subscription and its end in one form
                (form,) = [f for f in affordance["forms"] if subscribe & set(f["op"])]
                assert {"unsubscribeevent", "unobserveproperty"} & set(form["op"]), (name, form)
    events = [e for n, e in td.get("events", {}).items() if n.endswith(("Feedback", "State"))]
    assert all("Carries the correlationId" not in e.get("description", "") for e in events)
