"""Every golden is current: generated/ (the RB-1 example), each case's expected/ tree, each diagnostics
snapshot. And the machinery behind `python -m tests.golden` notices every kind of difference and repairs it.
This is the one test of generated/ against td2adaptor's output.

A case keeps no byte copy of a backend's verbatim source (its hash is in the manifest, its source named in
the verbatim index); the rule that makes that safe, that a backend copies its verbatim files unchanged, is
checked here: every verbatim source is copied by some case, and each copy's hash is the source's.

On a failure: run `.venv/bin/python -m tests.golden --refresh` and review git diff.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest

from td2adaptor.backends import registry
from td2adaptor.generation.emit import MANIFEST, read_manifest
from tests.conftest import REPO
from tests.golden import __main__ as golden_cli
from tests.golden.goldens import (
    ADVICE,
    CASE_FILE,
    CASES,
    EXPECTED,
    SNAPSHOTS,
    VERBATIM_INDEX,
    Golden,
    compare,
    expected_codes,
    goldens,
    materialize,
    transcript,
    verbatim_index,
    verbatim_sources,
)

ALL = goldens()
SNAPSHOT_FOLDERS = [g.path for g in ALL if g.is_snapshot]


@pytest.mark.parametrize("golden", ALL, ids=[g.name for g in ALL])
def test_golden_is_current(golden: Golden) -> None:
    report = compare(golden)
    assert not report.errors, f"{golden.name} cannot be generated: {report.errors}"
    shown = "\n".join(report.differences[:30])
    assert report.current, f"{golden.name} differs from td2adaptor's output now:\n{shown}\n{report.diff}\n{ADVICE}"


def test_the_cases_and_snapshots_are_all_found() -> None:
    names = {g.name for g in ALL}
    assert {"generated", "cases/rb1_fleet", "cases/rosclasses", "cases/std_robot"} <= names
    assert len(SNAPSHOT_FOLDERS) >= 10
    # a folder without its case file or snapshot file would be silently skipped
    assert all((d / CASE_FILE).is_file() for d in CASES.iterdir() if d.is_dir())
    assert all((d / EXPECTED).is_file() for d in SNAPSHOTS.iterdir() if d.is_dir())


def test_every_backend_has_golden_output() -> None:
    """Derived from the registry: generated/ holds each shipped backend's output, and some case each backend's
    (a plug-in's too, installed by its case)."""
    shipped = registry.builtin()
    assert sorted(p.name for p in (REPO / "generated").iterdir() if p.is_dir()) == sorted(shipped)
    in_cases = {p.name for p in CASES.glob("*/expected/*") if p.is_dir()}
    assert set(shipped) <= in_cases and "toy" in in_cases


def _case_roots() -> list[Path]:
    return sorted(p for p in CASES.glob("*/expected/*") if p.is_dir())


def test_no_case_keeps_a_copy_of_a_verbatim_source() -> None:
    sources = verbatim_sources()
    copies = [
        p.relative_to(CASES).as_posix()
        for p in CASES.rglob("*")
        if p.is_file() and hashlib.sha256(p.read_bytes()).hexdigest() in sources
    ]
    assert copies == []


def test_verbatim_files_are_copied_unchanged() -> None:
    """Each file a case records by hash has its source's bytes (the manifest's sha256 is the source's), and
    every verbatim source of every shipped backend is copied by some case: a backend that changed one on the
    way out would leave it unlisted (and its generated file stored whole), which fails here."""
    listed: set[str] = set()
    for root in _case_roots():
        manifest = read_manifest(root)
        for rel, source in verbatim_index(root).items():
            assert manifest[rel] == hashlib.sha256((REPO / source).read_bytes()).hexdigest(), f"{root}/{rel}"
            assert not (root / rel).exists()
            listed.add(source)
    assert sorted(set(verbatim_sources().values()) - listed) == []


def test_a_materialized_case_is_what_td2adaptor_writes(tmp_path: Path) -> None:
    """`materialize` puts the verbatim files back: every file of the manifest, with its hash."""
    root = CASES / "std_robot" / "expected" / "rospy"
    out = materialize(root, tmp_path / "rospy")
    manifest = read_manifest(out)
    on_disk = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()} - {MANIFEST}
    assert on_disk == set(manifest) and verbatim_index(root)
    for rel, sha in manifest.items():
        assert hashlib.sha256((out / rel).read_bytes()).hexdigest() == sha, rel


@pytest.mark.parametrize("folder", SNAPSHOT_FOLDERS, ids=[f.name for f in SNAPSHOT_FOLDERS])
def test_snapshot_shows_the_diagnostics_it_is_for(folder: Path) -> None:
    """A refresh that loses the point of a snapshot (its input no longer produces the codes named in
    `expect`) fails here even though the snapshot is then current."""
    text = (folder / EXPECTED).read_text(encoding="utf-8")
    missing = [c for c in expected_codes(folder) if f'"code": "{c}"' not in text and f" {c}: " not in text]
    assert not missing, f"{folder.name}: {missing} no longer reported; fix the input, then {ADVICE}"


# ---------------------------------------------------------------------------------------------------------
# the machinery


@pytest.fixture
def case(tmp_path: Path) -> Golden:
    """A case outside the repository: std_robot's TD with two backends."""
    folder = tmp_path / "case"
    folder.mkdir()
    shutil.copy(CASES / "std_robot" / "td.json", folder / "td.json")
    (folder / CASE_FILE).write_text(
        'output = "expected"\n\n[[target]]\ntds = ["td.json"]\nbackends = ["events", "rospy"]\n', encoding="utf-8"
    )
    return Golden("cases/tmp", folder / CASE_FILE)


def _kinds(differences: list[str], folder: Path) -> set[tuple[str, str]]:
    return {(d[0], Path(d[2:]).relative_to(folder).as_posix()) for d in differences}


def test_a_case_is_written_then_current(case: Golden) -> None:
    first = compare(case)
    assert first.differences and all(d.startswith("A ") for d in first.differences)
    assert compare(case, refresh=True).differences == first.differences
    assert compare(case).current
    pkg = case.path.parent / "expected" / "rospy" / "diffbot_adaptor"
    assert (pkg / "scripts" / "edge_node").stat().st_mode & 0o100


def test_every_kind_of_difference_is_found_and_repaired(case: Golden) -> None:
    compare(case, refresh=True)
    out = case.path.parent / "expected"
    pkg = out / "rospy" / "diffbot_adaptor"
    readme = pkg / "README.md"
    readme.write_text(readme.read_text() + "edited\n")  # edited
    (pkg / "src" / "diffbot_adaptor" / "components.py").unlink()  # removed
    (pkg / "src" / "diffbot_adaptor" / "errors.py").write_text("# a verbatim copy, kept by hash only\n")
    index = out / "rospy" / VERBATIM_INDEX
    index.write_text(index.read_text().replace("errors.py = ", "errors.py = ./"))  # a source renamed
    (pkg / "notes.txt").write_text("not generated\n")  # foreign file, not in the manifest
    (pkg / "scripts" / "edge_node").chmod(0o644)  # lost its executable bit
    (out / "mros" / "diffbot_adaptor").mkdir(parents=True)  # a backend the case does not generate
    (out / "mros" / "diffbot_adaptor" / "app.cpp").write_text("//\n")
    (pkg / "__pycache__").mkdir()  # tool caches are not part of a golden
    (pkg / "__pycache__" / "x.pyc").write_bytes(b"")
    report = compare(case)
    assert _kinds(report.differences, out) == {
        ("M", "rospy/diffbot_adaptor/README.md"),
        ("A", "rospy/diffbot_adaptor/src/diffbot_adaptor/components.py"),
        ("D", "rospy/diffbot_adaptor/src/diffbot_adaptor/errors.py"),
        ("M", f"rospy/{VERBATIM_INDEX}"),
        ("D", "rospy/diffbot_adaptor/notes.txt"),
        ("M", "rospy/diffbot_adaptor/scripts/edge_node"),
        ("D", "mros/diffbot_adaptor/app.cpp"),
    }
    compare(case, refresh=True)
    assert compare(case).current
    assert not (out / "mros").exists() and not (pkg / "notes.txt").exists()
    assert not (pkg / "src" / "diffbot_adaptor" / "errors.py").exists()
    assert (pkg / "scripts" / "edge_node").stat().st_mode & 0o100


def test_a_case_that_cannot_be_generated_is_an_error_and_nothing_is_written(case: Golden) -> None:
    td = case.path.parent / "td.json"
    td.write_text(td.read_text().replace('"geometry_msgs/msg/Twist"', '"geometry_msgs/msg/Twisst"'))
    report = compare(case, refresh=True)
    assert any("ROS423" in e for e in report.errors), report.errors
    assert not (case.path.parent / "expected").exists()


def test_a_changed_snapshot_is_shown_as_a_diff_and_refreshed(tmp_path: Path) -> None:
    folder = tmp_path / "json_syntax"
    shutil.copytree(SNAPSHOTS / "json_syntax", folder)
    golden = Golden("diagnostics/json_syntax", folder)
    assert compare(golden).current
    recorded = (folder / EXPECTED).read_text()
    (folder / EXPECTED).write_text(recorded.replace('"line": 7', '"line": 9'))
    report = compare(golden)
    assert report.differences == [f"M {folder / EXPECTED}"]
    assert '-      "line": 9,' in report.diff and '+      "line": 7,' in report.diff
    compare(golden, refresh=True)
    assert (folder / EXPECTED).read_text() == recorded


def test_snapshot_commands_run_in_a_scratch_copy(tmp_path: Path) -> None:
    """A command that writes (gen) writes into a copy, never into the snapshot's folder; no absolute path of
    the copy or the checkout stays in the transcript."""
    folder = tmp_path / "writes"
    folder.mkdir()
    shutil.copy(CASES / "std_robot" / "td.json", folder / "td.json")
    (folder / "snapshot.toml").write_text(
        'args = ["gen", "td.json", "-b", "events", "-o", "out", "-I", "{repo}/examples"]\nexpect = ["none"]\n'
    )
    text = transcript(folder)
    assert text.startswith("$ td2adaptor gen td.json -b events -o out -I <repo>/examples\n")
    assert "out/events: 11 written" in text and text.endswith("[exit 0]\n")
    assert sorted(p.name for p in folder.iterdir()) == ["snapshot.toml", "td.json"]
    assert str(tmp_path) not in text and str(Path.cwd()) not in text


def test_the_command_reports_then_refreshes(
    case: Golden, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(golden_cli, "goldens", lambda: [case])
    assert golden_cli.main([]) == 1
    captured = capsys.readouterr()
    assert "STALE     cases/tmp" in captured.out and ADVICE in captured.err
    assert golden_cli.main(["--refresh"]) == 0
    assert "review `git diff`" in capsys.readouterr().err
    assert golden_cli.main([]) == 0
    assert "current   cases/tmp" in capsys.readouterr().out
    assert golden_cli.main(["no-such-golden"]) == 2
