"""The forked JSON-LD stage: same diagnostics as in-process, and every failure falls back to the parent."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

from tests.conftest import EXAMPLE, REPO

CLI = str(Path(sys.executable).parent / "td2adaptor")


def _py(code: str) -> str:
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=60, cwd=REPO
    )
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.strip()


def test_runs_in_a_child_and_falls_back_on_failure() -> None:
    out = _py(
        """
        import os
        from td2adaptor.compiler.background import Background
        parent = os.getpid()
        print(Background(os.getpid).result() != parent)            # computed in a forked child
        print(Background(os.getpid, enabled=False).result() == parent)
        calls = []
        def flaky():
            calls.append(os.getpid())
            if os.getpid() != parent:
                raise RuntimeError("only in the child")
            return "parent"
        print(Background(flaky).result(), calls == [parent])       # child failed: recomputed here
        job = Background(lambda: __import__("time").sleep(30))
        job.cancel()                                                # no 30 s wait, child reaped
        print("cancelled")
        """
    )
    assert out.splitlines() == ["True", "True", "parent True", "cancelled"]


def _validate(path: Path, *, fork: bool) -> dict[str, object]:
    env = {**os.environ, "TD2ADAPTOR_NO_CACHE": "1"}
    if not fork:
        env["TD2ADAPTOR_NO_FORK"] = "1"
    proc = subprocess.run(
        [CLI, "validate", str(path), "-I", str(EXAMPLE / "interfaces"), "--format", "json"],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    result: dict[str, object] = json.loads(proc.stdout)
    return result


def test_cli_output_is_the_same_with_and_without_the_fork(tmp_path: Path) -> None:
    td = json.loads((EXAMPLE / "td.json").read_text())
    td["@context"].append("https://example.org/not/bundled")  # a JSON-LD stage warning (TD251)
    remote = tmp_path / "remote-context.json"
    remote.write_text(json.dumps(td))
    for path in (EXAMPLE / "td.reference-dialect.json", remote):
        forked, inline = _validate(path, fork=True), _validate(path, fork=False)
        assert forked == inline
    assert any(d["code"] == "TD251" for d in forked["diagnostics"])  # type: ignore[union-attr,index]
