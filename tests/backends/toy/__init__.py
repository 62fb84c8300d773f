"""A toy backend, installed the way a third party's is: the proof that a backend is a plug-in.

It lives wholly in this folder (and its golden case, tests/golden/cases/toy): `site/` holds the metadata an
installed distribution would leave (`td2adaptor_toy-1.0.dist-info/entry_points.txt` names this module in the
`td2adaptor.backends` group), so putting `site/` on the path is installing it. Nothing in td2adaptor or in
the other tests names it: the registry finds it, `gen -b toy` runs it, its own code TOY100 joins the
catalogue (`td2adaptor explain TOY100`), and the golden tests pick up its case.

It writes one text file per package: every component's ROS endpoints, names and types only.
"""

from __future__ import annotations

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.diagnostics.catalogue import Entry, Stage, register
from td2adaptor.diagnostics.severity import Severity
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.model import Model

NAME = "toy"
DISTRO: str | None = None
ORDER = 90

DIAGNOSTICS: Stage = register(
    Stage("TOY1", "Toy backend (the test suite's plug-in)", "tests/backends/toy", backend=NAME),
    (Entry("TOY100", (Severity.WARNING,), "services listed by name only: the toy writes no request or response"),),
)


def generate(model: Model, options: GenOptions, diags: Diagnostics) -> GeneratedTree:
    """`<package>/endpoints.txt`: one line per endpoint, in model order."""
    package = options.package_name or model.package_name
    lines = [f"# {model.thing.title}: the ROS endpoints of {package}"]
    services = []
    for component in model.components:
        lines.append(f"[{component.name}]")
        for service in component.services:
            lines.append(f"service {service.name} {service.ros_name.path} {service.type_name}")
            services.append(service)
        for topic in component.topics:
            lines.append(f"topic {topic.name} {topic.ros_name.path} {topic.type_name} {topic.role.value}")
        for action in component.actions:
            lines.append(f"action {action.name} {action.ros_name.path} {action.type_name}")
    if services:
        names = ", ".join(s.name for s in services)
        diags.warning(
            "TOY100", f"toy backend: {len(services)} services listed by name only: {names}", services[0].pointer
        )
    tree = GeneratedTree()
    tree.add(f"{package}/endpoints.txt", "\n".join(lines) + "\n")
    return tree
