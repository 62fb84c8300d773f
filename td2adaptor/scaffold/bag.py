"""A recording: the topics of a ROS 1 `.bag` or a ROS 2 bag (folder, `.db3`, `.mcap`), read with rosbags.

A bag shows only topics, and only as published: each becomes a read property. Latched ROS 1 topics and
ROS 2 topics offered transient-local keep that durability, so the adaptor still gets their last message.
A bag also carries the definitions of its message types (ROS 1 connection headers; rosbag2 metadata and
MCAP schemas in the `.msg` format): they go into `Graph.definitions`, so a custom type gets its data schema
without `--interfaces` (definitions stored as IDL are not read).
"""

from __future__ import annotations

import re
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


#: the line genmsg, rosbag2 and MCAP put before each nested type's text: `===...===` then `MSG: pkg/Name`
_SECTION = re.compile(r"^={80}\n", re.MULTILINE)


def definitions(msgtype: str, text: str) -> dict[str, str]:
    """A connection's full definition text → the .msg text of its type and of each type it uses."""
    out: dict[str, str] = {}
    for i, section in enumerate(_SECTION.split(text)):
        if i == 0:
            name: str | None = msgtype
            body = section
        else:
            first, _, body = section.partition("\n")
            name = first[len("MSG:") :].strip() if first.startswith("MSG:") else None
        canonical = normalize_type_name(name, "msg") if name else None
        if canonical is not None:
            out.setdefault(canonical, body)
    return out


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
            texts = [(c.msgtype, c.msgdef.data) for c in reader.connections if c.msgdef.format.name == "MSG"]
    except Exception as exc:  # noqa: BLE001 - rosbags raises many kinds for a damaged or foreign file
        diags.error("SCF100", f"cannot read the bag {path}: {type(exc).__name__}: {exc}")
        return None
    graph = Graph(f"the bag {path.name}", distro="ros1" if distro == "ros1" else "ros2")
    for msgtype, text in texts:
        for name, body in definitions(msgtype, text).items():
            graph.definitions.setdefault(name, (f"{path}:{name}", body))
    for topic, msgtype, ext in sorted(connections, key=lambda c: c[0]):
        canonical = normalize_type_name(msgtype, "msg")
        if canonical is None:
            continue
        qos, latch = _qos(ext)
        graph.endpoints.append(Endpoint("topic", topic, canonical, "publisher", (), qos, latch))
    return graph
