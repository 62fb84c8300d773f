"""What a first `validate` (no result cache) loads, and that the shortcuts taken for it change no verdict
(issue 34: a cold `validate` of the RB-1 took 320 ms, 6x `python -c pass`).

* The URI checks of the TD schema answer plain ASCII URIs with a small regex (`conformance._plain`) instead
  of compiling rfc3987's: the small one must accept nothing rfc3987 refuses.
* pyld is imported without its network and file document loaders (asyncio, urllib.request, requests):
  expansion must be pyld's all the same, and the network loader must stay out of reach.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import rfc3987
from hypothesis import given
from hypothesis import strategies as st

from td2adaptor.frontend.conformance import _PLAIN, _plain, _rfc3987
from tests.conftest import EXAMPLE, REPO

URI_CHARS = "aZz09-._~!$&'()*+,;=:@/?#%[] {}\"<>\\^`|\t"


@given(st.text(alphabet=URI_CHARS, max_size=24))
def test_the_plain_uri_regexes_accept_nothing_rfc3987_refuses(value: str) -> None:
    for rule in _PLAIN:
        plain = _plain(rule)
        assert plain is not None
        if plain.match(value):
            assert rfc3987.match(value, rule=rule), (rule, value)


def _plain_uri(rule: str) -> st.SearchStrategy[tuple[str, str]]:
    return st.tuples(st.just(rule), st.from_regex(_PLAIN[rule], fullmatch=True))


@given(st.sampled_from(sorted(_PLAIN)).flatmap(_plain_uri))
def test_what_the_plain_regexes_accept_rfc3987_accepts(drawn: tuple[str, str]) -> None:
    rule, value = drawn
    assert rfc3987.match(value, rule=rule), (rule, value)


@given(st.text(max_size=30) | st.text(alphabet=URI_CHARS + "é中", max_size=30))
def test_the_format_checks_say_what_rfc3987_says(value: str) -> None:
    for rule in ("URI", "IRI", "IRI_reference"):
        ascii_rule = rule.replace("IRI", "URI") if value.isascii() else rule
        assert _rfc3987(rule)(value) == (rfc3987.match(value, rule=ascii_rule) is not None), (rule, value)


def test_the_usual_uris_take_the_plain_path() -> None:
    usual = ["ros:svc/a0", "ros:/door1/door_controller/command", "urn:dev:ops:my-thing-1234", "mqtt://broker:1883/x"]
    for rule in _PLAIN:
        plain = _plain(rule)
        assert plain is not None and all(plain.match(u) for u in usual)
    assert _plain("URI_reference").match("robot/state?x=1#top")  # type: ignore[union-attr]
    assert not _plain("URI").match("robot/state")  # type: ignore[union-attr]  # relative: not a URI


def test_a_cold_validate_of_the_rb1_loads_neither_rfc3987_nor_pyld_loaders() -> None:
    code = (
        "import sys, json\n"
        "from td2adaptor.compiler.pipeline import compile\n"
        f"r = compile({str(EXAMPLE / 'td.json')!r}, interfaces=[{str(EXAMPLE / 'interfaces')!r}])\n"
        "names = ('rfc3987', 'asyncio', 'urllib.request', 'requests', 'pyld.jsonld')\n"
        "loaded = [m for m in names if m in sys.modules]\n"
        "print(json.dumps({'ok': r.ok, 'loaded': loaded}))\n"
    )
    env = {**os.environ, "TD2ADAPTOR_NO_FORK": "1", "PYTHONPATH": str(REPO)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    # pyld.jsonld is there: the JSON-LD stage ran in this process (no fork), without the loaders
    assert json.loads(out) == {"ok": True, "loaded": ["pyld.jsonld"]}


def test_pyld_imported_lightly_still_refuses_the_network() -> None:
    code = (
        "import json\n"
        "from td2adaptor.frontend.jsonld import _pyld\n"
        "jsonld = _pyld()\n"
        "try:\n"
        "    jsonld.expand({'@context': 'https://example.com/ctx.jsonld', 'x': 1})\n"
        "    print('fetched')\n"
        "except jsonld.JsonLdError as exc:\n"
        "    print(json.dumps(str(exc.code)))\n"
        "import pyld.documentloader.requests, pyld.documentloader.aiohttp\n"  # importable again afterwards
    )
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    assert json.loads(out) == "loading remote context failed"
