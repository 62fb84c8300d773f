"""The W3C WoT reference data the tests use as an oracle (tests only: td2adaptor ships none of it).

One layout, two sources:

* ``../shared/wot`` beside the repository (CI has it), used whenever present, unchanged: ``official/`` (the W3C
  TD/TM schemas and JSON-LD contexts) and ``playground/`` (the Thingweb Playground corpus in the folders
  ``valid/ invalid/ warn/ notValidYet/ tm_valid/ tm_invalid/``, and ``manifest.csv``);
* otherwise the pinned npm packages ``.ci/setup-wot.sh`` installs into ``.cache/wot``: the official TD and TM 1.1
  schemas from ``wot-thing-description-types`` / ``wot-thing-model-types`` (the W3C files with CRLF line ends)
  and an older snapshot of the corpus from ``@thing-description-playground/core`` (``examples/tds/*``,
  ``examples/tms/*``, mapped onto the folders above).

What neither source has for this run (the JSON-LD contexts and the TD 1.0 schema are in no registry package;
``manifest.csv``, some files and some files' current versions only in ../shared) makes the test that needs it
skip with a one-line reason. Which npm files differ from ../shared's is listed below and checked whenever both
sources are present (tests/frontend/test_conformance.py).
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import REPO

SHARED_WOT = REPO.parent / "shared" / "wot"
NPM_MODULES = REPO / ".cache" / "wot" / "node_modules"
SETUP = "bash .ci/setup-wot.sh"

#: the npm packages .ci/setup-wot.sh installs, at these exact versions (keep the two in step)
NPM_VERSIONS = {
    "wot-thing-description-types": "1.1.0-12-March-2025",
    "wot-thing-model-types": "1.1.0-12-March-2025",
    "@thing-description-playground/core": "1.4.0",
}
PLAYGROUND_PACKAGE = "@thing-description-playground/core"

#: official file name -> (npm package, path in it)
OFFICIAL_IN_NPM = {
    "td-schema-v1.1.json": ("wot-thing-description-types", "schema/td-json-schema-validation.json"),
    "tm-schema-v1.1.json": ("wot-thing-model-types", "schema/tm-json-schema-validation.json"),
}
#: why an official file that no pinned package ships is missing
NOT_IN_NPM = {
    "td-context-v1.jsonld": "no registry package ships the W3C TD context",
    "td-context-v1.1.jsonld": "no registry package ships the W3C TD context",
    "td-schema-v1.json": "no pinned registry package ships the TD 1.0 schema",
}

#: corpus folder (the kind of document: its expected verdict) -> its folder in the playground package
KINDS = ("valid", "invalid", "warn", "notValidYet", "tm_valid", "tm_invalid")
NPM_FOLDERS = {
    "valid": "examples/tds/valid",
    "invalid": "examples/tds/invalid",
    "warn": "examples/tds/warning",
    "notValidYet": "examples/tds/notValidYet",
    "tm_valid": "examples/tms/valid",
    "tm_invalid": "examples/tms/invalid",
}
#: files per folder in each source
COUNTS = {
    "shared": {"valid": 44, "invalid": 23, "warn": 6, "notValidYet": 6, "tm_valid": 13, "tm_invalid": 6},
    "npm": {"valid": 41, "invalid": 22, "warn": 6, "notValidYet": 2, "tm_valid": 13, "tm_invalid": 6},
}

# The npm snapshot against ../shared/wot/playground, file by file (compared as parsed JSON with key order and
# duplicate keys kept; the formatting differs throughout). Every other file is the same data in both.
#: in both, other content (older examples; other TM link URLs: thingweb/thingweb-playground, since renamed)
NPM_DIFFERENT = frozenset(
    {
        "valid/dataSchema.json",
        "valid/fromTM.json",
        "valid/semanticTD.json",
        "valid/uriVariablesThing.json",
        "valid/usingRecursiveTM.json",
        "valid/usingTM.json",
        "invalid/usingTM.json",
        "warn/unavailableRecursiveTm.json",
        "tm_valid/extend.json",
    }
)
#: only in ../shared
NPM_MISSING = frozenset(
    {
        "valid/mqtt-experimental.json",
        "valid/profile.json",
        "valid/uriVariablesAffordances.json",
        "invalid/emptyOpArray.json",
        "notValidYet/apikeyUriVariable.json",
        "notValidYet/bodyApiKey.json",
        "notValidYet/comboOneOf.json",
        "notValidYet/oauth2-client.json",
        "notValidYet/oauth2-device.json",
    }
)
#: only in npm (../shared has a newer version of mqtt-experimental.json in valid/)
NPM_EXTRA = frozenset({"notValidYet/mqtt-experimental.json"})


def npm_package(name: str) -> Path | None:
    """The installed npm package `name` if it is the pinned version."""
    manifest = NPM_MODULES / name / "package.json"
    if not manifest.is_file():
        return None
    if json.loads(manifest.read_text(encoding="utf-8")).get("version") != NPM_VERSIONS[name]:
        return None
    return manifest.parent


def _pinned(name: str) -> str:
    return f"{name}@{NPM_VERSIONS[name]}"


# ---------------------------------------------------------------------------------------------------------
# the official W3C files


def official_source(name: str) -> str:
    """Where official(name) comes from: "shared" or "npm"; skips the test when neither has it."""
    if (SHARED_WOT / "official" / name).is_file():
        return "shared"
    if name in OFFICIAL_IN_NPM and npm_package(OFFICIAL_IN_NPM[name][0]) is not None:
        return "npm"
    if name in OFFICIAL_IN_NPM:
        pytest.skip(f"needs ../shared/wot/official/{name} or npm {_pinned(OFFICIAL_IN_NPM[name][0])} ({SETUP})")
    pytest.skip(f"needs ../shared/wot/official/{name} ({NOT_IN_NPM[name]})")


def official(name: str) -> bytes:
    """The W3C file `name` of ../shared/wot/official: from there, else from its npm package with the package's
    CRLF line ends made LF (its only difference, which the pinned-sha256 test proves); else the test skips."""
    if official_source(name) == "shared":
        return (SHARED_WOT / "official" / name).read_bytes()
    package, inner = OFFICIAL_IN_NPM[name]
    path = npm_package(package)
    assert path is not None
    return (path / inner).read_bytes().replace(b"\r\n", b"\n")


@cache
def official_json(name: str) -> Any:
    return json.loads(official(name))


# ---------------------------------------------------------------------------------------------------------
# the Playground corpus


@dataclass(frozen=True)
class CorpusFile:
    rel: str  # "<kind>/<file name>", the ../shared/wot/playground layout
    path: Path

    @property
    def kind(self) -> str:
        return self.rel.split("/")[0]

    @property
    def name(self) -> str:
        return self.path.name


@dataclass(frozen=True)
class Corpus:
    source: str  # "shared" or "npm"
    label: str  # for messages
    folders: dict[str, Path]  # kind -> folder

    def files(self, *kinds: str) -> list[CorpusFile]:
        """The files of these folders (all when none given), sorted by name within each folder."""
        return [
            CorpusFile(f"{kind}/{path.name}", path)
            for kind in kinds or KINDS
            for path in sorted(self.folders[kind].glob("*.json"))
        ]

    def count(self, *kinds: str) -> int:
        """How many files these folders have in this source (the pinned contents)."""
        return sum(COUNTS[self.source][kind] for kind in kinds or KINDS)

    def file(self, rel: str, *, any_version: bool = False) -> Path:
        """One file, by its ../shared path. From npm only when it is the same data as ../shared's (or, with
        any_version, some version of it); otherwise the test skips."""
        differs = rel in NPM_MISSING or (rel in NPM_DIFFERENT and not any_version)
        if self.source == "npm" and differs:
            pytest.skip(f"needs ../shared/wot/playground/{rel} ({self.label} {_version_note(rel)})")
        path = self.folders[rel.split("/")[0]] / rel.split("/", 1)[1]
        assert path.is_file(), path
        return path

    def exact(self, *kinds: str) -> list[CorpusFile]:
        """files(*kinds) for a test whose expectations name these folders' exact contents: from npm only when
        they are the same files with the same data as ../shared's; otherwise the test skips."""
        if self.source == "npm":
            changed = sorted(
                rel for rel in NPM_DIFFERENT | NPM_MISSING | NPM_EXTRA if rel.split("/")[0] in (kinds or KINDS)
            )
            if changed:
                shown = ", ".join(changed[:3]) + (f" and {len(changed) - 3} more" if len(changed) > 3 else "")
                pytest.skip(f"needs ../shared/wot/playground: {self.label} lacks or has other versions of {shown}")
        return self.files(*kinds)


def _version_note(rel: str) -> str:
    return "has another version of it" if rel in NPM_DIFFERENT else "lacks it"


@cache
def corpus() -> Corpus | None:
    """The corpus of this run: ../shared/wot/playground, else the npm snapshot, else None."""
    if (SHARED_WOT / "playground").is_dir():
        base = SHARED_WOT / "playground"
        return Corpus("shared", "../shared/wot/playground", {kind: base / kind for kind in KINDS})
    package = npm_package(PLAYGROUND_PACKAGE)
    if package is not None:
        folders = {kind: package / folder for kind, folder in NPM_FOLDERS.items()}
        return Corpus("npm", _pinned(PLAYGROUND_PACKAGE), folders)
    return None


NO_CORPUS = f"needs ../shared/wot/playground or npm {_pinned(PLAYGROUND_PACKAGE)} ({SETUP})"


def require_corpus() -> Corpus:
    found = corpus()
    if found is None:
        pytest.skip(NO_CORPUS)
    return found


def require_shared_corpus(why: str) -> Corpus:
    """The corpus, for a test that needs exactly the ../shared one (say why); otherwise the test skips."""
    found = require_corpus()
    if found.source != "shared":
        pytest.skip(f"needs ../shared/wot/playground: {why}")
    return found


def manifest() -> list[dict[str, str]]:
    """../shared/wot/playground/manifest.csv (the npm package has none); otherwise the test skips."""
    path = SHARED_WOT / "playground" / "manifest.csv"
    if not path.is_file():
        pytest.skip("needs ../shared/wot/playground/manifest.csv (no registry package ships the manifest)")
    with path.open(encoding="utf-8", newline="") as fh:
        return list(csv.DictReader(fh))


def params(files: Sequence[CorpusFile]) -> list[Any]:
    """pytest parameters, one per corpus file (its ../shared path as the id); with no corpus at all, one skipped
    parameter that says why (never an empty parameter set)."""
    if corpus() is None:
        return [pytest.param(None, marks=pytest.mark.skip(reason=NO_CORPUS), id="no-corpus")]
    return [pytest.param(f, id=f.rel) for f in files]


def corpus_files(*kinds: str) -> list[CorpusFile]:
    """At collection time: the files of these folders in this run's corpus (none without a corpus)."""
    found = corpus()
    return found.files(*kinds) if found is not None else []
