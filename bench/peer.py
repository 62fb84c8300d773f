"""td2adaptor next to a peer generator (issue 3): datamodel-code-generator turning the same TD's data
schemas into pydantic models, versus `td2adaptor gen` of the rclpy and rospy packages. Cold CLI both, same
run; the ratio is reported, not targeted (the two produce different things: data models vs ROS clients).
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "robotnik_rb1"
BIN = Path(sys.executable).parent
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
SCHEMA_ONLY = {
    "title",
    "titles",
    "description",
    "descriptions",
    "forms",
    "observable",
    "rosv:component",
    "rosv:procedure",
}


def td_schemas(td: dict[str, object]) -> dict[str, object]:
    """Every data schema of the TD (action input/output, property schemas) as $defs of one JSON Schema."""
    defs: dict[str, object] = {}
    for name, aff in td.get("actions", {}).items():  # type: ignore[union-attr]
        for key in ("input", "output"):
            if key in aff:
                defs[f"{name}_{key}"] = aff[key]
    for name, aff in td.get("properties", {}).items():  # type: ignore[union-attr]
        defs[name] = {k: v for k, v in aff.items() if k not in SCHEMA_ONLY}
    return {
        "$schema": "http://json-schema.org/draft-07/schema#",
        "title": "RB1",
        "type": "object",
        "properties": {k: {"$ref": f"#/definitions/{k}"} for k in defs},
        "definitions": defs,
    }


def median_run(cmd: list[str], cwd: Path, runs: int = 5, before: object = None) -> float:
    times = []
    for _ in range(runs):
        if callable(before):
            before()
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=cwd, capture_output=True, env=ENV, check=False)
        times.append(time.perf_counter() - t0)
        if proc.returncode != 0:
            raise SystemExit(f"{cmd[0]} failed: {proc.stderr.decode()[-500:]}")
    return statistics.median(times)


def main() -> None:
    peer = BIN / "datamodel-codegen"
    if not peer.exists():
        print("datamodel-code-generator not installed: .venv/bin/pip install -e '.[bench]'")
        return
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        schema = work / "rb1.schema.json"
        schema.write_text(json.dumps(td_schemas(json.loads((EXAMPLE / "td.json").read_text()))))
        out = work / "models.py"
        t_peer = median_run(
            [
                str(peer),
                "--input",
                str(schema),
                "--input-file-type",
                "jsonschema",
                "--output-model-type",
                "pydantic_v2.BaseModel",
                "--output",
                str(out),
            ],
            work,
        )
        gen_out = work / "gen"
        cmd = [
            str(BIN / "td2adaptor"),
            "gen",
            str(EXAMPLE / "td.json"),
            "-I",
            str(EXAMPLE / "interfaces"),
            "-b",
            "rclpy",
            "-b",
            "rospy",
            "-o",
            str(gen_out),
        ]
        t_ours = median_run(cmd, work, before=lambda: shutil.rmtree(gen_out, ignore_errors=True))
        lines = len(out.read_text().splitlines())
        print(f"datamodel-codegen, RB-1 data schemas -> pydantic ({lines} lines)  {t_peer * 1000:8.1f} ms")
        print(
            f"td2adaptor gen rclpy+rospy, RB-1, fresh output dir         {t_ours * 1000:8.1f} ms"
            f"   ratio ours/peer {t_ours / t_peer:5.2f}   target (gen cold) <= 500 ms"
        )


if __name__ == "__main__":
    main()
