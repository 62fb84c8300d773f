"""Backends are found, not listed: every package under td2adaptor/backends/ is one (a new backend is a new
folder), and so is an entry point of the `td2adaptor.backends` group that another distribution installs."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

import td2adaptor.backends
from td2adaptor.backends import registry
from td2adaptor.compiler.build import resolve_backends


@pytest.fixture
def fresh_registry() -> Iterator[None]:
    registry.modules.cache_clear()
    yield
    registry.modules.cache_clear()


def test_every_backend_folder_is_a_backend_in_its_order() -> None:
    folders = sorted(
        p.name
        for p in Path(td2adaptor.backends.__file__).parent.iterdir()
        if (p / "__init__.py").is_file() and not p.name.startswith("_")
    )
    assert sorted(registry.modules()) == folders
    assert registry.available() == ["rclpy", "rospy", "mros", "events"]  # `all` order: ORDER of each backend
    for name in folders:
        plugin = registry.load(name)
        assert plugin.NAME == name and callable(plugin.generate)
        assert (Path(td2adaptor.backends.__file__).parent / name / "templates").is_dir()


def test_an_entry_point_adds_a_backend(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fresh_registry: None) -> None:
    plugin = tmp_path / "td2a_plugin_backend.py"
    plugin.write_text(
        "from td2adaptor.generation.backend import GeneratedTree\n"
        "NAME = 'plugin'\nDISTRO = None\nORDER = 50\n"
        "def generate(model, options, diags):\n    return GeneratedTree()\n"
    )
    dist = tmp_path / "td2a_plugin-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: td2a-plugin\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[td2adaptor.backends]\nplugin = td2a_plugin_backend\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert registry.available() == ["rclpy", "rospy", "mros", "plugin", "events"]
    assert resolve_backends(["plugin", "rclpy"]) == (["rclpy", "plugin"], None)
    sys.modules.pop("td2a_plugin_backend", None)


def test_unknown_backend_names_the_known_ones() -> None:
    names, problem = resolve_backends(["nope"])
    assert names == [] and problem is not None and "rclpy" in problem and "all" in problem


def test_a_new_backend_folder_is_found_listed_in_the_help_and_generates(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fresh_registry: None
) -> None:
    """Adding a backend is adding a folder: nothing else names it (the CLI's help neither)."""
    from click.testing import CliRunner

    from td2adaptor.cli import cli

    extra = tmp_path / "more_backends"
    (extra / "toy" / "templates").mkdir(parents=True)
    (extra / "toy" / "__init__.py").write_text(
        "from td2adaptor.generation.backend import GeneratedTree\n"
        "NAME = 'toy'\nDISTRO = None\nORDER = 60\n"
        "def generate(model, options, diags):\n"
        "    tree = GeneratedTree()\n"
        "    tree.add('toy.txt', model.thing.title.encode())\n"
        "    return tree\n"
    )
    monkeypatch.setattr(td2adaptor.backends, "__path__", [*td2adaptor.backends.__path__, str(extra)])
    try:
        assert registry.available() == ["rclpy", "rospy", "mros", "toy", "events"]
        runner = CliRunner()
        help_text = runner.invoke(cli, ["gen", "--help"]).output
        assert "rclpy, rospy, mros, toy, events or all" in " ".join(help_text.split())
        td = Path(__file__).resolve().parents[2] / "examples" / "robotnik_rb1" / "td.json"
        interfaces = td.parent / "interfaces"
        out = tmp_path / "out"
        result = runner.invoke(cli, ["gen", str(td), "-I", str(interfaces), "-b", "toy", "-o", str(out), "--no-cache"])
        assert result.exit_code == 0, result.output
        assert (out / "toy" / "toy.txt").read_text() == "Robotnik RB-1"
    finally:
        sys.modules.pop("td2adaptor.backends.toy", None)


def test_the_quick_look_for_entry_points_agrees_with_importlib_metadata(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`registry.entry_points` reads the entry_points.txt files before asking importlib.metadata (start-up time)."""
    from importlib.metadata import entry_points

    assert registry.entry_points() == list(entry_points(group=registry.ENTRY_POINT_GROUP)) == []
    assert not registry._may_declare(registry.ENTRY_POINT_GROUP)
    other = tmp_path / "other-1.0.dist-info"
    other.mkdir()
    (other / "entry_points.txt").write_text("[console_scripts]\nother = other:main\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert not registry._may_declare(registry.ENTRY_POINT_GROUP)
    archive = tmp_path / "eggs.zip"
    archive.write_bytes(b"")
    monkeypatch.syspath_prepend(str(archive))  # not a folder: only importlib.metadata can say what it holds
    assert registry._may_declare(registry.ENTRY_POINT_GROUP)
