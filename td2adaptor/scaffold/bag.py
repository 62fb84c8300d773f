"""A recording: the topics of a ROS 1 `.bag` or a ROS 2 bag (folder, `.db3`, `.mcap`), read with rosbags.

A bag shows only topics, and only as published: each becomes a read property. Latched ROS 1 topics and
ROS 2 topics offered transient-local keep that durability, so the adaptor still gets their last message.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.rostypes.names import normalize_type_name
from td2adaptor.scaffold.graph import Endpoint, Graph, qos_of


def _qos(ext: Any) -> tuple[dict[str, Any] | None, bool]:
    if getattr(ext, "latching", None):
        return {"durability": "transient_local"}, False
    profiles = getattr(ext, "offered_qos_profiles", None) or []
    for profile in profiles:
        reliability = getattr(profile.reliability, "name", "").lower()
        durability = getattr(profile.durability, "name", "").lower()
        keep_last = getattr(profile.history, "name", "").lower() == "keep_last"
        return qos_of(reliability, durability, int(profile.depth) if keep_last else None), False
    return None, False


def read(path: Path, diags: Diagnostics) -> Graph | None:
    """The bag's topics; None (SCF100) when it cannot be read."""
    from rosbags.highlevel import AnyReader

    from td2adaptor.rostypes.typestore import base_store

    if not path.exists():
        diags.error("SCF100", f"no such bag, listing or source: {path}", hint="SOURCE is ros2, ros1, a bag or a .yaml")
        return None
    target = path.parent if path.is_file() and path.suffix in (".db3", ".mcap") else path
    try:
        with AnyReader([target], default_typestore=base_store("ros2")) as reader:
            distro = "ros2" if reader.is2 else "ros1"
            connections = [(c.topic, c.msgtype, c.ext) for c in reader.connections]
    except Exception as exc:  # noqa: BLE001 - rosbags raises many kinds for a damaged or foreign file
        diags.error("SCF100", f"cannot read the bag {path}: {type(exc).__name__}: {exc}")
        return None
    graph = Graph(f"the bag {path.name}", distro="ros1" if distro == "ros1" else "ros2")
    for topic, msgtype, ext in sorted(connections, key=lambda c: c[0]):
        canonical = normalize_type_name(msgtype, "msg")
        if canonical is None:
            continue
        qos, latch = _qos(ext)
        graph.endpoints.append(Endpoint("topic", topic, canonical, "publisher", (), qos, latch))
    return graph
