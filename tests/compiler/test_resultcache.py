"""The compile result cache: hits give the same answer, any relevant change is a miss."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import td2adaptor
from td2adaptor.compiler.pipeline import Result
from tests.conftest import EXAMPLE


@pytest.fixture
def work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("TD2ADAPTOR_CACHE_DIR", str(tmp_path / "cache"))
    shutil.copytree(EXAMPLE, tmp_path / "rb1", ignore=shutil.ignore_patterns("sim"))
    return tmp_path / "rb1"


def _compile(path: Path, work: Path) -> Result:
    return td2adaptor.compile(path, interfaces=[work / "interfaces"], use_cache=True)


def _entries(work: Path) -> int:
    return len(list((work.parent / "cache" / "results").glob("*.pickle")))


def test_hit_equals_fresh_result(work: Path) -> None:
    first = _compile(work / "td.reference-dialect.json", work)
    assert _entries(work) == 1
    second = _compile(work / "td.reference-dialect.json", work)
    assert second.model == first.model and second.diagnostics == first.diagnostics
    assert second.input is None  # answered from the cache
    assert _entries(work) == 1


def test_a_hit_without_need_model_gives_the_diagnostics_and_loads_no_model(work: Path) -> None:
    """`validate` only reports: its hits leave the model (and its classes) unloaded (start-up time, issue 17)."""
    first = _compile(work / "td.json", work)
    probe = (
        "import sys, td2adaptor\n"
        f"r = td2adaptor.compile({str(work / 'td.json')!r}, interfaces=[{str(work / 'interfaces')!r}], "
        "use_cache=True, need_model=False)\n"
        "print(r.model is None, r.input is None, 'td2adaptor.model' in sys.modules, len(r.diagnostics))"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", "True", "False", str(len(first.diagnostics))]
    hit = td2adaptor.compile(work / "td.json", interfaces=[work / "interfaces"], use_cache=True, need_model=False)
    assert hit.model is None and hit.diagnostics == first.diagnostics
    assert _compile(work / "td.json", work).model == first.model  # the model is still there for those who need it


def test_changed_td_or_interface_is_a_miss(work: Path) -> None:
    assert _compile(work / "td.json", work).ok
    td = json.loads((work / "td.json").read_text())
    td["actions"]["gotoRun"]["forms"][0]["rosv:type"] = "robot_local_control_msgs/srv/Nope"
    (work / "td.json").write_text(json.dumps(td))
    assert not _compile(work / "td.json", work).ok
    td["actions"]["gotoRun"]["forms"][0]["rosv:type"] = "robot_local_control_msgs/srv/GoToPetition"
    (work / "td.json").write_text(json.dumps(td))
    assert _compile(work / "td.json", work).ok
    srv = work / "interfaces" / "robot_local_control_msgs" / "srv" / "GoToPetition.srv"
    srv.write_text("this is not a definition\n---\n")
    assert not _compile(work / "td.json", work).ok


def test_files_found_while_compiling_are_dependencies(work: Path) -> None:
    parent = work / "parent.tm.json"
    parent.write_text(
        json.dumps(
            {
                "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
                "@type": "tm:ThingModel",
                "title": "Parent",
                "properties": {
                    "p": {
                        "type": "number",
                        "forms": [{"href": "ros:p", "rosv:name": "/p", "rosv:type": "std_msgs/msg/Float64"}],
                    }
                },
            }
        )
    )
    child = work / "child.tm.json"
    child.write_text(
        json.dumps(
            {
                "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
                "@type": "tm:ThingModel",
                "title": "Child",
                "links": [{"rel": "tm:extends", "href": "./parent.tm.json", "type": "application/tm+json"}],
            }
        )
    )
    assert _compile(child, work).ok
    parent.write_text("{ broken")
    again = _compile(child, work)
    assert not again.ok and any(d.file and "parent" in d.file for d in again.diagnostics)


def test_cache_can_be_disabled(work: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TD2ADAPTOR_NO_CACHE", "1")
    assert _compile(work / "td.json", work).input is not None
    assert not (work.parent / "cache").exists()


def test_a_hit_names_interface_files_as_this_run_spells_them(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    iface = tmp_path / "ifaces"
    (iface / "demo_msgs" / "msg").mkdir(parents=True)
    (iface / "demo_msgs" / "msg" / "Broken.msg").write_text("int32\n")
    td = tmp_path / "td.json"
    td.write_text((EXAMPLE / "td.json").read_text())
    monkeypatch.chdir(tmp_path)
    interfaces = [str(EXAMPLE / "interfaces")]
    first = td2adaptor.compile("td.json", interfaces=[*interfaces, "ifaces"], use_cache=True)
    again = td2adaptor.compile("td.json", interfaces=[*interfaces, str(iface)], use_cache=True)
    files = [{d.file for d in r.diagnostics if d.code == "TY510"} for r in (first, again)]
    assert files == [{"ifaces/demo_msgs/msg/Broken.msg"}, {str(iface / "demo_msgs" / "msg" / "Broken.msg")}]
