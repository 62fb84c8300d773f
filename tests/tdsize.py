"""How large a robot's published Thing Description is, as JSON and as RDF (issue 35, item 16): the figures of
the table in docs/fleet.md, which tests/test_td_size.py holds equal to the code's and `bench/td_size.py`
makes again (with the real TD directory for the N-Triples it gives back and its answer to `GET`).

The TDs are the examples' own, exposed for robot `r1` on `mqtt://127.0.0.1:1883`, as `td2adaptor expose`
writes them (which is the text `td2adaptor run` publishes). Triples: the TD's JSON-LD turned into RDF offline
(pyld, with the TD 1.1 context td2adaptor bundles): what a directory stores, before it adds its own
registration data.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tests.conftest import REPO

ROBOT = "r1"
BROKER = "mqtt://127.0.0.1:1883"
#: the table's rows: label -> (TD, interface folder or None)
EXAMPLES: dict[str, tuple[Path, Path | None]] = {
    "RB-1": (REPO / "examples" / "robotnik_rb1" / "td.json", REPO / "examples" / "robotnik_rb1" / "interfaces"),
    "nav_base": (REPO / "examples" / "nav_base" / "td.json", REPO / "examples" / "nav_base" / "interfaces"),
    "warehouse door": (REPO / "examples" / "warehouse" / "door.td.json", None),
}


@dataclass(frozen=True)
class Size:
    """A TD's size: its JSON as published (two-space indent) and compact, and its RDF (triples, N-Triples bytes
    with pyld's short blank node labels)."""

    pretty: int
    compact: int
    triples: int
    ntriples: int


def exposed(label: str) -> dict[str, Any]:
    """The published TD of example `label` for robot ROBOT on BROKER."""
    import td2adaptor
    from td2adaptor.model.exposed import exposed_td

    td, interfaces = EXAMPLES[label]
    result = td2adaptor.compile(td, interfaces=[interfaces] if interfaces else [])
    assert result.model is not None, [d.message for d in result.diagnostics]
    return exposed_td(result.model, robot=ROBOT, broker=BROKER)


def ntriples(td: dict[str, Any]) -> str:
    """`td` as N-Triples (JSON-LD to RDF, offline: only the bundled contexts)."""
    from td2adaptor.frontend.jsonld import OfflineLoader, _pyld, base_iri

    options = {"format": "application/n-quads", "documentLoader": OfflineLoader(), "base": base_iri(td)}
    return str(_pyld().to_rdf(td, options))


def size(td: dict[str, Any]) -> Size:
    from td2adaptor.support.jsondump import dump

    rdf = ntriples(td)
    return Size(
        pretty=len(dump(td).encode("utf-8")),
        compact=len(json.dumps(td, ensure_ascii=False, separators=(",", ":")).encode("utf-8")),
        triples=sum(1 for line in rdf.splitlines() if line.strip()),
        ntriples=len(rdf.encode("utf-8")),
    )
