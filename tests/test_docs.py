"""The documentation can be found and its relative links lead somewhere: README.md and docs/*.md link only to
files that exist, and the pages a user needs are linked from where they look (docs/migrating.md was written
and linked from nowhere)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.conftest import REPO

PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
_LINK = re.compile(r"\]\(([^)\s]+)\)")


def _relative_links(page: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)  # code is not a link
    targets = (m.group(1).split("#", 1)[0] for m in _LINK.finditer(text))
    return [t for t in targets if t and not re.match(r"[a-z]+:", t)]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(REPO).as_posix())
def test_relative_links_lead_to_files(page: Path) -> None:
    broken = [t for t in _relative_links(page) if not (page.parent / t).exists()]
    assert not broken, broken


@pytest.mark.parametrize(
    ("page", "target"),
    [("README.md", "docs/migrating.md"), ("docs/binding.md", "migrating.md")],
)
def test_the_migration_guide_is_linked(page: str, target: str) -> None:
    path = REPO / page
    assert target in _relative_links(path), f"{page} does not link {target}"
    # binding.md links it from its section about the reference dialect
    if page == "docs/binding.md":
        section = path.read_text(encoding="utf-8").split("## The reference dialect", 1)[1].split("\n## ", 1)[0]
        assert f"]({target})" in section
