"""The fleet file `td2adaptor run --config` serves, read again on SIGHUP and when it changes on disk.

Each reading goes through the same loader as the start (`config.load_fleet` with the command line's options
and the environment) and is applied to the running fleet (`Fleet.apply`, origin "file"): robots no longer in
the file leave, new ones join, a robot whose settings changed restarts alone. A file that no longer reads (a
YAML error, an unknown key, a robot id twice, a file gone) is reported and changes nothing: the fleet goes on
as it runs. On disk a change is taken once the file has stood still for one look (`poll`, every quarter of a
second from `run`'s main loop), so an editor's half-written file is not read.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol

from td2adaptor.runtime.config import ConfigError, RuntimeConfig
from td2adaptor.runtime.node.fleet import Changes, Fleet, FleetError

log = logging.getLogger("td2adaptor.runtime.fleet")

Stamp = tuple[int, int, int] | None


class Applies(Protocol):
    """What a reading is applied to: the fleet, or its share (`run --share`, share.py) which serves part of it."""

    def apply(self, configs: Sequence[RuntimeConfig], origin: str) -> Changes: ...


def stamp(path: Path) -> Stamp:
    """What tells a changed file (modification time, size, inode); None when it cannot be read."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_mtime_ns, st.st_size, st.st_ino)


class FleetFile:
    """Reloads `path` into `fleet` (see the module docstring); `load` reads it as at the start."""

    def __init__(
        self, path: Path, fleet: Fleet | Applies, load: Callable[[], list[RuntimeConfig]], *, seen: Stamp | None = None
    ) -> None:
        self.path = path
        self.fleet = fleet
        self.load = load
        self.reloads = 0  # readings applied (tests, the log)
        self.refused = 0  # readings that failed and left the fleet as it was
        self._seen: Stamp = seen if seen is not None else stamp(path)  # what the running fleet was read from
        self._moving: Stamp = self._seen  # the last look's, until it stands still

    def poll(self) -> Changes | None:
        """Reload when the file changed since the last reading and stood still since the last look."""
        now = stamp(self.path)
        if now == self._seen:
            self._moving = now
            return None
        if now != self._moving:  # still being written: look again next time
            self._moving = now
            return None
        return self.reload("it changed on disk")

    def reload(self, why: str = "SIGHUP") -> Changes | None:
        """Read the file and apply it; None when it could not be read or applied (the fleet is unchanged)."""
        self._seen = self._moving = stamp(self.path)
        try:
            configs = self.load()
        except ConfigError as exc:
            self.refused += 1
            log.error("fleet file %s not reloaded (%s), the running fleet is kept as it is: %s", self.path, why, exc)
            return None
        try:
            changes = self.fleet.apply(configs, "file")
        except FleetError as exc:
            self.refused += 1
            log.error("fleet file %s not reloaded (%s): %s", self.path, why, exc)
            return None
        self.reloads += 1
        if changes.failed:
            log.error("fleet file %s reloaded (%s): %s", self.path, why, changes.describe())
        else:
            log.info("fleet file %s reloaded (%s): %s", self.path, why, changes.describe())
        return changes
