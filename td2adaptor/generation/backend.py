"""What a backend is: the plug-in interface every folder under `td2adaptor/backends/` implements.

A backend package provides `NAME`, `DISTRO` ("ros1", "ros2" or None), `ORDER` (its place in `--backend all`)
and `generate(model: Model, options: GenOptions, diags: Diagnostics) -> GeneratedTree`. Backends never write
to disk (`generation.emit` does), never see dialects (only the model), and must be deterministic: same model
and options, same bytes.

A backend that reports codes of its own (not the shared GEN8xx ones) declares them: a `Stage` with
`backend=NAME` and its `Entry`s, given to `td2adaptor.diagnostics.catalogue.register` when the backend's
package is imported (before anything reports them), and the stage it returns named `DIAGNOSTICS`. They join
the catalogue, `td2adaptor explain` and, for the backends td2adaptor ships, docs/diagnostics.md.

A backend may also provide `finish(tree: GeneratedTree) -> GeneratedTree`: `build` calls it once per output
directory with the trees of every TD merged (e.g. to add an index of the packages), and writes what it
returns. It must not depend on the order of the TDs.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:  # annotations only: what the generation driver needs from here loads without the model
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.model import Model


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
    ORDER: int
    generate: Callable[[Model, GenOptions, Diagnostics], GeneratedTree]
