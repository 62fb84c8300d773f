"""The `td2adaptor` command line (click). `main` is the console-script entry point."""

from __future__ import annotations

from td2adaptor.cli.main import cli, main

__all__ = ["cli", "main"]
