"""Finding, comparing and refreshing every golden file (see tests/golden/__init__.py).

Two kinds of golden:

* a *configuration* (pyproject.toml's `[tool.td2adaptor]`, or a case's `td2adaptor.toml`): its targets are
  built in memory with `td2adaptor.compiler.build.build` and each output directory must hold exactly the
  generated files and the manifest, byte for byte and with the same executable bits — nothing more. A case
  records a file that is a byte copy of a backend's `verbatim/` source by hash only: the manifest keeps its
  sha256 and `.golden-verbatim.txt` says which source it is (`generated/`, the example users read and
  build, keeps every file). A case may install plug-in backends for itself: each line of its `plugins.txt`
  is a folder (relative to the case) put on the path while it is made, as `pip install` would;
* a *diagnostics snapshot*: the td2adaptor command of `snapshot.toml`, run in a scratch copy of the snapshot's
  folder (so it can never write into the repository), its normalised transcript against `expected.txt`.
"""

from __future__ import annotations

import difflib
import hashlib
import os
import shutil
import stat
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

from click.testing import CliRunner

from td2adaptor.backends import registry
from td2adaptor.cli.main import EXIT_INTERNAL, cli
from td2adaptor.compiler.build import build
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation import targets as config
from td2adaptor.generation.backend import GeneratedTree
from td2adaptor.generation.emit import MANIFEST, _manifest_bytes, plan, write

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

REPO = Path(__file__).resolve().parents[2]
HERE = REPO / "tests" / "golden"
CASES = HERE / "cases"
SNAPSHOTS = HERE / "diagnostics"
CASE_FILE = "td2adaptor.toml"
SNAPSHOT_FILE = "snapshot.toml"
EXPECTED = "expected.txt"
PLUGINS_FILE = "plugins.txt"
VERBATIM_INDEX = ".golden-verbatim.txt"  # a hidden name: no generated file can have it (emit refuses them)
COMMAND = ".venv/bin/python -m tests.golden --refresh"
ADVICE = f"run `{COMMAND}` and review git diff"


@dataclass
class Report:
    """One golden: what differs from what td2adaptor makes now (`A` missing, `M` changed, `D` extra), or why
    it cannot be made at all (`errors`), and for snapshots a unified diff."""

    name: str
    differences: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    diff: str = ""

    @property
    def current(self) -> bool:
        return not self.differences and not self.errors


@dataclass(frozen=True)
class Golden:
    name: str
    path: Path  # a configuration file, or a snapshot folder

    @property
    def is_snapshot(self) -> bool:
        return self.path.is_dir()


def goldens() -> list[Golden]:
    """Every golden in a fixed order: generated/, the cases, the diagnostics snapshots."""
    found = [Golden("generated", REPO / "pyproject.toml")]
    found += [Golden(f"cases/{p.parent.name}", p) for p in sorted(CASES.glob(f"*/{CASE_FILE}"))]
    found += [Golden(f"diagnostics/{p.parent.name}", p.parent) for p in sorted(SNAPSHOTS.glob(f"*/{SNAPSHOT_FILE}"))]
    return found


def compare(golden: Golden, *, refresh: bool = False) -> Report:
    """What differs; with `refresh`, rewrite the golden first (the report then says what was rewritten)."""
    if golden.is_snapshot:
        return _snapshot(golden, refresh)
    return _configuration(golden, refresh)


# ---------------------------------------------------------------------------------------------------------
# generated trees


def _configuration(golden: Golden, refresh: bool) -> Report:
    report = Report(golden.name)
    diags = Diagnostics()
    with installed(golden.path.parent):
        loaded = config.load(golden.path, diags)
        trees = build(loaded.targets, diags, use_cache=False) if loaded is not None else None
    report.errors = [f"{d.location}: {d.code}: {d.message}" for d in diags if d.severity is Severity.ERROR]
    if loaded is None or trees is None or report.errors:
        return report
    expected: dict[Path, dict[str, tuple[bytes, bool]]] = {}
    for root, tree in trees.items():
        expected[root] = _files(tree, by_hash=golden.name != "generated")
    for output in sorted({t.output for t in loaded.targets}):
        for child in sorted(output.iterdir()) if output.is_dir() else []:
            if child not in expected:
                expected[child] = {}  # a folder no target generates (a backend dropped from the case)
    for root, files in sorted(expected.items()):
        changes = _differences(root, files)
        report.differences += [f"{change[0]} {root / change[2:]}" for change in changes]
        if refresh and changes:
            _rewrite(root, trees.get(root), files)
    return report


@contextmanager
def installed(case: Path) -> Iterator[None]:
    """The plug-in backends a case names in its `plugins.txt` installed (on the path, the registry asked
    again) while it is made; uninstalled after, so that no other golden sees them."""
    listed = case / PLUGINS_FILE
    lines = listed.read_text(encoding="utf-8").splitlines() if listed.is_file() else []
    sites = [str((case / line.strip()).resolve()) for line in lines if line.strip()]
    if not sites:
        yield
        return
    sys.path[:0] = sites
    registry.modules.cache_clear()
    try:
        yield
    finally:
        for site in sites:
            sys.path.remove(site)
        registry.modules.cache_clear()


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@cache
def verbatim_sources() -> dict[str, str]:
    """sha256 → repository path of every file a backend copies into its output unchanged (its `verbatim/`;
    a `ruff.toml` there is the repository's lint setting for the folder, not output)."""
    found: dict[str, str] = {}
    for path in sorted((REPO / "td2adaptor" / "backends").glob("*/verbatim/**/*")):
        if path.name == "ruff.toml" and path.parent.name == "verbatim":
            continue
        if path.is_file() and not TOOL_CACHES.intersection(path.parts) and path.suffix != ".pyc":
            found.setdefault(_sha(path.read_bytes()), path.relative_to(REPO).as_posix())
    return found


def _files(tree: GeneratedTree, *, by_hash: bool = False) -> dict[str, tuple[bytes, bool]]:
    """Every file a backend directory must hold: (content, executable), the manifest included. `by_hash`:
    a byte copy of a verbatim source is left out, named in the verbatim index instead (its hash is the
    manifest's)."""
    files = {rel: (data, rel in tree.executable) for rel, data in tree}
    files[MANIFEST] = (_manifest_bytes(tree), False)
    if by_hash:
        sources = verbatim_sources()
        copies = {rel: sources[_sha(data)] for rel, (data, _) in files.items() if _sha(data) in sources}
        lines = [f"{rel} = {source}{' (executable)' * files[rel][1]}\n" for rel, source in sorted(copies.items())]
        for rel in copies:
            del files[rel]
        if lines:
            files[VERBATIM_INDEX] = ("".join(lines).encode(), False)
    return files


def verbatim_index(root: Path) -> dict[str, str]:
    """A case's output directory's verbatim index: generated path → the repository path of its source."""
    path = root / VERBATIM_INDEX
    lines = path.read_text(encoding="utf-8").splitlines() if path.is_file() else []
    return {rel: source.removesuffix(" (executable)") for rel, _, source in (line.partition(" = ") for line in lines)}


def materialize(root: Path, into: Path) -> Path:
    """A case's output directory whole, as td2adaptor writes it: a copy with every verbatim file put back."""
    shutil.copytree(root, into, ignore=shutil.ignore_patterns(VERBATIM_INDEX, *TOOL_CACHES))
    for rel, source in verbatim_index(root).items():
        target = into / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(REPO / source, target)
    return into


# what tools leave beside the files and git ignores (.gitignore): not part of a golden
TOOL_CACHES = frozenset({"__pycache__", ".pytest_cache", ".mypy_cache", ".ruff_cache", ".hypothesis"})


def _on_disk(root: Path) -> dict[str, Path]:
    if not root.exists():
        return {}
    if not root.is_dir():
        return {"": root}
    found = {}
    for path in root.rglob("*"):
        rel = path.relative_to(root)
        if not path.is_dir() and not TOOL_CACHES.intersection(rel.parts) and path.suffix != ".pyc":
            found[rel.as_posix()] = path
    return found


def _differences(root: Path, files: dict[str, tuple[bytes, bool]]) -> list[str]:
    """`A rel` missing, `M rel` other bytes or executable bit, `D rel` not generated, in path order."""
    disk = _on_disk(root)
    out = []
    for rel in sorted(set(files) | set(disk)):
        if rel not in disk:
            out.append(f"A {rel}")
        elif rel not in files:
            out.append(f"D {rel}")
        else:
            data, executable = files[rel]
            path = disk[rel]
            if path.is_symlink() or path.read_bytes() != data or _executable(path) != executable:
                out.append(f"M {rel}")
    return out


def _executable(path: Path) -> bool:
    return bool(path.stat().st_mode & stat.S_IXUSR)


def _rewrite(root: Path, tree: GeneratedTree | None, files: dict[str, tuple[bytes, bool]]) -> None:
    """Make `root` hold exactly `files`: td2adaptor's own writer (forced), then whatever it keeps goes."""
    if tree is None:
        shutil.rmtree(root) if root.is_dir() and not root.is_symlink() else root.unlink()
        return
    if root.exists() and not root.is_dir():
        root.unlink()
    diags = Diagnostics()
    rep = plan(tree, root, diags, force=True)
    if rep is None:
        raise RuntimeError(f"cannot write {root}: {[d.message for d in diags]}")
    write(tree, root, rep)
    for rel, (data, _) in files.items():
        if rel not in tree.files and rel != MANIFEST:  # the verbatim index: the golden's own
            (root / rel).write_bytes(data)
    for rel, path in _on_disk(root).items():
        if rel not in files:
            path.unlink()
        elif _executable(path) != files[rel][1]:  # same bytes: the writer left the file alone
            path.chmod(0o755 if files[rel][1] else 0o644)
    for folder in sorted((p for p in root.rglob("*") if p.is_dir()), key=lambda p: -len(p.parts)):
        if not any(folder.iterdir()) and not TOOL_CACHES.intersection(folder.parts):
            folder.rmdir()


# ---------------------------------------------------------------------------------------------------------
# diagnostics snapshots


def _snapshot(golden: Golden, refresh: bool) -> Report:
    report = Report(golden.name)
    try:
        actual = transcript(golden.path)
    except (OSError, ValueError, KeyError) as exc:
        report.errors.append(f"{golden.path / SNAPSHOT_FILE}: {exc}")
        return report
    path = golden.path / EXPECTED
    recorded = path.read_text(encoding="utf-8") if path.is_file() else None
    if recorded != actual:
        report.differences.append(f"{'M' if recorded is not None else 'A'} {_shown(path)}")
        report.diff = "".join(
            difflib.unified_diff(
                (recorded or "").splitlines(keepends=True),
                actual.splitlines(keepends=True),
                f"{golden.name}/{EXPECTED} (recorded)",
                f"{golden.name}/{EXPECTED} (now)",
            )
        )
        if refresh:
            path.write_text(actual, encoding="utf-8")
    return report


def _spec(folder: Path, key: str) -> list[str]:
    """A list of strings from the snapshot's `snapshot.toml`: `args` (the td2adaptor arguments) or `expect`
    (the diagnostic codes the snapshot is there to show)."""
    with (folder / SNAPSHOT_FILE).open("rb") as fh:
        value = tomllib.load(fh)[key]
    if not isinstance(value, list) or not value or not all(isinstance(a, str) for a in value):
        raise ValueError(f"{key!r} must be a non-empty list of strings")
    return value


def command(folder: Path) -> list[str]:
    """The td2adaptor arguments of a snapshot (`{repo}` stands for the repository's root)."""
    return [a.replace("{repo}", REPO.as_posix()) for a in _spec(folder, "args")]


def expected_codes(folder: Path) -> list[str]:
    return _spec(folder, "expect")


def transcript(folder: Path) -> str:
    """Run the snapshot's command in a scratch copy of its folder; the command, its stdout and stderr and its
    exit code, with the scratch folder written `.` and the repository `<repo>`."""
    args = command(folder)
    with tempfile.TemporaryDirectory(prefix="td2adaptor-golden-") as scratch:
        work = Path(scratch) / folder.name
        shutil.copytree(folder, work, ignore=shutil.ignore_patterns(SNAPSHOT_FILE, EXPECTED))
        with _cwd(work):
            result = CliRunner().invoke(cli, args, prog_name="td2adaptor", env={"TD2ADAPTOR_NO_CACHE": "1"})
        stdout, stderr, code = result.stdout, result.stderr, result.exit_code
        if result.exception is not None and not isinstance(result.exception, SystemExit):
            exc = result.exception
            stderr += f"td2adaptor: internal error: {type(exc).__name__}: {exc} (please report this)\n"
            code = EXIT_INTERNAL
        text = f"$ td2adaptor {' '.join(command_words(folder))}\n"
        for title, stream in (("stdout", stdout), ("stderr", stderr)):
            if stream:
                text += f"[{title}]\n{stream}{'' if stream.endswith(chr(10)) else chr(10)}"
        text += f"[exit {code}]\n"
        for base, name in ((work.resolve(), "."), (work, "."), (REPO, "<repo>")):
            text = text.replace(base.as_posix(), name)
    return text


def command_words(folder: Path) -> list[str]:
    """The command as recorded (with `<repo>`, not this checkout's path)."""
    return [a.replace(REPO.as_posix(), "<repo>") for a in command(folder)]


def _shown(path: Path) -> Path:
    return path.relative_to(REPO) if path.is_relative_to(REPO) else path


@contextmanager
def _cwd(path: Path) -> Iterator[None]:
    old = Path.cwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)
