"""`gen` grows with the TD, not faster (issue 34: 13.5x the time for 10x the affordances).

Two causes, each checked here without timing anything (this suite runs on loaded machines):
* the events backend looked every reply event up by scanning all events (`EventCatalog.find`): quadratic;
* the garbage collector walked the whole, ever larger, heap again and again while `gen` built it: the CLI's
  one-shot commands now run with it paused (`support.gcpause`).
`bench/startup_scale.py` measures the growth itself.
"""

from __future__ import annotations

import gc
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from td2adaptor.cli.main import cli
from td2adaptor.compiler.pipeline import compile
from td2adaptor.model.events import EventCatalog, Kind, build_catalog
from td2adaptor.support.gcpause import collector_paused
from tests.conftest import EXAMPLE


def _td(n: int) -> dict[str, Any]:
    """N affordances alike (half services, half topics), as bench/synth.py makes them."""
    actions, properties = {}, {}
    for i in range(n):
        form = {"href": f"ros:x/{i}", "rosv:name": f"/{{{{robotName}}}}/x{i}", "op": "invokeaction"}
        if i % 2 == 0:
            form = {**form, "rosv:type": "std_srvs/srv/Trigger"}
            actions[f"a{i}"] = {"rosv:component": f"C{i // 4}", "forms": [form]}
        else:
            form = {**form, "op": ["readproperty", "observeproperty"], "rosv:type": "std_msgs/msg/Float64"}
            properties[f"p{i}"] = {"rosv:component": f"C{i // 4}", "observable": True, "readOnly": True}
            properties[f"p{i}"]["forms"] = [form]
    return {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "title": f"Synthetic {n}",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "properties": properties,
        "actions": actions,
    }


class _Counted(tuple):  # type: ignore[type-arg]
    """A tuple that counts the items handed out by iterating it."""

    visits = 0

    def __iter__(self) -> Iterator[Any]:
        for item in super().__iter__():
            _Counted.visits += 1
            yield item


def test_finding_an_event_does_not_scan_the_catalog(tmp_path: Path) -> None:
    path = tmp_path / "td.json"
    path.write_text(json.dumps(_td(200)))
    model = compile(str(path)).model
    assert model is not None
    built = build_catalog(model)
    catalog = EventCatalog(built.package, _Counted(built.specs), built.envelope, built.distro)
    _Counted.visits = 0
    for spec in built.specs:
        assert catalog.find(spec.kind, spec.affordance).kind is spec.kind
    # once through to index them, not once per lookup (that was 1,500 x 1,500 / 2 for 1,000 affordances)
    assert _Counted.visits <= len(built.specs)
    with pytest.raises(StopIteration):  # as before: callers catch StopIteration for an unknown affordance
        catalog.find(Kind.INVOKE, "no_such_action")


def _watch(monkeypatch: pytest.MonkeyPatch, module: Any, name: str) -> list[str]:
    """Wrap `module.name` (the command's work): what happened meanwhile, `enabled` if the collector was on when
    the work began and `collected N` for each collection that ran during it (none is asked for explicitly)."""
    seen: list[str] = []
    real = getattr(module, name)
    running = [False]

    def callback(phase: str, info: dict[str, int]) -> None:
        if phase == "start" and running[0]:
            seen.append(f"collected {info['generation']}")

    def work(*args: Any, **kwargs: Any) -> Any:
        if gc.isenabled():
            seen.append("enabled")
        running[0] = True
        try:
            return real(*args, **kwargs)
        finally:
            running[0] = False

    monkeypatch.setattr(module, name, work)
    gc.callbacks.append(callback)
    monkeypatch.setattr(gc, "callbacks", gc.callbacks)  # restored list object; the callback is removed below
    return seen


@pytest.fixture
def watch(monkeypatch: pytest.MonkeyPatch) -> Iterator[Any]:
    before = list(gc.callbacks)
    yield lambda module, name: _watch(monkeypatch, module, name)
    gc.callbacks[:] = before


def test_gen_runs_without_the_collector(tmp_path: Path, watch: Any) -> None:
    from td2adaptor.compiler import build

    seen = watch(build, "generate")
    (tmp_path / "td.json").write_text(json.dumps(_td(400)))
    args = ["gen", str(tmp_path / "td.json"), "-o", str(tmp_path / "out"), "--partial", "--no-cache"]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert (tmp_path / "out" / "events").is_dir()
    assert seen == []
    assert gc.isenabled()  # and it is back on after the command


def test_validate_runs_without_the_collector(watch: Any) -> None:
    from td2adaptor.cli import frontend

    seen = watch(frontend, "_compile_units")
    args = ["validate", str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces"), "--no-cache"]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert seen == []
    assert gc.isenabled()


def test_the_pause_leaves_a_disabled_collector_disabled() -> None:
    gc.disable()
    try:
        with collector_paused():
            assert not gc.isenabled()
        assert not gc.isenabled()
    finally:
        gc.enable()
    with collector_paused():
        assert not gc.isenabled()
    assert gc.isenabled()
