"""The mros backend's own diagnostic codes (MROS9xx), added to the catalogue when the package is imported.

A backend owns its codes: they are declared here, beside the code that reports them, rather than in
`td2adaptor.diagnostics.catalogue` (which knows no backend); `docs/diagnostics.md` and `td2adaptor explain`
show them with the rest.
"""

from __future__ import annotations

from td2adaptor.diagnostics.catalogue import Entry, Stage, register
from td2adaptor.diagnostics.severity import Severity

_E, _W, _I = Severity.ERROR, Severity.WARNING, Severity.INFO

ENTRIES: tuple[Entry, ...] = (
    Entry(
        "MROS900",
        (_E, _W),
        "TD action: mROS 1 has no services",
        "pass --partial to skip the actions, or use the rospy backend",
        "warning under --partial, which skips the actions: one warning lists them",
    ),
    Entry("MROS901", (_W,), "node name longer than mROS allows; the td2a_pub/td2a_sub default is used"),
    Entry("MROS902", (_E,), "topic name longer than mROS's 48 characters"),
    Entry("MROS903", (_W,), "a namespaced topic leaves no room for a robot namespace"),
    Entry("MROS904", (_E,), "type name longer than mROS's 49 characters"),
    Entry("MROS905", (_W,), "more topics/publishers/subscribers than mROS's default tables; the table is raised"),
    Entry("MROS906", (_W,), "latched publisher requested; mROS 1 cannot latch"),
    Entry(
        "MROS907",
        (_E, _W),
        "TD action bound to a ROS action: mROS has no actions",
        "pass --partial to skip it, or use the rospy backend (ROS 1 actions on actionlib; rclpy for ROS 2)",
        "warning under --partial, which skips the actions: one warning lists them",
    ),
    Entry("MROS910", (_E,), "message larger than the largest allowed pool block", "raise mros.max_pool_block"),
    Entry("MROS911", (_I,), "unbounded strings/sequences: pool sized with the assumed capacities"),
    Entry("MROS912", (_E,), "invalid mros.* option"),
    Entry(
        "MROS913",
        (_W,),
        "a subscribed message is sized below what robots usually publish (e.g. a laser scan's ranges)",
        "--option mros.capacity.<pkg>/msg/<Type>.<field>=N",
    ),
    Entry(
        "MROS914",
        (_E,),
        "a ROS 1 publisher's TCPROS header (with the full message definition) overruns mROS's subscriber buffer",
        "raise MROS_PACKET_MAXSIZE_RES_TCPROS in the mROS tree and state it: --option mros.tcpros_header_max=N",
    ),
    Entry(
        "MROS915",
        (_E,),
        "a rospy subscriber's TCPROS header (with the full message definition) overruns mROS's publisher buffer",
        "raise MROS_PACKET_MAXSIZE_REQ_TCPROS in the mROS tree and state it: --option mros.tcpros_header_max=N",
    ),
    Entry(
        "MROS916",
        (_E,),
        "an XML-RPC request mROS sends for a topic does not fit its packet buffer (the topic never registers)",
        "raise MROS_PACKET_MAXSIZE_REQ_REGISTER_* in the mROS tree and state it: --option mros.xmlrpc_packet_max=N",
    ),
    Entry(
        "MROS917",
        (_W,),
        "a TCPROS header fits the stated mROS limit only as counted without comments (a lower bound)",
        "pass the types' .msg files with -I to check the exact size",
    ),
    Entry("MROS920", (_W,), "field or constant name unusable in C++: renamed with a trailing '_'"),
    Entry("MROS921", (_W,), "package or message name unusable in C++: the namespace/class is renamed"),
    Entry("MROS922", (_E,), "component or affordance name unusable in C++ identifiers"),
    Entry(
        "MROS923",
        (_W, _E),
        "component name reserved in C++ (renamed), or generated C++ names collide",
        None,
        "error when the generated names collide",
    ),
    Entry("MROS930", (_W,), "no property bound to a topic: only a README is generated"),
    Entry("MROS931", (_E,), "a topic's message type ROS 1 cannot use (not found, or for ROS 2 only)"),
    Entry("MROS932", (_E,), "field type ROS 1 lacks, e.g. wstring"),
    Entry("MROS933", (_W,), "constant C++ cannot hold (non-finite float) or of an unknown type: left out"),
)

DIAGNOSTICS: Stage = register(Stage("MROS9", "mROS backend", "backends/mros", backend="mros"), ENTRIES)
