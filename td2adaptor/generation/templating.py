"""The Jinja2 environment every backend renders with: one place for the settings and the bytecode cache.

Each backend keeps its templates in its own folder (`backends/<name>/templates/`) and its verbatim files
(copied unchanged) in `backends/<name>/verbatim/`.

Templates are dumb (backends compute names, types and imports; the names of generated methods come from the
global `api`, the contract of the generated API, `model/genapi.py`); StrictUndefined turns a missing value into
an error instead of an empty string. Compiled templates are cached in the user cache (compiling them is
most of a warm `check`); any cache failure just means no cache.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import jinja2
import jinja2.bccache

from td2adaptor.model import genapi
from td2adaptor.support.cache import cache_dir


class _QuietBytecodeCache(jinja2.FileSystemBytecodeCache):
    def load_bytecode(self, bucket: jinja2.bccache.Bucket) -> None:
        try:
            super().load_bytecode(bucket)
        except OSError:
            pass

    def dump_bytecode(self, bucket: jinja2.bccache.Bucket) -> None:
        try:
            super().dump_bytecode(bucket)
        except OSError:
            pass


def _bytecode_cache(backend: str) -> jinja2.BytecodeCache | None:
    directory = cache_dir()
    if directory is None:
        return None
    try:
        (directory / "jinja").mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return _QuietBytecodeCache(str(directory / "jinja"), f"{backend}-%s.cache")


@cache
def environment(directory: Path, *, trim: bool = True) -> jinja2.Environment:
    """The environment for a backend's template folder."""
    backend = directory.parent.name
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(directory)),
        autoescape=False,
        keep_trailing_newline=True,
        trim_blocks=trim,
        lstrip_blocks=trim,
        undefined=jinja2.StrictUndefined,
        bytecode_cache=_bytecode_cache(backend),
    )
    env.globals["api"] = genapi
    return env


def render(directory: Path, template: str, **context: object) -> str:
    """`directory/<template>` rendered with `context`."""
    return environment(directory).get_template(template).render(**context)


@cache
def verbatim(directory: Path, name: str) -> bytes:
    """A file copied into the output as it is (read once per process)."""
    return (directory / name).read_bytes()
