"""Code-generation backends. Each turns the canonical model into a tree of files, in memory.

A backend module provides `NAME`, `DISTRO` ("ros1", "ros2" or None) and
`generate(model: Model, options: GenOptions, diags: Diagnostics) -> GeneratedTree`.
Backends never write to disk (`td2adaptor.emit` does), never see dialects (only the model), and must be
deterministic: same model and options, same bytes.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, Protocol

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.model import Model

#: backend name → module, in the order `--backend all` runs them
BACKENDS: dict[str, str] = {
    "rclpy": "td2adaptor.backends.rclpy",
    "rospy": "td2adaptor.backends.rospy",
    "mros": "td2adaptor.backends.mros",
    "events": "td2adaptor.backends.events",
}


@dataclass(frozen=True)
class GenOptions:
    """What the user chose on the command line (or in project config) besides the model."""

    package_name: str | None = None  # overrides model.package_name
    partial: bool = False  # skip what a backend cannot express (with a warning) instead of failing
    extra: tuple[tuple[str, Any], ...] = ()


@dataclass
class GeneratedTree:
    """Relative POSIX path → file content. Paths are validated by `emit` before anything is written."""

    files: dict[str, bytes] = field(default_factory=dict)
    executable: set[str] = field(default_factory=set)

    def add(self, path: str, content: str | bytes, *, executable: bool = False) -> None:
        if path in self.files:
            raise ValueError(f"backend produced {path!r} twice")
        self.files[path] = content.encode("utf-8") if isinstance(content, str) else content
        if executable:
            self.executable.add(path)

    def __iter__(self) -> Iterator[tuple[str, bytes]]:
        return iter(sorted(self.files.items()))


class Backend(Protocol):
    NAME: str
    DISTRO: str | None
    generate: Callable[[Model, GenOptions, Diagnostics], GeneratedTree]


def available() -> list[str]:
    """Backends whose module exists in this installation, in `all` order."""
    out = []
    for name, module in BACKENDS.items():
        if importlib.util.find_spec(module) is not None:
            out.append(name)
    return out


def load(name: str) -> Backend:
    module: Any = importlib.import_module(BACKENDS[name])
    return module  # type: ignore[no-any-return]
