"""Shared test set-up: repository paths (the W3C reference data beside the repo: tests/wot_corpus.py), and the
fixtures of real ROS 1 that several folders use (`ros1`, `master`)."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from hypothesis import settings

# Property tests draw the same examples in every run (derandomize): a suite that passes must pass again; an
# exploring run is `pytest --hypothesis-profile explore` (random draws, as many as each test asks for). No
# per-example deadline: on a machine busier than its cores an example's first call took 414 ms against the 200 ms
# default while the same example took 0.04 ms again (Hypothesis then fails the test as flaky); speed lives in bench/.
if TYPE_CHECKING:
    from tests.ros1.harness import Master

settings.register_profile("default", derandomize=True, deadline=None)
settings.register_profile("explore", derandomize=False, deadline=None)
settings.load_profile("default")

# Tests never read or write the user's cache; the result cache gets its own tests.
os.environ["TD2ADAPTOR_CACHE_DIR"] = tempfile.mkdtemp(prefix="td2adaptor-test-cache-")

REPO = Path(__file__).resolve().parents[1]

EXAMPLE = REPO / "examples" / "robotnik_rb1"


@pytest.fixture(autouse=True)
def _no_history_between_tests() -> Iterator[None]:
    """Every test's edge nodes start without a past: the default state directory, where a node remembers
    event ids and the missions it had in flight (a node started again follows on what the last one left),
    is emptied before each test. A test of restarts gives its nodes a state_dir of its own."""
    shutil.rmtree(Path(os.environ["TD2ADAPTOR_CACHE_DIR"]) / "state", ignore_errors=True)
    yield


@pytest.fixture(scope="module")
def ros1() -> None:
    """Real ROS 1 (Debian's rospy, rosmaster, catkin), by the one policy of tests/tools.py."""
    from tests.ros1 import harness
    from tests.tools import require_ok

    require_ok(harness.ros1_problem())


@pytest.fixture(scope="module")
def master(tmp_path_factory: pytest.TempPathFactory, ros1: None) -> Iterator[Master]:
    """A private ROS 1 master (a real rosmaster on a free port) for one test module."""
    from tests.ros1 import harness

    with harness.rosmaster(tmp_path_factory.mktemp("ros1-home")) as m:
        yield m
