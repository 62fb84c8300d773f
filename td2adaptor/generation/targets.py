"""Project configuration: `[tool.td2adaptor]` in pyproject.toml, or a td2adaptor.toml, found upwards from cwd.

    [tool.td2adaptor]
    output = "generated"                      # default for every target

    [[tool.td2adaptor.target]]
    tds = ["examples/robotnik_rb1/*.json"]    # paths or globs, relative to the config file
    backends = ["all"]
    interfaces = ["examples/robotnik_rb1/interfaces"]
    output = "generated"                      # optional, overrides the default
    values = { robotName = "rb1_base_a" }     # Thing Model placeholder values (optional)
    package-name = "my_adaptor"               # optional
    partial = true                            # skip what a backend cannot express (e.g. services in mROS)
    options = { "mros.sequence_capacity" = 16, "mros.capacity.sensor_msgs/msg/LaserScan.ranges" = 720 }
    exclude = ["**/*.tm.json"]                # optional globs

In td2adaptor.toml the same keys live at the top level (`output`, `[[target]]`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostics

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


@dataclass(frozen=True)
class Target:
    """One generation job: which TDs, which backends, where to."""

    tds: tuple[Path, ...]
    backends: tuple[str, ...] = ("all",)
    output: Path = Path("generated")
    interfaces: tuple[Path, ...] = ()
    values: tuple[tuple[str, Any], ...] = ()
    package_name: str | None = None
    partial: bool = False
    strict: bool = False
    options: tuple[tuple[str, Any], ...] = ()  # backend options, `<backend>.<name>` = value (GenOptions.extra)


@dataclass(frozen=True)
class Config:
    path: Path
    targets: tuple[Target, ...] = field(default_factory=tuple)


#: pyproject.toml files `find` parsed, with their text: `load` of the same unchanged text takes the parse once
_FOUND: dict[str, tuple[str, dict[str, Any]]] = {}


def find(start: Path | None = None) -> Path | None:
    """The nearest td2adaptor.toml, or pyproject.toml with a [tool.td2adaptor] table, from `start` upwards."""
    here = (start or Path.cwd()).resolve()
    for folder in (here, *here.parents):
        own = folder / "td2adaptor.toml"
        if own.is_file():
            return own
        pyproject = folder / "pyproject.toml"
        if pyproject.is_file():
            try:
                text = pyproject.read_text(encoding="utf-8")
                data = tomllib.loads(text)
                if "td2adaptor" in data.get("tool", {}):
                    _FOUND[str(pyproject)] = (text, data)
                    return pyproject
            except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
                continue
    return None


def load(path: Path, diags: Diagnostics) -> Config | None:
    """Parse and check a configuration file; every problem is a diagnostic (CFG90x), never an exception."""
    name = str(path)
    try:
        text = path.read_text(encoding="utf-8")
        found = _FOUND.pop(name, None)
        data = found[1] if found is not None and found[0] == text else tomllib.loads(text)
    except (OSError, UnicodeDecodeError) as exc:
        diags.add("CFG900", _err(), f"cannot read {name}: {exc}", file=name)
        return None
    except tomllib.TOMLDecodeError as exc:
        diags.add("CFG901", _err(), f"invalid TOML: {exc}", file=name)
        return None
    table = data.get("tool", {}).get("td2adaptor") if path.name == "pyproject.toml" else data
    if not isinstance(table, dict):
        diags.add("CFG902", _err(), "[tool.td2adaptor] must be a table", file=name)
        return None
    base = _display_base(path.parent)
    default_output = table.get("output", "generated")
    raw_targets = table.get("target", [])
    if not isinstance(raw_targets, list) or not raw_targets:
        diags.add("CFG903", _err(), "no [[tool.td2adaptor.target]] tables: nothing to generate", file=name)
        return None
    targets = []
    for i, raw in enumerate(raw_targets):
        where = f"target #{i + 1}"
        if not isinstance(raw, dict):
            diags.add("CFG904", _err(), f"{where} must be a table", file=name)
            continue
        known = {
            "tds",
            "td",
            "backends",
            "interfaces",
            "output",
            "values",
            "package-name",
            "partial",
            "strict",
            "exclude",
            "options",
        }
        for key in raw:
            if key not in known:
                diags.add(
                    "CFG905", _err(), f"{where}: unknown key {key!r} (known: {', '.join(sorted(known))})", file=name
                )
        patterns = _strings(raw.get("tds", raw.get("td")), f"{where}: tds", name, diags)
        excludes = _strings(raw.get("exclude", []), f"{where}: exclude", name, diags)
        tds = _expand(base, patterns, excludes)
        if patterns and not tds:
            diags.add("CFG906", _err(), f"{where}: no file matches {patterns}", file=name)
        values = raw.get("values", {})
        if not isinstance(values, dict):
            diags.add("CFG904", _err(), f"{where}: values must be a table", file=name)
            values = {}
        output = raw.get("output", default_output)
        package = raw.get("package-name")
        backend_options = raw.get("options", {})
        if not isinstance(backend_options, dict):
            diags.add("CFG904", _err(), f"{where}: options must be a table", file=name)
            backend_options = {}
        targets.append(
            Target(
                tds=tuple(tds),
                backends=tuple(_strings(raw.get("backends", ["all"]), f"{where}: backends", name, diags)),
                output=base / str(output),
                interfaces=tuple(
                    base / p for p in _strings(raw.get("interfaces", []), f"{where}: interfaces", name, diags)
                ),
                values=tuple(sorted(values.items())),
                package_name=package if isinstance(package, str) else None,
                partial=bool(raw.get("partial", False)),
                strict=bool(raw.get("strict", False)),
                options=tuple(sorted(backend_options.items())),
            )
        )
    return Config(path, tuple(targets))


def _display_base(folder: Path) -> Path:
    """The config's folder relative to the working directory when it is inside it (shorter messages)."""
    try:
        rel = folder.resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        return folder
    return rel if str(rel) != "." else Path()


def _err() -> Any:
    from td2adaptor.diagnostics import Severity

    return Severity.ERROR


def _strings(value: Any, what: str, name: str, diags: Diagnostics) -> list[str]:
    if isinstance(value, str):
        return [value]
    if isinstance(value, list) and all(isinstance(v, str) for v in value):
        return list(value)
    if value is not None:
        diags.add("CFG904", _err(), f"{what} must be a string or a list of strings", file=name)
    return []


def _expand(base: Path, patterns: Sequence[str], excludes: Sequence[str]) -> list[Path]:
    """Glob patterns relative to the config file, sorted (directory listing order never matters)."""
    found: dict[Path, None] = {}
    for pattern in patterns:
        matches = sorted(base.glob(pattern)) if any(c in pattern for c in "*?[") else [base / pattern]
        for m in matches:
            if m.is_file() and not any(m.match(x) or m.relative_to(base).match(x) for x in excludes):
                found[m] = None
    return list(found)


@dataclass(frozen=True)
class Options:
    """What a caller (the CLI's options, or the library's keyword arguments) asks for besides the TDs.

    None / empty means "not given": with TDs the defaults apply (all backends, `generated/`); with the
    project configuration each configured target keeps its own setting.
    """

    backends: tuple[str, ...] = ()
    output: Path | None = None
    interfaces: tuple[Path, ...] = ()
    values: tuple[tuple[str, Any], ...] = ()
    package_name: str | None = None
    partial: bool = False
    strict: bool = False
    options: tuple[tuple[str, Any], ...] = ()


NO_CONFIGURATION = "no TD given and no td2adaptor.toml or [tool.td2adaptor] in pyproject.toml found"


def targets(
    tds: Sequence[Path | str], options: Options, diags: Diagnostics, *, config: Path | None = None
) -> list[Target] | None:
    """The generation jobs for `gen`/`check`, the same for the CLI and the library.

    With TDs: one target built from `options`. Without: the project configuration (`config`, or the one
    found upwards from the working directory), each of its targets with every given option applied on top:
    backends, output and package name replace the configured ones, interfaces are added, placeholder values
    and backend options are merged (the option wins), partial and strict switch on. None (with diagnostics)
    when there is no configuration or it is invalid (CFG907 for none at all).
    """
    if tds:
        return [
            Target(
                tds=tuple(Path(p) for p in tds),
                backends=options.backends or ("all",),
                output=options.output or Path("generated"),
                interfaces=options.interfaces,
                values=options.values,
                package_name=options.package_name,
                partial=options.partial,
                strict=options.strict,
                options=options.options,
            )
        ]
    path = config or find()
    if path is None:
        diags.error("CFG907", NO_CONFIGURATION)
        return None
    loaded = load(path, diags)
    if loaded is None:
        return None
    return [_override(t, options) for t in loaded.targets]


def _override(target: Target, options: Options) -> Target:
    values = dict(target.values)
    values.update(options.values)
    backend_options = dict(target.options)
    backend_options.update(options.options)
    return Target(
        tds=target.tds,
        backends=options.backends or target.backends,
        output=options.output or target.output,
        interfaces=target.interfaces + tuple(p for p in options.interfaces if p not in target.interfaces),
        values=tuple(sorted(values.items())),
        package_name=options.package_name or target.package_name,
        partial=target.partial or options.partial,
        strict=target.strict or options.strict,
        options=tuple(sorted(backend_options.items())),
    )
