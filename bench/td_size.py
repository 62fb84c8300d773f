"""The size of the examples' published Thing Descriptions (issue 35, item 16): the table in docs/fleet.md.

For each example TD (tests/tdsize.py: robot `r1` on `mqtt://127.0.0.1:1883`): its JSON as published and
compact, its triples (JSON-LD to RDF offline), and, with a real TD directory (Domus on Oxigraph,
.ci/setup-tdd.sh), what the directory makes of it: the N-Triples it gives back (`Accept:
application/n-triples`; Domus 1.0.2 hands them to node as one command-line argument to give the TD back as
JSON, so past Linux's 131,072 bytes for one argument its `GET /things/{id}` answers 500) and that `GET`'s
status.

    PYTHONPATH=. .venv/bin/python bench/td_size.py [--no-directory]
"""

from __future__ import annotations

import json
import sys
import tempfile
import urllib.request
from pathlib import Path
from typing import Any
from urllib.parse import quote

import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from td2adaptor.runtime.node.discovery import registration_document  # noqa: E402
from tests.runtime.tdd import TddServer  # noqa: E402
from tests.tdsize import EXAMPLES, exposed, size  # noqa: E402


def in_directory(server: TddServer, td: dict[str, Any]) -> tuple[int, int, int]:
    """PUT `td` to the directory: (triples, N-Triples bytes) it gives back, and its answer to GET as JSON."""
    path = f"/things/{quote(str(td['id']), safe='')}"
    body = json.dumps(registration_document(json.dumps(td), 0)).encode("utf-8")
    headers = {"Content-Type": "application/td+json"}
    with urllib.request.urlopen(urllib.request.Request(server.url + path, body, headers, method="PUT"), timeout=60):
        pass
    text = server.triples(str(td["id"])) or ""
    status = server.status("GET", path)
    server.status("DELETE", path)
    return sum(1 for line in text.splitlines() if line.strip()), len(text.encode("utf-8")), status


def main(argv: list[str]) -> None:
    tds = {label: exposed(label) for label in EXAMPLES}
    server = None
    if "--no-directory" not in argv:
        try:
            server = TddServer(Path(tempfile.mkdtemp(prefix="td-size-")))
        except pytest.skip.Exception as exc:  # no directory installed: the offline figures only
            print(f"(without the directory's figures: {exc.msg})")
        else:
            server.start()
    try:
        print("| robot TD | JSON as published | compact JSON | triples | triples in Domus | N-Triples in Domus | GET |")
        print("|---|---|---|---|---|---|---|")
        for label, td in tds.items():
            s = size(td)
            cells = [label, f"{s.pretty:,} B", f"{s.compact:,} B", f"{s.triples:,}"]
            if server is not None:
                triples, nt, status = in_directory(server, td)
                cells += [f"{triples:,}", f"{nt:,} B", str(status)]
            else:
                cells += ["", f"({s.ntriples:,} B offline)", ""]
            print("| " + " | ".join(cells) + " |")
    finally:
        if server is not None:
            server.stop()


if __name__ == "__main__":
    main(sys.argv[1:])
