"""Hostile sizes: bounded time and memory, a clear diagnostic, no traceback (issue 6)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

CLI = str(Path(sys.executable).parent / "td2adaptor")
ENV = {**os.environ, "TD2ADAPTOR_NO_CACHE": "1"}


#: peak resident memory any hostile input may cost the CLI (the 100,000-affordance TD needs ~115 MB)
MAX_RSS_MB = 400


def _validate(path: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    """Run `validate` and check its peak memory (from the child's own rusage, via wait4)."""
    with open(path.with_suffix(".stderr"), "w+") as err:
        child = subprocess.Popen(  # noqa: S603 - our own CLI
            [CLI, "validate", str(path), *extra], stdout=subprocess.DEVNULL, stderr=err, text=True, env=ENV
        )
        watchdog = threading.Timer(120, child.kill)  # bounded time: a hang fails the test, it does not stall CI
        watchdog.start()
        try:
            _, status, usage = os.wait4(child.pid, 0)
        finally:
            watchdog.cancel()
        child.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        stderr = err.read()
    assert usage.ru_maxrss / 1024 < MAX_RSS_MB, f"{path.name}: {usage.ru_maxrss // 1024} MB"
    return subprocess.CompletedProcess(child.args, child.returncode, "", stderr)


def test_50_megabyte_td_is_refused_quickly(tmp_path: Path) -> None:
    big = tmp_path / "big.json"
    with big.open("w") as fh:
        fh.write('{"title": "big", "description": "')
        chunk = "x" * (1 << 20)
        for _ in range(50):
            fh.write(chunk)
        fh.write('"}')
    proc = _validate(big)
    assert proc.returncode == 1 and "TD006" in proc.stderr and "Traceback" not in proc.stderr
    assert "--max-bytes" in proc.stderr


def test_deep_nesting_is_refused(tmp_path: Path) -> None:
    for depth in (150, 10_000):
        deep = tmp_path / f"deep{depth}.json"
        deep.write_text('{"title": "d", "x": ' + "[" * depth + "]" * depth + "}")
        proc = _validate(deep)
        assert proc.returncode == 1 and "TD007" in proc.stderr and "Traceback" not in proc.stderr


def test_100000_affordances_are_refused_with_a_limit(tmp_path: Path) -> None:
    props = {f"p{i}": {"type": "number", "forms": [{"href": f"ros:p{i}"}]} for i in range(100_000)}
    many = tmp_path / "many.json"
    many.write_text(json.dumps({"title": "many", "properties": props}))
    proc = _validate(many)
    assert proc.returncode == 1 and "TD010" in proc.stderr and "--max-affordances" in proc.stderr
    small = tmp_path / "small.json"
    small.write_text(json.dumps({"title": "small", "properties": dict(list(props.items())[:50])}))
    proc = _validate(small, "--max-affordances", "10")
    assert proc.returncode == 1 and "more than the limit of 10" in proc.stderr


def test_unpaired_surrogates_in_rb1_text_are_refused_by_gen(tmp_path: Path) -> None:
    # `\ud800` in a title used to reach the backends and crash the UTF-8 write (exit 3, internal error)
    td = json.loads((Path(__file__).parents[2] / "examples/robotnik_rb1/td.json").read_text())
    td["title"] = "RB-1 \ud800"
    td["actions"]["gotoRun"]["description"] = "go \udfff there"
    (tmp_path / "td.json").write_text(json.dumps(td))  # ensure_ascii: written as \ud800 escapes
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "keep.txt").write_text("mine")
    interfaces = str(Path(__file__).parents[2] / "examples/robotnik_rb1/interfaces")
    proc = subprocess.run(
        [CLI, "gen", "td.json", "-o", "out", "-I", interfaces, "--partial"],
        capture_output=True, text=True, timeout=120, env=ENV, cwd=tmp_path,
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.count("TD011") == 2 and "/title" in proc.stderr and "Traceback" not in proc.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["keep.txt"]
