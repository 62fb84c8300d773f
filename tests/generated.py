"""Generated packages for tests: compile a TD, run one backend, write its tree. The one place the tests that
run a generated package (under rospy, rclpy, the ROS 1 bridge) make it, instead of a copy of these lines each.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import td2adaptor
from td2adaptor.backends.registry import load
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.model import Model


def write(tree: GeneratedTree, out: Path) -> None:
    """Every file of `tree` under `out` (as `td2adaptor gen` lays it out, without its manifest)."""
    for rel, data in tree:
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)


def generate(
    backend: str, td: Path, out: Path, *, interfaces: Sequence[Path] = (), options: GenOptions | None = None
) -> tuple[Model, Path]:
    """`backend`'s package of `td` written under `out`; the model and the package's directory. An invalid TD
    or an error of the backend fails the test with the diagnostics' messages."""
    result = td2adaptor.compile(td, interfaces=list(interfaces))
    assert result.model is not None, [d.message for d in result.diagnostics]
    diags = Diagnostics()
    options = options or GenOptions()
    tree = load(backend).generate(result.model, options, diags)
    assert not [d for d in diags if d.severity is Severity.ERROR], [d.message for d in diags]
    write(tree, out)
    return result.model, out / (options.package_name or result.model.package_name)
