"""Compiling generated mROS applications: host g++ (C++98 syntax, the harnesses) and arm-none-eabi-g++.

Builds that several tests need run once per test session and are shared between xdist workers: each is
keyed by a hash of its inputs, built under a lock in a directory common to the session's workers.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

HERE = Path(__file__).resolve().parent
API = HERE / "mros_api"

HOST_CXX = "g++"
ARM_CXX = "arm-none-eabi-g++"
ARM_CC = "arm-none-eabi-gcc"
#: the flags of the issue: C++98 as mROS's toolchain defaults to, every warning an error
#: what mROS's Makefile.m defines for every build (ROS_WARN compiles to nothing)
MROS_CDEFS = ["-DMROS_LOG_DISABLE_WARN"]
HOST_SYNTAX = [*MROS_CDEFS, "-std=gnu++98", "-Wall", "-Wextra", "-Werror", "-fsyntax-only"]
ARM_CPU = ["-mcpu=cortex-a9", "-marm", "-mfpu=vfpv3", "-mfloat-abi=hard", "-mno-unaligned-access"]
ARM_CXXFLAGS = [
    *MROS_CDEFS,
    "-std=gnu++98",
    *ARM_CPU,
    "-Os",
    "-fno-exceptions",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-Wno-psabi",  # GCC's note that a 2017 ABI change affects some std::vector iterators: information only
]
ARM_CFLAGS = ["-std=gnu99", *ARM_CPU, "-Os", "-Wall", "-Wextra", "-Werror"]


def have(tool: str) -> bool:
    return shutil.which(tool) is not None


def includes(app: Path) -> list[str]:
    return ["-I", str(app), "-I", str(app / "include"), "-I", str(app / "mros_config"), "-I", str(API)]


def run(cmd: Sequence[str], cwd: Path | None = None, stdin: str | None = None, timeout: float = 300) -> str:
    """Run a command; a failure shows the command and its output."""
    proc = subprocess.run(list(cmd), cwd=cwd, input=stdin, capture_output=True, text=True, timeout=timeout, check=False)
    assert proc.returncode == 0, f"$ {' '.join(cmd)}\n{proc.stdout[-4000:]}\n{proc.stderr[-8000:]}"
    return proc.stdout


def digest(paths: Iterable[Path], *extra: str) -> str:
    h = hashlib.sha256()
    for path in sorted(paths):
        h.update(str(path.name).encode())
        h.update(path.read_bytes())
    for e in extra:
        h.update(e.encode())
    return h.hexdigest()[:16]


def shared(root: Path, key: str, build: Callable[[Path], None]) -> Path:
    """`root/key`, built once by `build(dir)` whichever worker gets there first (a lock file serialises)."""
    root.mkdir(parents=True, exist_ok=True)
    target = root / key
    with open(root / f"{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (target / ".done").exists():
            if target.exists():
                shutil.rmtree(target)
            target.mkdir()
            build(target)
            (target / ".done").write_text("ok")
    return target


def app_sources(app: Path) -> list[Path]:
    return sorted(p for p in app.rglob("*") if p.is_file() and p.suffix in (".h", ".cpp", ".c", ".cfg"))


def host_objects(app: Path, out: Path, extra_cxx: Sequence[str] = (), defines: Sequence[str] = ()) -> list[Path]:
    """The application, the ros.cpp stand-in, the loopback bus and mros_usr_config.c as host objects."""
    out.mkdir(parents=True, exist_ok=True)
    cxx = [HOST_CXX, *MROS_CDEFS, "-std=gnu++98", "-g", "-O1", "-Wall", "-Wextra", "-Werror", *defines, *includes(app)]
    objs = []
    for src in [app / "app.cpp", API / "mros_stub_lib.cpp", API / "mros_stub_bus.cpp", *map(Path, extra_cxx)]:
        obj = out / (src.stem + ".o")
        run([*cxx, "-c", str(src), "-o", str(obj)])
        objs.append(obj)
    obj = out / "mros_usr_config.o"
    run(
        [
            "gcc",
            "-std=gnu99",
            "-Wall",
            "-Wextra",
            "-Werror",
            *includes(app),
            "-c",
            str(app / "mros_config" / "mros_usr_config.c"),
            "-o",
            str(obj),
        ]
    )
    objs.append(obj)
    return objs


def arm_objects(app: Path, out: Path, sources: Sequence[Path] | None = None) -> list[Path]:
    """Cortex-A9 objects of the application, the ros.cpp stand-in and mros_usr_config.c."""
    out.mkdir(parents=True, exist_ok=True)
    objs = []
    cxx_sources = list(sources) if sources is not None else [app / "app.cpp", API / "mros_stub_lib.cpp"]
    for src in cxx_sources:
        obj = out / (src.stem + ".arm.o")
        run([ARM_CXX, *ARM_CXXFLAGS, *includes(app), "-c", str(src), "-o", str(obj)])
        objs.append(obj)
    obj = out / "mros_usr_config.arm.o"
    run([ARM_CC, *ARM_CFLAGS, *includes(app), "-c", str(app / "mros_config" / "mros_usr_config.c"), "-o", str(obj)])
    objs.append(obj)
    return objs


def size(objs: Sequence[Path]) -> dict[str, tuple[int, int, int]]:
    """arm-none-eabi-size per object: (text, data, bss)."""
    out = run(["arm-none-eabi-size", *map(str, objs)])
    rows = {}
    for line in out.splitlines()[1:]:
        text, data, bss, _dec, _hex, name = line.split(None, 5)
        rows[name] = (int(text), int(data), int(bss))
    return rows


def nm(obj: Path, *flags: str) -> list[str]:
    return run(["arm-none-eabi-nm", "-C", *flags, str(obj)]).splitlines()


def worker_count() -> int:
    return int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
