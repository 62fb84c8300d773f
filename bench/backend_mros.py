"""mROS backend benchmarks (issue 4). Every figure comes with a baseline measured in the same run.

* Footprint (`arm-none-eabi-size` text/data/bss, Cortex-A9, -Os) of the generated RB-1 adaptor against a
  hand-written application doing the same job with the same message headers and pools
  (bench/mros/handwritten/; target <= 1.05x). Each side is its application objects plus a consumer of the
  latest values (bench/mros/user_generated.cpp, handwritten/user.cpp), the ros.cpp stand-in with the
  application's glue (tests/backends/mros/mros_api/mros_stub_lib.cpp) and mros_usr_config.c, merged with `ld -r` so that
  inline functions emitted by several objects count once (a real link does the same).
* Host encode/decode throughput of the generated message classes (bench/mros/throughput.cpp, g++ -O2)
  against rosbags' serialize_ros1/deserialize_ros1 on the same bytes (report only).

Needs g++ and the arm-none-eabi toolchain (.ci/setup-mros.sh). Run: .venv/bin/python bench/backend_mros.py
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import td2adaptor  # noqa: E402
from td2adaptor.backends.mros import generator as mros  # noqa: E402
from td2adaptor.backends.mros import lint as mros_lint  # noqa: E402
from td2adaptor.diagnostics import Diagnostics  # noqa: E402
from td2adaptor.generation.backend import GenOptions  # noqa: E402
from td2adaptor.model import ArrayKind, FieldType, TypeTable  # noqa: E402
from td2adaptor.rostypes.registry import TypeRegistry  # noqa: E402

EXAMPLE = REPO / "examples" / "robotnik_rb1"
API = REPO / "tests" / "backends" / "mros" / "mros_api"
HAND = REPO / "bench" / "mros" / "handwritten"
ARM = ["-mcpu=cortex-a9", "-marm", "-mfpu=vfpv3", "-mfloat-abi=hard", "-mno-unaligned-access", "-Os"]
ARM_CXX = ["arm-none-eabi-g++", "-std=gnu++98", *ARM, "-fno-exceptions", "-Wall", "-Wextra", "-Werror", "-Wno-psabi"]
ARM_CC = ["arm-none-eabi-gcc", "-std=gnu99", *ARM, "-Wall", "-Wextra", "-Werror"]
TYPES = {
    "Status": "robot_local_control_msgs/msg/Status",
    "AlvarMarkers": "ar_track_alvar_msgs/msg/AlvarMarkers",
    "Float64": "std_msgs/msg/Float64",
}


def run(cmd: list[str], stdin: str | None = None) -> str:
    proc = subprocess.run(cmd, input=stdin, capture_output=True, text=True, check=False)
    if proc.returncode:
        raise SystemExit(f"$ {' '.join(cmd)}\n{proc.stderr[-4000:]}")
    return proc.stdout


def generate(dest: Path) -> tuple[Path, Any]:
    """The RB-1 adaptor written under dest (with the kernel_cfg.h the TOPPERS configurator would make)."""
    result = td2adaptor.compile(EXAMPLE / "td.json", interfaces=[EXAMPLE / "interfaces"])
    assert result.model is not None
    # an mROS tree whose TCPROS buffers take the RB-1 types' headers (as pyproject.toml states)
    options = GenOptions(partial=True, extra=(("mros.tcpros_header_max", 8192),))
    tree = mros.generate(result.model, options, Diagnostics())
    for rel, data in tree:
        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
        (dest / rel).write_bytes(data)
    app = dest / result.model.package_name
    (app / "kernel_cfg.h").write_text(mros_lint.kernel_cfg_h((app / "app.cfg").read_text()))
    return app, result.model


def footprint(app: Path, work: Path) -> dict[str, tuple[int, int, int]]:
    """text/data/bss of the merged objects of the generated and the hand-written application."""
    (work / "hw").mkdir()
    (work / "gen").mkdir()
    (work / "hw" / "kernel_cfg.h").write_text(mros_lint.kernel_cfg_h((HAND / "app.cfg").read_text()))
    common = ["-I", str(app / "mros_config"), "-I", str(API)]
    variants = {
        "gen": (
            ["-I", str(app), "-I", str(app / "include"), *common],
            [app / "app.cpp", REPO / "bench" / "mros" / "user_generated.cpp", API / "mros_stub_lib.cpp"],
            app / "mros_config" / "mros_usr_config.c",
        ),
        "hw": (
            ["-I", str(work / "hw"), "-I", str(HAND), "-I", str(HAND / "include"), "-I", str(app / "include"), *common],
            [HAND / "app.cpp", HAND / "user.cpp", API / "mros_stub_lib.cpp"],
            HAND / "mros_config" / "mros_usr_config.c",
        ),
    }
    out = {}
    for name, (inc, sources, config) in variants.items():
        objs = []
        for src in sources:
            obj = work / name / (src.stem + ".o")
            run([*ARM_CXX, *inc, "-c", str(src), "-o", str(obj)])
            objs.append(obj)
        obj = work / name / "mros_usr_config.o"
        run([*ARM_CC, *inc, "-c", str(config), "-o", str(obj)])
        objs.append(obj)
        merged = work / name / "merged.o"
        run(["arm-none-eabi-ld", "-r", "-o", str(merged), *map(str, objs)])
        for label, path in (("all", merged), ("app", objs[0])):
            line = run(["arm-none-eabi-size", str(path)]).splitlines()[1].split()
            out[f"{name}-{label}"] = (int(line[0]), int(line[1]), int(line[2]))
    return out


# ---------------------------------------------------------------------------------------------------------
# throughput


def value(ts: Any, table: TypeTable, name: str, text: int, count: int) -> Any:
    """A rosbags message: strings of `text` characters, `count` elements in every variable array."""
    import numpy as np

    def field(ftype: FieldType) -> Any:
        def one() -> Any:
            if ftype.is_message:
                return value(ts, table, ftype.base, text, count)
            if ftype.base in ("time", "duration"):
                kind = "Time" if ftype.base == "time" else "Duration"
                return ts.types[f"builtin_interfaces/msg/{kind}"](sec=1700000000, nanosec=123456789)
            if ftype.base == "string":
                return "s" * text
            if ftype.base == "bool":
                return True
            return 1.25 if ftype.base.startswith("float") else 7

        n = 1 if ftype.array is ArrayKind.NONE else ftype.length if ftype.array is ArrayKind.FIXED else count
        if ftype.array is ArrayKind.NONE:
            return one()
        items = [one() for _ in range(n)]
        if ftype.is_message or ftype.base in ("string", "time", "duration"):
            return items
        dtype = {"bool": np.bool_, "float32": np.float32, "float64": np.float64}.get(ftype.base, np.int64)
        return np.array(items, dtype=dtype)

    msg = table.message(name)
    return ts.types[name](**{f.name: field(f.type) for f in msg.fields})


def rosbags_rates(ts: Any, name: str, msg: Any, raw: bytes, n: int) -> tuple[float, float]:
    t0 = time.perf_counter()
    for _ in range(n):
        ts.deserialize_ros1(raw, name)
    t1 = time.perf_counter()
    for _ in range(n):
        ts.serialize_ros1(msg, name)
    t2 = time.perf_counter()
    return n / (t1 - t0), n / (t2 - t1)


def throughput(app: Path, model: Any, work: Path) -> list[tuple[str, int, float, float, float, float]]:
    exe = work / "throughput"
    run(["g++", "-std=gnu++17", "-O2", "-I", str(app), "-I", str(app / "include"), "-I", str(API),
         str(REPO / "bench" / "mros" / "throughput.cpp"), "-o", str(exe)])  # fmt: skip
    ts = TypeRegistry("ros1", [EXAMPLE / "interfaces"]).typestore()
    cases = []
    for short, name in TYPES.items():
        shapes = [("", 12, 2)] if short == "Float64" else [(" typical", 12, 2), (" maximal", 64, 8)]
        for label, text, count in shapes:
            msg = value(ts, model.ros1, name, text, count)
            raw = bytes(ts.serialize_ros1(msg, name))
            cases.append((short + label, name, msg, raw))
    lines = "".join(f"{c[0].replace(' ', '_')} 200000 {c[3].hex()}\n" for c in cases)
    rows = []
    for case, reply in zip(cases, run([str(exe)], stdin=lines).splitlines(), strict=True):
        _, size, dec, enc, ok = reply.split()
        assert ok == "1", f"{case[0]}: the re-encoding differs from rosbags' bytes"
        rb_dec, rb_enc = rosbags_rates(ts, case[1], case[2], case[3], 3000)
        rows.append((case[0], int(size), float(dec), float(enc), rb_dec, rb_enc))
    return rows


def main() -> None:
    for tool in ("g++", "arm-none-eabi-g++", "arm-none-eabi-ld", "arm-none-eabi-size"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: run .ci/setup-mros.sh")
    print(f"python {sys.version.split()[0]}, {run(['arm-none-eabi-g++', '--version']).splitlines()[0]}")
    with tempfile.TemporaryDirectory(prefix="td2a-bench-mros-") as tmp:
        work = Path(tmp)
        app, model = generate(work / "out")
        sizes = footprint(app, work)
        print("\nfootprint, Cortex-A9 -Os, bytes      text     data      bss   total   ratio text  ratio total")
        for part, what in (("all", "adaptor+consumer+glue+pools"), ("app", "app.o only")):
            g, h = sizes[f"gen-{part}"], sizes[f"hw-{part}"]
            print(f"  {what}")
            print(f"    generated                   {g[0]:8} {g[1]:8} {g[2]:8} {sum(g):7}")
            print(
                f"    hand-written                {h[0]:8} {h[1]:8} {h[2]:8} {sum(h):7}"
                f"   {g[0] / h[0]:8.3f}x   {sum(g) / sum(h):8.3f}x" + ("   target <= 1.05x" if part == "all" else "")
            )
        print("\nhost throughput (messages/s)   bytes   generated C++ dec/enc        rosbags dec/enc        speed-up")
        for name, size, dec, enc, rb_dec, rb_enc in throughput(app, model, work):
            print(
                f"  {name:<24} {size:6}   {dec:12,.0f} {enc:12,.0f}   {rb_dec:10,.0f} {rb_enc:10,.0f}"
                f"   {dec / rb_dec:6.0f}x {enc / rb_enc:6.0f}x"
            )


if __name__ == "__main__":
    main()
