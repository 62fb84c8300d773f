"""A tiny backend of our own plugin interface, so emit/gen/check are tested independently of real backends.

It writes one module per component and a file whose content depends on the robot namespace use, enough to
exercise new, changed, unchanged and removed files.
"""

from __future__ import annotations

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.model import Model

NAME = "dummy"
DISTRO = None


def generate(model: Model, options: GenOptions, diags: Diagnostics) -> GeneratedTree:
    tree = GeneratedTree()
    pkg = model.package_name
    for comp in model.components:
        members = [s.name for s in comp.services] + [t.name for t in comp.topics]
        tree.add(f"{pkg}/{comp.name.lower()}.txt", "\n".join(members) + "\n")
    tree.add(f"{pkg}/index.txt", "\n".join(c.name for c in model.components) + "\n")
    return tree
