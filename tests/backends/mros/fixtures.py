"""Session fixtures of the mROS tests: generated applications on disk and the wire harness, built once.

Import the fixtures into a test module (`from .mros.fixtures import ...`) to use them.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from td2adaptor.backends.mros.types import Capacities, TypeViews
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.rostypes.registry import TypeRegistry
from tests.backends.mros import apps, build, wire
from tests.tools import needs, require

needs_host = needs(build.HOST_CXX, ".ci/setup-mros.sh")
needs_arm = needs(build.ARM_CXX, ".ci/setup-mros.sh")


@pytest.fixture(scope="session")
def shared_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory every xdist worker of this session sees (for builds made once)."""
    base = tmp_path_factory.getbasetemp()
    return (base.parent if base.name.startswith("popen-gw") else base) / "mros-shared"


@pytest.fixture(scope="session")
def generated(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[apps.App, Path]]:
    """The RB-1, feature and keyword applications, generated and written to disk (per worker: cheap)."""
    out = {}
    for name, make in (
        ("rb1", apps.rb1),
        ("features", apps.features),
        ("keywords", lambda: apps.generate(apps.keywords_td(), [apps.KEYWORD_INTERFACES])),
    ):
        app = make()
        out[name] = (app, apps.write(app, tmp_path_factory.mktemp(f"mros-{name}")))
    return out


@pytest.fixture(scope="session")
def feature_views(generated: dict[str, tuple[apps.App, Path]]) -> TypeViews:
    app = generated["features"][0]
    roots = list(dict.fromkeys(t.type_name for c in app.model.components for t in c.topics))
    return TypeViews(app.model.ros1, roots, Capacities(), Diagnostics())


@pytest.fixture(scope="session")
def typestore() -> object:
    """rosbags typestore (ROS 1 Noetic) with the test and RB-1 interface types."""
    return TypeRegistry("ros1", [apps.INTERFACES, apps.RB1_INTERFACES]).typestore()


@pytest.fixture(scope="session")
def wire_harness(
    generated: dict[str, tuple[apps.App, Path]], feature_views: TypeViews, shared_root: Path
) -> Iterator[wire.Harness]:
    """The wire-format harness of the feature application, built once per session, running."""
    require(build.HOST_CXX, ".ci/setup-mros.sh")
    app_dir = generated["features"][1]
    source = wire.harness_source(feature_views)
    key = "wire-" + build.digest(build.app_sources(app_dir / "include"), source)

    def make(target: Path) -> None:
        (target / "harness.cpp").write_text(source)
        build.run(
            [
                build.HOST_CXX,
                "-std=gnu++17",
                "-O1",
                "-Wall",
                "-Wextra",
                "-Werror",
                *build.includes(app_dir),
                str(target / "harness.cpp"),
                "-o",
                str(target / "harness"),
            ]
        )

    exe = build.shared(shared_root, key, make) / "harness"
    harness = wire.Harness.start(exe)
    yield harness
    harness.close()
