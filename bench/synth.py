"""Synthetic TDs in the td2adaptor binding with N affordances (for benchmarks and scale tests)."""

from __future__ import annotations

import json
import sys
from typing import Any


def synthetic_td(n: int) -> dict[str, Any]:
    """N affordances over N/4 components: half services (std_srvs), half topics (std_msgs)."""
    actions: dict[str, Any] = {}
    properties: dict[str, Any] = {}
    for i in range(n):
        comp = f"Component{i // 4}"
        if i % 2 == 0:
            actions[f"action{i}"] = {
                "rosv:component": comp,
                "description": f"Trigger number {i}",
                "forms": [
                    {
                        "href": f"ros:svc/a{i}",
                        "op": "invokeaction",
                        "rosv:name": f"/{{{{robotName}}}}/svc/a{i}",
                        "rosv:type": "std_srvs/srv/Trigger",
                    }
                ],
            }
        else:
            properties[f"prop{i}"] = {
                "rosv:component": comp,
                "type": "object",
                "properties": {"data": {"type": "number"}},
                "observable": True,
                "readOnly": True,
                "forms": [
                    {
                        "href": f"ros:topic/p{i}",
                        "op": ["readproperty", "observeproperty"],
                        "rosv:name": f"/{{{{robotName}}}}/topic/p{i}",
                        "rosv:type": "std_msgs/msg/Float64",
                    }
                ],
            }
    return {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "title": f"Synthetic {n}",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "properties": properties,
        "actions": actions,
    }


if __name__ == "__main__":
    json.dump(synthetic_td(int(sys.argv[1])), sys.stdout, indent=1)
