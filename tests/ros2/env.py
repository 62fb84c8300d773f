"""Process environment for real ROS 2 (Jazzy wheels in the venv): isolation and loading built prefixes.

Import this module before `rclpy.init()`. `isolate()` keeps DDS discovery on this host and gives this process a
private `ROS_DOMAIN_ID`, claimed with a lock file so that concurrent test workers (pytest-xdist, or another
test run on the same machine) never share a domain.
"""

from __future__ import annotations

import atexit
import ctypes
import fcntl
import importlib.util
import os
import sys
import tempfile
from pathlib import Path
from typing import IO

REPO = Path(__file__).resolve().parents[2]
VENV = Path(sys.prefix)
PY_DIR = f"python{sys.version_info.major}.{sys.version_info.minor}"

#: domain ids we may claim; Fast DDS allows 0..232, and low ids are what other ROS users pick
DOMAIN_RANGE = range(101, 232)

_claimed: tuple[int, IO[bytes]] | None = None
_loaded: set[Path] = set()


def ros2_available() -> bool:
    """Whether rclpy (the `ros2` pip extra) is installed in this interpreter's environment."""
    return importlib.util.find_spec("rclpy") is not None


def claim_domain_id() -> int:
    """A ROS_DOMAIN_ID no other live process of this machine's test runs holds (kept until exit)."""
    global _claimed
    if _claimed is None:
        _claimed = _claim()
    return _claimed[0]


def private_domain_id() -> int:
    """Another free ROS_DOMAIN_ID (kept until exit), for children that must not meet this process's robots."""
    return _claim()[0]


def _claim() -> tuple[int, IO[bytes]]:
    lock_dir = Path(tempfile.gettempdir()) / "td2adaptor-ros2-domains"
    lock_dir.mkdir(exist_ok=True)
    start = os.getpid() % len(DOMAIN_RANGE)
    for i in range(len(DOMAIN_RANGE)):
        domain = DOMAIN_RANGE[(start + i) % len(DOMAIN_RANGE)]
        fh = (lock_dir / f"{domain}.lock").open("wb")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            continue
        atexit.register(fh.close)
        return domain, fh
    raise RuntimeError(f"no free ROS_DOMAIN_ID in {DOMAIN_RANGE}")


def isolate() -> int:
    """Localhost-only discovery, Fast DDS, a private domain: set in os.environ, inherited by children."""
    domain = claim_domain_id()
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROS_STATIC_PEERS"] = ""
    os.environ["RMW_IMPLEMENTATION"] = "rmw_fastrtps_cpp"
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy, and it would log warnings
    profile = str(Path(__file__).with_name("fastdds.xml"))  # faster discovery of new participants
    os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = profile
    os.environ["FASTDDS_DEFAULT_PROFILES_FILE"] = profile
    return domain


def site_packages(prefix: Path) -> Path:
    return prefix / "lib" / PY_DIR / "site-packages"


def child_env(prefixes: list[Path], extra_pythonpath: list[Path] | None = None) -> dict[str, str]:
    """Environment for a child interpreter that imports what `prefixes` installed.

    The custom typesupport libraries are `dlopen`ed by bare name, so their directories must be on
    LD_LIBRARY_PATH when the process starts; the wheels' bootstrapper keeps existing entries.
    """
    env = dict(os.environ)
    libs = [str(p / "lib") for p in prefixes]
    env["LD_LIBRARY_PATH"] = os.pathsep.join([*libs, *filter(None, env.get("LD_LIBRARY_PATH", "").split(os.pathsep))])
    paths = [str(site_packages(p)) for p in prefixes] + [str(p) for p in extra_pythonpath or []] + [str(REPO)]
    env["PYTHONPATH"] = os.pathsep.join([*paths, *filter(None, env.get("PYTHONPATH", "").split(os.pathsep))])
    env["AMENT_PREFIX_PATH"] = os.pathsep.join([*map(str, prefixes), str(VENV)])
    env["PYTHONUNBUFFERED"] = "1"
    return env


def load_prefix(prefix: Path) -> None:
    """Make an install prefix usable in *this* process: its Python packages and its shared libraries.

    LD_LIBRARY_PATH cannot change after start-up, so every library is preloaded with RTLD_GLOBAL; the bare-name
    `dlopen` of the typesupport then finds the already loaded one.
    """
    prefix = prefix.resolve()
    if prefix in _loaded:
        return
    libs = sorted((prefix / "lib").glob("lib*.so"))
    pending = list(libs)
    # Load in dependency order without knowing it: retry what failed until nothing changes.
    while pending:
        failed: list[Path] = []
        for lib in pending:
            try:
                ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
            except OSError:
                failed.append(lib)
        if len(failed) == len(pending):
            raise OSError(f"cannot load {[str(f) for f in failed]}")
        pending = failed
    path = str(site_packages(prefix))
    if path not in sys.path:
        sys.path.insert(0, path)
    _loaded.add(prefix)
