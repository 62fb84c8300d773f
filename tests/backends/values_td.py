"""The Thing Description of a robot whose component only takes values (write-only properties of given ROS
types): what the tests of the generated packages' number checks (construct_* and publish_*) build and drive."""

from __future__ import annotations

from typing import Any


def values_td(name: str, properties: dict[str, str]) -> dict[str, Any]:
    """A TD `urn:dev:wot:test:<name>` whose `ValuesComponent` has one write-only property per name → ROS type."""

    def prop(prop_name: str, ros_type: str) -> dict[str, Any]:
        form = {"href": f"ros:{prop_name}", "op": ["writeproperty"], "rosv:name": f"/{{{{robotName}}}}/{prop_name}"}
        return {"rosv:component": "ValuesComponent", "writeOnly": True, "forms": [{**form, "rosv:type": ros_type}]}

    return {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "id": f"urn:dev:wot:test:{name}",
        "title": name.replace("-", " ").title() + " Bot",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "properties": {p: prop(p, t) for p, t in properties.items()},
    }
