"""Build ROS 2 packages with the PyPI wheels: interface packages (CMake) and generated adaptors (colcon).

Used by the tests (tests/ros2/build.py re-exports it with the repository's paths) and by
`td2adaptor demo warehouse`, which builds the RB-1 interfaces it needs on first use.

The RB-1 definitions in examples/robotnik_rb1/interfaces are written in ROS 1 syntax (`Header`, `time`,
unquoted string constants), because the ROS 1 MD5 tests pin them. rosidl's .msg adapter accepts unquoted
string constants but resolves a bare `Header` inside the package itself and has no `time`, so the build step
translates a copy: `Header` → `std_msgs/Header`, `time` → `builtin_interfaces/Time`, `duration` →
`builtin_interfaces/Duration`, constants quoted. A CMakeLists.txt calling `rosidl_generate_interfaces` is
written next to each package's own package.xml, and colcon (colcon-ros, ament_cmake) builds all four in
dependency order into one prefix.

The result is cached in `<cache>/<hash>` (hash of the definitions, this file and the Python version) and
built once, under a file lock, however many processes ask at once. It needs the `ros2` extra (the ROS 2
wheels with their build tools, colcon) in this interpreter's environment, and cmake, ninja and a C compiler.

    python -m td2adaptor.support.ros2build INTERFACES CACHE   # build (or find) the interfaces, print the prefix
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

VENV = Path(sys.prefix)
PY_DIR = f"python{sys.version_info.major}.{sys.version_info.minor}"

_TYPE_MAP = {"Header": "std_msgs/Header", "time": "builtin_interfaces/Time", "duration": "builtin_interfaces/Duration"}
_FIELD = re.compile(r"^(?P<type>[A-Za-z][A-Za-z0-9_/]*)(?P<array>\[[^\]]*\])?(?P<rest>\s+.*)$")
_CONST = re.compile(r"^(?P<type>string)\s+(?P<name>[A-Za-z][A-Za-z0-9_]*)\s*=(?P<value>.*)$")


def translate_line(line: str) -> str:
    """One line of a ROS 1 .msg/.srv in ROS 2 syntax (comments and blank lines kept)."""
    stripped = line.strip()
    if not stripped or stripped.startswith("#") or stripped == "---":
        return line
    const = _CONST.match(stripped)
    if const:
        # ROS 1: a string constant's value is the rest of the line, '#' included, whitespace trimmed.
        value = const["value"].strip().replace("\\", "\\\\").replace('"', '\\"')
        return f'{const["type"]} {const["name"]}="{value}"'
    field = _FIELD.match(stripped)
    if not field:
        return line
    base = _TYPE_MAP.get(field["type"], field["type"])
    return f"{base}{field['array'] or ''}{field['rest']}"


def translate(text: str) -> str:
    return "\n".join(translate_line(line) for line in text.splitlines()) + "\n"


def referenced_packages(text: str, own: str) -> set[str]:
    """Interface packages a translated definition refers to (besides its own)."""
    found = set()
    for line in text.splitlines():
        stripped = line.split("#", 1)[0].strip()
        field = _FIELD.match(stripped) if stripped and stripped != "---" else None
        if field and "/" in field["type"]:
            found.add(field["type"].split("/", 1)[0])
    return found - {own}


_GENERATORS = (
    "rosidl_cmake",
    "rosidl_generator_type_description",
    "rosidl_generator_c",
    "rosidl_typesupport_fastrtps_c",
    "rosidl_typesupport_introspection_c",
    "rosidl_typesupport_c",
    "rosidl_generator_py",
)


def _cmakelists(package: str, files: list[str], deps: list[str]) -> str:
    lines = [
        "cmake_minimum_required(VERSION 3.8)",
        f"project({package})",
        "find_package(ament_cmake REQUIRED)",
        # rclpy needs only the C and Python generators; skipping the C++ ones halves the build time
        *(f"find_package({g} REQUIRED)" for g in _GENERATORS),
        *(f"find_package({d} REQUIRED)" for d in deps),
        # dependencies (std_msgs, ...) bring the C++ generators back in: drop them again
        'list(FILTER AMENT_EXTENSIONS_rosidl_generate_idl_interfaces EXCLUDE REGEX "_cpp:")',
        "rosidl_generate_interfaces(${PROJECT_NAME}",
        *(f'  "{f}"' for f in files),
        *([f"  DEPENDENCIES {' '.join(deps)}"] if deps else []),
        ")",
        "ament_export_dependencies(rosidl_default_runtime)",
        "ament_package()",
    ]
    return "\n".join(lines) + "\n"


class BuildError(Exception):
    """The interfaces cannot be built; the message says why (one line for the user)."""


def packages_in(src: Path) -> list[Path]:
    """The interface packages `src` holds: its subfolders with a package.xml, or `src` itself when it is one."""
    if (src / "package.xml").is_file():
        return [src]
    if not src.is_dir():
        raise BuildError(f"{src} is not a folder")
    found = sorted(p for p in src.iterdir() if (p / "package.xml").is_file())
    if not found:
        raise BuildError(
            f"no interface package in {src}: a package is a folder with a package.xml and msg/, srv/ or action/"
        )
    return found


def prepare_sources(src: Path, dest: Path) -> list[str]:
    """Copy every interface package under `src` to `dest`, translated, with a CMakeLists.txt; their names."""
    names = []
    for pkg_dir in packages_in(src):
        package = pkg_dir.name
        out = dest / package
        out.mkdir(parents=True)
        shutil.copy2(pkg_dir / "package.xml", out / "package.xml")
        files: list[str] = []
        deps: set[str] = set()
        for kind in ("msg", "srv", "action"):
            for f in sorted((pkg_dir / kind).glob(f"*.{kind}")):
                text = translate(f.read_text(encoding="utf-8"))
                (out / kind).mkdir(exist_ok=True)
                (out / kind / f.name).write_text(text, encoding="utf-8")
                files.append(f"{kind}/{f.name}")
                deps |= referenced_packages(text, package)
        (out / "CMakeLists.txt").write_text(_cmakelists(package, files, sorted(deps)), encoding="utf-8")
        names.append(package)
    return names


def missing_dependencies(src: Path, venv: Path = VENV) -> list[tuple[str, str]]:
    """(package, interface package it uses that this environment lacks) for every package under `src`: CMake
    would stop on each with a page of output; the wheels install a package's CMake config under share/."""
    packages = packages_in(src)
    own = {p.name for p in packages}
    missing = []
    for pkg_dir in packages:
        used: set[str] = set()
        for kind in ("msg", "srv", "action"):
            for f in sorted((pkg_dir / kind).glob(f"*.{kind}")):
                used |= referenced_packages(translate(f.read_text(encoding="utf-8")), pkg_dir.name)
        missing += [(pkg_dir.name, dep) for dep in sorted(used - own) if not (venv / "share" / dep / "cmake").is_dir()]
    return missing


def definitions_hash(src: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(p for p in src.rglob("*") if p.is_file()):
        digest.update(path.relative_to(src).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    digest.update(Path(__file__).read_bytes())
    digest.update(f"{sys.version_info[:2]}".encode())
    return digest.hexdigest()[:16]


def fix_cmake_exports(venv: Path = VENV) -> int:
    """Point the wheels' exported CMake targets at this machine's Python and numpy headers (idempotent).

    The wheels were built in a manylinux container; their `*Export.cmake` files name
    `/opt/python/cpXY-cpXY/include/pythonX.Y` and that container's numpy include directory, which makes
    `rosidl_generate_interfaces(... DEPENDENCIES std_msgs)` fail with "non-existent path" errors.
    """
    import numpy

    py_include = sysconfig.get_paths()["include"]
    np_include = numpy.get_include()
    numpy_re = re.compile(r"/opt/python/[^;\"\s]*/site-packages/numpy/(?:_core|core)/include")
    python_re = re.compile(r"/opt/python/cp[0-9]+-cp[0-9]+t?/include/python[0-9.]+t?")
    changed = 0
    for path in sorted((venv / "share").glob("*/cmake/*Export*.cmake")):
        text = path.read_text(encoding="utf-8")
        if "/opt/python/" not in text:
            continue
        new = python_re.sub(lambda _m: py_include, numpy_re.sub(lambda _m: np_include, text))
        if new != text:
            path.write_text(new, encoding="utf-8")
            changed += 1
    return changed


@contextmanager
def file_lock(path: Path) -> Iterator[None]:
    """An exclusive lock shared by every process on this machine (pytest-xdist workers included)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def build_env(prefixes: list[Path], colcon_home: Path | None = None) -> dict[str, str]:
    """Environment for CMake/colcon: the venv (and earlier prefixes) as ament and CMake prefixes.

    `colcon_home` (default: a directory in the system's temporary directory) keeps colcon away from the
    user's own ~/.colcon configuration.
    """
    env = dict(os.environ)
    paths = os.pathsep.join([*map(str, prefixes), str(VENV)])
    env.update(
        AMENT_PREFIX_PATH=paths,
        CMAKE_PREFIX_PATH=paths,
        ROS_VERSION="2",
        ROS_DISTRO="jazzy",
        ROS_PYTHON_VERSION="3",
        PATH=os.pathsep.join([str(VENV / "bin"), env.get("PATH", "")]),
        PYTHONPATH=os.pathsep.join(str(p / "lib" / PY_DIR / "site-packages") for p in prefixes),
        COLCON_HOME=str(colcon_home or Path(tempfile.gettempdir()) / "td2adaptor-colcon-home"),
        MAKEFLAGS=f"-j{os.cpu_count() or 2}",
    )
    env.pop("COLCON_PREFIX_PATH", None)
    return env


def colcon_build(base: Path, prefixes: list[Path], *, cmake: bool, colcon_home: Path | None = None) -> Path:
    """`colcon build --merge-install` of every package under `base/src`; the install prefix."""
    args = [
        str(VENV / "bin" / "colcon"),
        "--log-base",
        str(base / "log"),
        "build",
        "--merge-install",
        "--executor",
        "parallel",
        "--parallel-workers",
        str(os.cpu_count() or 2),
        "--base-paths",
        str(base / "src"),
        "--build-base",
        str(base / "build"),
        "--install-base",
        str(base / "install"),
    ]
    if cmake:
        args += [
            "--cmake-args",
            "-G",
            "Ninja",
            "-DBUILD_TESTING=OFF",
            f"-DPython3_EXECUTABLE={VENV / 'bin' / 'python'}",
            "-DCMAKE_INSTALL_RPATH=$ORIGIN;$ORIGIN/../../..",
        ]
    environ = build_env(prefixes, colcon_home)
    proc = subprocess.run(args, env=environ, capture_output=True, text=True, cwd=base, check=False)
    if proc.returncode != 0:
        logs = "\n".join(
            p.read_text(encoding="utf-8", errors="replace")[-4000:] for p in sorted((base / "log").rglob("stderr.log"))
        )
        raise RuntimeError(
            f"colcon build failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}\n{logs}"
        )
    return base / "install"


def build_interfaces(
    src: Path, cache: Path, *, colcon_home: Path | None = None, progress: Callable[[str], None] | None = None
) -> Path:
    """The install prefix of the interface packages under `src`, built once per definitions hash.

    `progress` hears about a build before it starts and when it is done (half a minute or more): the
    command line passes it on a terminal only, so CI logs stay quiet.
    """
    packages = packages_in(src)  # refuse an empty or missing folder before hashing or locking anything
    missing = missing_dependencies(src)
    if missing:
        from td2adaptor.support.providers import providers

        said = "; ".join(f"{pkg} uses {dep}" for pkg, dep in missing)
        wheels = " ".join(sorted({providers(dep)[0] for _, dep in missing}))
        raise BuildError(f"interface packages this environment does not have: {said} (pip install {wheels})")
    src, cache = src.resolve(), cache.resolve()  # colcon runs in the build folder: relative paths would miss
    key = definitions_hash(src)
    root = cache / key
    done = root / "DONE"
    if done.is_file():
        return root / "install"
    with file_lock(cache / f"{key}.lock"):
        if done.is_file():
            return root / "install"
        if root.exists():
            shutil.rmtree(root)  # a build that died half-way
        started = time.monotonic()
        if progress is not None:
            names = ", ".join(p.name for p in packages)
            progress(f"building {names} with CMake (once; cached in {cache}) ...")
        fix_cmake_exports()
        prepare_sources(src, root / "src")
        install = colcon_build(root, [], cmake=True, colcon_home=colcon_home)
        done.write_text("ok\n", encoding="utf-8")
        if progress is not None:
            progress(f"built in {time.monotonic() - started:.0f} s")
        return install


def main(argv: list[str]) -> int:
    """`python -m td2adaptor.support.ros2build INTERFACES CACHE`: print the install prefix, or one line why not."""
    if len(argv) != 2:
        print("usage: python -m td2adaptor.support.ros2build INTERFACES CACHE", file=sys.stderr)
        return 2

    def say(message: str) -> None:
        print(f"ros2build: {message}", file=sys.stderr, flush=True)

    try:
        print(build_interfaces(Path(argv[0]), Path(argv[1]), progress=say if sys.stderr.isatty() else None))
    except BuildError as exc:
        print(f"ros2build: {exc}", file=sys.stderr)
        return 1
    except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
        print(f"ros2build: building the interfaces failed: {exc}", file=sys.stderr)
        return 1
    except ImportError as exc:
        print(
            f"ros2build: the ROS 2 build tools are not installed ({exc}): pip install 'td2adaptor[ros2]'",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
