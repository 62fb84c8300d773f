"""One policy for what tests need from outside the venv (tests/tools.py): a skip with a one-line reason on a
developer's machine, a failure in CI; and no test has a rule of its own."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests import tools
from tests.conftest import REPO

_CI_WORDS = {"": False, "0": False, "false": False, "FALSE": False, "true": True, "1": True, "yes": True}


@pytest.mark.parametrize(("value", "ci"), _CI_WORDS.items())
def test_ci_is_said_by_the_ci_variable(monkeypatch: pytest.MonkeyPatch, value: str, ci: bool) -> None:
    monkeypatch.setenv("CI", value)
    assert tools.in_ci() is ci


def test_ci_run_says_it_is_ci() -> None:
    assert 'export CI="${CI:-true}"' in (REPO / ".ci" / "run").read_text(encoding="utf-8")


def test_a_missing_tool_skips_here_and_fails_in_ci(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("CI", raising=False)
    with pytest.raises(pytest.skip.Exception, match=r"^no-such-tool-x not installed \(apt install x\)$"):
        tools.require("no-such-tool-x", "apt install x")
    with pytest.raises(pytest.skip.Exception, match="Python module no_such_module_x not installed"):
        tools.require_module("no_such_module_x", "pip install x")
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match=r"no-such-tool-x not installed .*CI installs it"):
        tools.require("no-such-tool-x", "apt install x")
    with pytest.raises(pytest.fail.Exception, match="ROS 1 is not here"):
        tools.require_ok("ROS 1 is not here")


def test_a_present_tool_is_found(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CI", "true")
    assert Path(tools.require("sh", "-")).name == "sh"
    tools.require_module("json", "-")
    tools.require_ok(None)


def test_needs_checks_before_the_test_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    ran = []

    @tools.needs("no-such-tool-x", "apt install x")
    def a_test(value: int) -> None:
        ran.append(value)

    monkeypatch.setenv("CI", "1")
    with pytest.raises(pytest.fail.Exception):
        a_test(1)
    assert ran == [] and a_test.__name__ == "a_test"


#: the other rules there were: skip always (importorskip, skipif marks), fail unless told to skip
#: (TD2ADAPTOR_SKIP_ROS1), skip unless CI (a test reading CI itself)
_OTHER_RULES = re.compile(r"importorskip|mark\.skipif|TD2ADAPTOR_SKIP_ROS1|environ\.get\(\"CI\"\)")


def test_no_test_has_a_rule_of_its_own() -> None:
    found = [
        f"{path.relative_to(REPO)}:{number}"
        for path in sorted((REPO / "tests").rglob("*.py"))
        if path.name not in ("tools.py", "test_tools.py") and "expected" not in path.parts
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if _OTHER_RULES.search(line)
    ]
    assert found == []
