"""The one policy for what a test needs from outside Python's venv (a program, a module, a set-up tree):
`require`. Without it a test is skipped with a one-line reason on a developer's machine and fails in CI,
where `.ci/setup.sh --test` installs everything, so that a broken set-up never passes as a row of skips.

CI says it is CI with the `CI` environment variable (`.ci/run` sets it; hosted CI services set it too).
"""

from __future__ import annotations

import functools
import importlib.util
import os
import shutil
from collections.abc import Callable
from typing import Any, NoReturn, TypeVar

import pytest

F = TypeVar("F", bound=Callable[..., Any])


def in_ci() -> bool:
    """Whether this run is CI's: `CI` set to anything but empty, `0` or `false`."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false")


def missing(reason: str) -> NoReturn:
    """A need not met: fail in CI, skip elsewhere; `reason` is one line that says how to meet it."""
    if in_ci():
        pytest.fail(f"{reason} (CI installs it: .ci/setup.sh --test)", pytrace=False)
    pytest.skip(reason, allow_module_level=True)


def require(tool: str, setup: str) -> str:
    """The path of the program `tool`; `setup` says how to install it (`.ci/setup-mros.sh`)."""
    found = shutil.which(tool)
    if found is None:
        missing(f"{tool} not installed ({setup})")
    return found


def require_module(name: str, setup: str) -> None:
    """The Python module `name` is importable (without importing it)."""
    if importlib.util.find_spec(name) is None:
        missing(f"Python module {name} not installed ({setup})")


def require_ok(problem: str | None) -> None:
    """A set-up check that says why it is not met (`harness.ros1_problem()`, None when it is)."""
    if problem is not None:
        missing(problem)


def needs(tool: str, setup: str) -> Callable[[F], F]:
    """A test decorator: `require(tool, setup)` before the test runs (a skipif mark could only skip)."""

    def decorate(test: F) -> F:
        @functools.wraps(test)
        def run(*args: Any, **kwargs: Any) -> Any:
            require(tool, setup)
            return test(*args, **kwargs)

        return run  # type: ignore[return-value]

    return decorate
