"""A real mROS v1.3 tree for the tests: found through MROS_ROOT, copied, built with its own makefiles.

The tree (upstream mROS at v1.3 with its ASP/Mbed submodule) is test material beside the repository, never
part of it: `MROS_ROOT` names it, by default `../shared/mros/mROS-1.3`; without it the tests skip. It lacks
the TOPPERS configurator binary its makefiles call (`asp_mbed/cfg_binary/cfg-linux-static-1_9_6`): that is
built from the configurator's source in the tree with Debian's Boost, once, and cached under `.cache/` by
the hash of its sources. Applications are built in a copy of the tree (the makefiles write objects into it),
serially (`make`, as the generated README says).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path

from tests.backends.mros import build
from tests.conftest import REPO

DEFAULT_ROOT = REPO.parent / "shared" / "mros" / "mROS-1.3"
CFG_SOURCE = "asp_mbed/asp-gr_peach_gcc-mbed/asp-1.9.2-utf8/cfg"
CFG_BINARY = "asp_mbed/cfg_binary/cfg-linux-static-1_9_6"
PACKET_CONFIG = "mros-lib/mros-src/packet/cimpl/version/kinetic/mros_packet_config.h"
CACHE = REPO / ".cache" / "mros-cfg"
#: serially (its top Makefile races under -j); Boost >= 1.67 no longer pulls in next/prior where its source
#: expects them
CFG_MAKE = ["make", "OPTIMIZE=-O1 -std=gnu++11 -w -include boost/next_prior.hpp"]
BOOST_HEADER = Path("/usr/include/boost/program_options.hpp")


def root() -> Path:
    return Path(os.environ.get("MROS_ROOT", str(DEFAULT_ROOT)))


def tree_problem() -> str | None:
    """Why there is no real mROS tree (reference material beside the repository: a skip, not a failure)."""
    tree = root()
    if not (tree / "mros-lib" / "mros-src" / "api" / "ros.cpp").is_file():
        return f"no mROS v1.3 tree at {tree} (set MROS_ROOT)"
    return None


def problem() -> str | None:
    """Why the real-tree builds cannot run here with a tree (None when they can): the tools CI installs."""
    missing = [t for t in ("make", "g++", "arm-none-eabi-g++", "arm-none-eabi-size") if shutil.which(t) is None]
    if missing:
        return f"{', '.join(missing)} not installed (.ci/setup-mros.sh)"
    libstdcxx = subprocess.run(
        ["arm-none-eabi-g++", "-mcpu=cortex-a9", "-mfloat-abi=hard", "-print-file-name=libstdc++.a"],
        capture_output=True,
        text=True,
        check=False,
    ).stdout.strip()
    if not os.path.isabs(libstdcxx):
        return "newlib's libstdc++ for arm-none-eabi is not installed (.ci/setup-mros.sh)"
    if not BOOST_HEADER.is_file() and not any(CACHE.glob("*/cfg")):
        return "Boost headers are not installed (.ci/setup-mros.sh), needed to build the TOPPERS configurator"
    return None


def _source_key(source: Path) -> str:
    h = hashlib.sha256()
    for path in sorted(p for p in source.rglob("*") if p.is_file()):
        h.update(path.relative_to(source).as_posix().encode())
        h.update(path.read_bytes())
    h.update(subprocess.run(["g++", "--version"], capture_output=True, text=True, check=True).stdout.encode())
    return h.hexdigest()[:16]


def configurator() -> Path:
    """The TOPPERS configurator built from the tree's source (cached in .cache/mros-cfg/<hash>/cfg)."""
    source = root() / CFG_SOURCE

    def make(out: Path) -> None:
        work = out / "src"
        shutil.copytree(source, work)
        build.run(["sh", "configure", "--without-xml"], cwd=work, timeout=300)
        build.run(CFG_MAKE, cwd=work, timeout=1200)
        shutil.copy2(work / "cfg" / "cfg", out / "cfg")
        shutil.rmtree(work)

    return build.shared(CACHE, _source_key(source), make) / "cfg"


def tree_copy(dest: Path, tcpros_max: int) -> Path:
    """A copy of the tree with the configurator in place and its TCPROS buffers raised to `tcpros_max` (what
    the generated applications state with mros.tcpros_header_max)."""
    shutil.copytree(root(), dest, ignore=shutil.ignore_patterns(".git"))
    binary = dest / CFG_BINARY
    binary.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy2(configurator(), binary)
    config = dest / PACKET_CONFIG
    text = config.read_text()
    for side in ("REQ", "RES"):
        line = f"#define MROS_PACKET_MAXSIZE_{side}_TCPROS"
        start = text.index(line)
        end = text.index("\n", start)
        text = text[:start] + f"{line}\t\t\t\t\t{tcpros_max}" + text[end:]
    config.write_text(text)
    return dest


def make(app: Path, *args: str, timeout: float = 900) -> str:
    """`make` in an application directory of a tree copy (serially, as the README says); the output."""
    proc = subprocess.run(["make", *args], cwd=app, capture_output=True, text=True, timeout=timeout, check=False)
    assert proc.returncode == 0, f"make in {app} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-6000:]}"
    return proc.stdout + proc.stderr


def image_size(elf: Path) -> tuple[int, int, int]:
    """(text, data, bss) of a linked image (arm-none-eabi-size)."""
    line = build.run(["arm-none-eabi-size", str(elf)]).splitlines()[1]
    text, data, bss = (int(v) for v in line.split()[:3])
    return text, data, bss
