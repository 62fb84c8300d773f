"""The mros backend's verbatim files (td2adaptor/backends/mros/verbatim/) are real sources that compile.

Each header there is compiled on its own, straight from that folder (not from a generated copy), included twice
(its include guard holds) with `g++ -fsyntax-only -Wall -Wextra -Werror`: as C++98 (mROS's toolchain) and C++17.
It sees only the stand-in mROS headers (mros_api/) and the two application headers a verbatim header may include,
td2a_config.h and kernel_cfg.h of the RB-1 example, in a folder of their own. The headers under mros_config/,
which mROS's C sources include, compile as C99 too. The generator copies exactly the files of that folder.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from td2adaptor.backends.mros import generator as mros
from td2adaptor.backends.mros import lint as mros_lint
from tests.backends.mros import apps, build
from tests.backends.mros.fixtures import needs_host

HEADERS = sorted(p.relative_to(mros.VERBATIM).as_posix() for p in mros.VERBATIM.rglob("*.h"))
C_HEADERS = [h for h in HEADERS if h.startswith("mros_config/")]
FLAGS = ["-fsyntax-only", "-Wall", "-Wextra", "-Werror"]


def test_the_generator_copies_every_verbatim_file() -> None:
    on_disk = sorted(p.relative_to(mros.VERBATIM).as_posix() for p in mros.VERBATIM.rglob("*") if p.is_file())
    assert on_disk == sorted(mros.VERBATIM_FILES)
    assert HEADERS and C_HEADERS
    app = apps.rb1()
    for rel in mros.VERBATIM_FILES:
        assert app.tree.files[app.root + rel] == (mros.VERBATIM / rel).read_bytes(), rel


@pytest.fixture(scope="module")
def app_headers(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """td2a_config.h and the configurator's kernel_cfg.h of the RB-1 example, alone in a folder."""
    app = apps.rb1()
    out = tmp_path_factory.mktemp("mros-verbatim")
    (out / "td2a_config.h").write_text(app.text("include/td2a_config.h"))
    (out / "kernel_cfg.h").write_text(mros_lint.kernel_cfg_h(app.text("app.cfg")))
    return out


def _compile(compiler: str, flags: list[str], header: str, app_headers: Path, unit: Path) -> None:
    unit.write_text(f'#include "{header}"\n#include "{header}"\n')
    paths = ["-I", str(mros.VERBATIM), "-I", str(app_headers), "-I", str(build.API)]
    build.run([compiler, *flags, *paths, str(unit)])


@needs_host
@pytest.mark.parametrize("std", ["gnu++98", "gnu++17"])
@pytest.mark.parametrize("header", HEADERS)
def test_verbatim_header_compiles_on_its_own(header: str, std: str, app_headers: Path, tmp_path: Path) -> None:
    _compile(build.HOST_CXX, [f"-std={std}", *FLAGS], header, app_headers, tmp_path / "unit.cpp")


@needs_host
@pytest.mark.parametrize("header", C_HEADERS)
def test_verbatim_c_header_compiles_as_c(header: str, app_headers: Path, tmp_path: Path) -> None:
    _compile("gcc", ["-std=gnu99", *FLAGS], header, app_headers, tmp_path / "unit.c")
