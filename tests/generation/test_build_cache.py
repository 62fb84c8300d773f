"""The build result cache: an unchanged project is answered without any backend, any change is a miss."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from td2adaptor.compiler import build, resultcache
from tests.conftest import EXAMPLE

_PROBE = """
import json, sys
from td2adaptor.compiler import build
target = build.target("td.json", interfaces=["interfaces"], backends=["rclpy", "events"], output="out")
outcome = build.check([target])
# the registry that finds the backends is loaded (to learn of installed ones), no backend is
loaded = sorted(m for m in sys.modules if m.startswith("td2adaptor.backends.") and m != "td2adaptor.backends.registry")
slow = sorted(m for m in ("td2adaptor.model", "td2adaptor.compiler.pipeline", "importlib.metadata") if m in sys.modules)
print(json.dumps({"ok": outcome.ok, "backends": loaded, "slow": slow}))
"""


@pytest.fixture
def work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("TD2ADAPTOR_CACHE_DIR", str(tmp_path / "cache"))
    shutil.copytree(EXAMPLE, tmp_path / "rb1", ignore=shutil.ignore_patterns("sim"))
    monkeypatch.chdir(tmp_path / "rb1")
    return tmp_path / "rb1"


def _target() -> build.Target:
    return build.target("td.json", interfaces=["interfaces"], backends=["rclpy", "events"], output="out")


def _probe(work: Path) -> dict[str, object]:
    env = {**os.environ, "TD2ADAPTOR_CACHE_DIR": str(work.parent / "cache")}
    out = subprocess.run([sys.executable, "-c", _PROBE], cwd=work, env=env, capture_output=True, text=True, check=True)
    return dict(json.loads(out.stdout))


def test_check_of_an_unchanged_project_imports_no_backend(work: Path) -> None:
    assert build.generate([_target()]).ok
    first = _probe(work)  # the build is cached by generate already: no backend is needed to compare
    # nor the model, the compiler or importlib.metadata (the pre-commit check's start-up time, issue 17)
    assert first == {"ok": True, "backends": [], "slow": []}
    (work / "out" / "rclpy" / "robotnik_rb_1_adaptor" / "package.xml").write_text("edited\n")
    assert _probe(work) == {"ok": False, "backends": [], "slow": []}  # a hit still compares every file with disk


def test_changed_td_or_interface_is_a_miss(work: Path) -> None:
    assert build.generate([_target()]).ok
    td = json.loads((work / "td.json").read_text())
    td["title"] = "Renamed Robot"
    (work / "td.json").write_text(json.dumps(td))
    probe = _probe(work)
    assert probe["ok"] is False and "td2adaptor.backends.rclpy" in str(probe["backends"])
    assert build.generate([_target()]).ok and build.check([_target()]).ok
    srv = work / "interfaces" / "robot_local_control_msgs" / "srv" / "GoToPetition.srv"
    srv.write_text(srv.read_text().replace("---", "int32 extra\n---", 1))
    assert not build.check([_target()]).ok


def test_dependencies_found_by_a_cached_inner_step_reach_the_outer_entry(work: Path) -> None:
    """A build hit must notice a changed `tm:extends` target even when the compile inside it was a hit."""
    parent, child = work / "parent.tm.json", work / "child.tm.json"
    context = ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"]
    form = {"href": "ros:p", "rosv:name": "/p", "rosv:type": "std_msgs/msg/Float64"}
    parent.write_text(
        json.dumps(
            {"@context": context, "@type": "tm:ThingModel", "title": "P", "properties": {"p": {"forms": [form]}}}
        )
    )
    link = {"rel": "tm:extends", "href": "./parent.tm.json", "type": "application/tm+json"}
    child.write_text(json.dumps({"@context": context, "@type": "tm:ThingModel", "title": "C", "links": [link]}))
    import td2adaptor

    def compile_child() -> bool:
        runs.append(1)
        return td2adaptor.compile(child, use_cache=True).ok

    runs: list[int] = []
    assert td2adaptor.compile(child, use_cache=True).ok  # the inner entry exists before the outer one
    key = resultcache.key([str(child)], [], "outer")
    assert resultcache.cached(key, compile_child) is True
    assert resultcache.cached(key, compile_child) is True and len(runs) == 1
    parent.write_text("{ broken")
    assert resultcache.cached(key, compile_child) is False and len(runs) == 2
