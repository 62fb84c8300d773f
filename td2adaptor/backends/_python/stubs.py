"""The shape of the type stubs both Python backends write for their interface packages.

rosidl (ROS 2) and genpy (ROS 1) message classes carry no type information; each backend describes the classes
its package uses with these, and its template prints them in its dialect (rosidl's keyword-only constructors,
genpy's `genpy.Message` base class).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class StubField:
    """One message field: what reading it gives, and what the constructor accepts for it."""

    name: str
    annotation: str
    init: str


@dataclass(frozen=True)
class StubClass:
    """A message class (constants are whole declarations, e.g. `MAX: Final = 3`), or a service class that
    names its request and response classes."""

    name: str
    constants: list[str]
    fields: list[StubField]
    request: str | None = None
    response: str | None = None
    aliases: tuple[tuple[str, str], ...] = ()  # ROS 2 action classes: (Goal, Fibonacci_Goal), ...


@dataclass(frozen=True)
class StubModule:
    """One `.pyi` file: its path under `stubs/`, its first line (docstring or comment), imports and classes."""

    path: str
    header: str
    imports: list[str]
    classes: list[StubClass]
