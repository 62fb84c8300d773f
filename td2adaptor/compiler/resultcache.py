"""Cache of compile results, so an unchanged TD validates (and later regenerates) without recompiling.

The key covers everything a result depends on that is known up front: td2adaptor's own code and data, the
options, the input files and every file under the interface folders. Files discovered while compiling
(`tm:extends`/`tm:ref` targets, linked Thing Models) are recorded with their hashes and re-checked on every
hit. Entries are pickles written by td2adaptor itself into the user's cache directory (see `cache.py`).
"""

from __future__ import annotations

import hashlib
import os
import pickle
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from td2adaptor.frontend import jsonsrc
from td2adaptor.support import cache

_FORMAT = 1
_PKG = Path(__file__).resolve().parents[1]  # the td2adaptor package, bundled schemas included


def _code_fingerprint() -> str:
    """Sizes and mtimes of td2adaptor's sources and data (templates and verbatim files included, since cached
    generated trees depend on them): any edit or upgrade invalidates the cache."""
    h = hashlib.sha256()
    for path, st in sorted(_files(str(_PKG))):
        h.update(f"{path}:{st.st_size}:{st.st_mtime_ns}\n".encode())
    return h.hexdigest()


def _files(folder: str) -> list[tuple[str, os.stat_result]]:
    """Every file under `folder` outside `__pycache__` (as `Path.rglob` and `is_file` see them: symbolic links
    followed) with its stat; os.scandir, since pathlib took a third of a cache hit's time."""
    out = []
    with os.scandir(folder) as entries:
        for entry in entries:
            if entry.is_dir():
                if entry.name != "__pycache__":
                    out += _files(entry.path)
            elif entry.is_file():
                out.append((entry.path, entry.stat()))
    return out


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def key(sources: Sequence[str], interfaces: Sequence[Path], options: Any) -> str | None:
    """The cache key, or None when the inputs cannot be cached (stdin, unreadable files)."""
    h = hashlib.sha256(f"{_FORMAT}\n{_code_fingerprint()}\n{options!r}\n".encode())
    try:
        for src in sources:
            if src == "-":
                return None
            p = Path(src).resolve()
            # the spelling too: diagnostics name files as the user wrote them, and a hit must repeat that
            h.update(f"src {p} {src} {_file_digest(p)}\n".encode())
        for folder in interfaces:
            root = Path(folder).resolve()
            h.update(f"dir {root} {folder}\n".encode())
            if root.is_dir():
                for f in sorted(root.rglob("*")):
                    if f.is_file():
                        h.update(f"{f.relative_to(root)} {_file_digest(f)}\n".encode())
    except OSError:
        return None
    return h.hexdigest()


def cached(cache_key: str | None, compute: Callable[[], Any]) -> Any:
    """`compute()`'s result for `cache_key`, from the cache when every recorded dependency is unchanged."""
    directory = cache.cache_dir()
    if cache_key is None or directory is None:
        return compute()
    entry = directory / "results" / f"{cache_key}.pickle"
    try:
        with entry.open("rb") as fh:
            deps, value = pickle.load(fh)
        if all(Path(p).is_file() and _file_digest(Path(p)) == digest for p, digest in deps):
            if jsonsrc.READ_LOG is not None:  # an enclosing cached computation depends on them too
                jsonsrc.READ_LOG.extend(deps)
            return value
    except (OSError, pickle.PickleError, EOFError, ValueError, TypeError, AttributeError, ImportError):
        pass
    previous = jsonsrc.READ_LOG
    log: list[tuple[str, str]] = []
    jsonsrc.READ_LOG = log
    try:
        value = compute()
    finally:
        jsonsrc.READ_LOG = previous
        if previous is not None:
            previous.extend(log)
    try:
        from td2adaptor.support.fsutil import write_atomic

        write_atomic(entry, pickle.dumps((log, value), protocol=pickle.HIGHEST_PROTOCOL))
    except (OSError, pickle.PickleError, TypeError, AttributeError):
        pass
    return value
