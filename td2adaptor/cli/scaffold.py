"""`td2adaptor scaffold`: a TD (or a fleet's Thing Model) from a running robot, a bag or a listing."""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from td2adaptor.cli.common import EXIT_INVALID, EXIT_OK, _format_option, cli, report, write_json

if TYPE_CHECKING:
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.scaffold.graph import Graph


def _read_source(source: str, diags: Diagnostics, opts: dict[str, Any]) -> Graph | None:
    if source == "ros1":
        from td2adaptor.scaffold import ros1graph

        return ros1graph.read(diags, master_uri=opts["master_uri"], timeout=opts["wait"])
    path = Path(source)
    if path.suffix in (".yaml", ".yml", ".json") and path.is_file():
        from td2adaptor.scaffold import listing

        return listing.read(path, diags)
    from td2adaptor.scaffold.bag import read as read_bag

    return read_bag(path, diags)


def _existing(path: Path, diags: Diagnostics) -> dict[str, Any] | None:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        diags.error("SCF110", f"cannot read the TD to merge into, {path}: {exc}")
        return None
    if not isinstance(doc, dict) or not any(isinstance(doc.get(s), dict) for s in ("properties", "actions", "events")):
        diags.error("SCF110", f"{path} is not a Thing Description (no properties, actions or events)")
        return None
    return doc


@cli.command()
@click.argument("source", metavar="SOURCE")
@click.option("-o", "--output", default="-", show_default=True, help="Where to write the TD ('-': stdout).")
@click.option(
    "--interfaces",
    "-I",
    multiple=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder of interface packages for types the standard sets lack; repeatable.",
)
@click.option("--namespace", "namespaces", multiple=True, help="Only names under this namespace (repeatable).")
@click.option("--node", "nodes", multiple=True, help="Only endpoints of this node, full name (repeatable).")
@click.option("--include", multiple=True, metavar="REGEX", help="Only names matching (repeatable).")
@click.option("--exclude", multiple=True, metavar="REGEX", help="Leave out names matching (repeatable).")
@click.option("--keep", multiple=True, metavar="NAME", help="Keep this infrastructure name (e.g. /tf_static).")
@click.option(
    "--robot-namespace",
    "robot_namespaces",
    multiple=True,
    help="The robot namespace(s) written as {{robotName}} (default: found; several: a Thing Model).",
)
@click.option(
    "--group",
    type=click.Choice(["prefix", "node"]),
    default="prefix",
    show_default=True,
    help="Components: by shared name prefix, or by the node serving each endpoint.",
)
@click.option("--title", help="The Thing's title (the generated package name derives from it).")
@click.option(
    "--merge",
    "merge_into",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Update this TD (keeps its names and texts); write the result with -o.",
)
@click.option("--master-uri", help="ROS 1 master (SOURCE ros1; default: ROS_MASTER_URI).")
@click.option("--domain-id", type=click.IntRange(0, 232), help="ROS 2 domain id (default: ROS_DOMAIN_ID).")
@click.option("--wait", type=float, default=10.0, show_default=True, help="Longest wait for the graph, seconds.")
@click.option(
    "--settle", type=float, default=2.0, show_default=True, help="ROS 2: the part asked about unchanged this long."
)
@_format_option
def scaffold(
    source: str,
    output: str,
    interfaces: tuple[Path, ...],
    namespaces: tuple[str, ...],
    nodes: tuple[str, ...],
    include: tuple[str, ...],
    exclude: tuple[str, ...],
    keep: tuple[str, ...],
    robot_namespaces: tuple[str, ...],
    group: str,
    title: str | None,
    merge_into: Path | None,
    master_uri: str | None,
    domain_id: int | None,
    wait: float,
    settle: float,
    fmt: str,
) -> None:
    """Write a TD from SOURCE: 'ros2' (the running graph), 'ros1' (the master), a bag (.bag, or a ROS 2
    bag folder / .db3 / .mcap) or a listing (.yaml: names and types)."""
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.scaffold import Options
    from td2adaptor.scaffold import scaffold as build
    from td2adaptor.scaffold.graph import Filters

    diags = Diagnostics()
    existing = _existing(merge_into, diags) if merge_into is not None else None
    opts = {"wait": wait, "master_uri": master_uri}
    options = Options(
        Filters(namespaces, nodes, include, exclude, keep),
        robot_namespaces,
        "node" if group == "node" else "prefix",
        title,
        interfaces,
    )
    doc = None
    wanted = options.filters.wanted(diags)  # invalid expressions are reported here, before any waiting
    if diags.has_errors:
        pass
    elif source == "ros2":
        from td2adaptor.scaffold import ros2graph

        with ros2graph.opened(diags, wait=wait, settle=settle, domain_id=domain_id, wanted=wanted) as graph:
            doc = None if graph is None else build(graph, options, diags)
    else:
        graph = _read_source(source, diags, opts)
        doc = None if graph is None else build(graph, options, diags)
    if doc is not None and existing is not None:
        from td2adaptor.scaffold.merge import merge

        doc = merge(existing, doc, diags)
    # located at the source (the listing or bag, ros2, ros1) unless a diagnostic names its own file
    located = [d if d.file else replace(d, file=source) for d in diags]
    ok = report(located, fmt if output != "-" else "human", label=f"scaffold {source}")
    if doc is None or not ok:
        sys.exit(EXIT_INVALID)
    write_json(doc, output)
    sys.exit(EXIT_OK)
