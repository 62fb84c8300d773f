"""The inputs a target's files make: each TD alone, RosClasses config files together. The build groups a
target's TDs so, and the front-end commands (validate, types) group their arguments so, without loading the
build.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from td2adaptor.diagnostics import Diagnostics


def compile_units(tds: Sequence[Path]) -> list[list[Path]]:
    """The inputs a target's TDs make: each TD or Thing Model alone, and all its RosClasses config files together.

    A RosClasses configuration is split over several files (service.json, topic.json) that only make one
    adaptor together, as `validate` and `migrate` read them; every RosClasses file of a target therefore goes
    into one input, placed where the first of them is. Each TD is its own input beside it (the compiler
    refuses several TDs at once). `validate` and `types` group their arguments the same way.
    """
    if len(tds) < 2:
        return [[td] for td in tds]
    units: list[list[Path]] = []
    config: list[Path] | None = None
    for td in tds:
        if is_rosclasses(td):
            if config is None:
                config = []
                units.append(config)
            config.append(td)
        else:
            units.append([td])
    return units


#: The text of a JSON string that may decode to "RosClasses" (each letter as it is or as a \u escape).
_ROSCLASSES_STRING = re.compile(rb'"(?:[RosClae]|\\u00[0-9A-Fa-f]{2}){10}"')


def is_rosclasses(path: Path) -> bool:
    """Whether `path` is a RosClasses config file. A file whose bytes hold no string that can read
    "RosClasses" is not one: answered without parsing it (the compile that follows parses it, once)."""
    from td2adaptor.frontend.jsonsrc import DEFAULT_MAX_BYTES, load_path
    from td2adaptor.frontend.legacy import is_legacy

    try:
        with path.open("rb") as fh:
            raw = fh.read(DEFAULT_MAX_BYTES + 1)
    except OSError:
        return False
    if len(raw) > DEFAULT_MAX_BYTES or not _ROSCLASSES_STRING.search(raw):
        return False
    doc = load_path(str(path), Diagnostics(), keep=True)  # the compile that follows takes this parse
    return doc is not None and is_legacy(doc.data)
