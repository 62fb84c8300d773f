"""How serious a diagnostic is; its own module so that the catalogue can use it without an import cycle."""

from __future__ import annotations

import enum


class Severity(str, enum.Enum):
    ERROR = "error"
    WARNING = "warning"
    INFO = "info"
