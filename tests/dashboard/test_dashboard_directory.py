"""`dashboard --directory URL`: robots listed from a real Thing Description Directory (Domus TDD on Oxigraph,
tests/runtime/tdd.py) as well as from the bus; the robot's retained TD on the bus wins while it is there, the
directory's copy stands in when the robot's node stopped, and a robot the directory drops leaves the list."""

from __future__ import annotations

import json
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.dashboard.directory import DirectoryReader, robot_of
from td2adaptor.dashboard.fleet import Fleet
from td2adaptor.model.exposed import exposed_td
from td2adaptor.runtime.node.discovery import Directory, registration_document
from tests.conftest import EXAMPLE
from tests.dashboard.harness import dashboard, serve_robot
from tests.runtime.broker import Mosquitto
from tests.runtime.edge import until
from tests.runtime.tdd import TddServer, small_robot_td


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Mosquitto]:
    b = Mosquitto(tmp_path / "broker")
    b.start()
    yield b
    b.stop()


def fleet(url: str) -> dict[str, dict[str, Any]]:
    with urllib.request.urlopen(f"{url}api/fleet", timeout=10) as answer:
        return {r["id"]: r for r in json.loads(answer.read())["robots"]}


def test_robots_are_listed_from_a_td_directory_as_well_as_the_bus(broker: Mosquitto, tmp_path: Path) -> None:
    tdd = TddServer(tmp_path / "tdd")
    tdd.start()
    try:
        result = td2adaptor.compile(small_robot_td(tmp_path), interfaces=[EXAMPLE / "interfaces"])
        assert result.model is not None
        td = exposed_td(result.model, robot="d1", broker=broker.url)
        directory = Directory(tdd.url)
        directory.put(td["id"], registration_document(json.dumps(td), 0))
        with dashboard(broker.url, "--directory", tdd.url, "--directory-period", "0.3") as dash:
            assert f"directory {tdd.url}" in dash.output()
            assert until(lambda: fleet(dash.url).get("d1", {}).get("source") == "directory", 30), fleet(dash.url)
            listed = fleet(dash.url)["d1"]
            assert listed["status"] is None and listed["title"] == td["title"]
            # the robot's node comes up: its own TD on the bus, and its status
            engine = serve_robot(broker.url, "d1")
            try:
                assert until(lambda: fleet(dash.url)["d1"]["source"] == "bus", 20), fleet(dash.url)
                assert until(lambda: (fleet(dash.url)["d1"]["status"] or {}).get("state") == "online", 20)
            finally:
                engine.stop()  # clears its TD on the bus: the directory's copy stands in, offline
            assert until(lambda: fleet(dash.url).get("d1", {}).get("source") == "directory", 20), fleet(dash.url)
            assert fleet(dash.url)["d1"]["status"]["state"] == "offline"
            directory.delete(td["id"])
            assert until(lambda: "d1" not in fleet(dash.url), 30), fleet(dash.url)
    finally:
        tdd.stop()


def test_a_directory_that_pages_its_listing_is_read_to_its_last_page(broker: Mosquitto, tmp_path: Path) -> None:
    """Domus pages `GET /things?limit=N` with `Link: <...>; rel="next"`: five robots in pages of two are all
    listed (the first page alone held two)."""
    tdd = TddServer(tmp_path / "tdd")
    tdd.start()
    try:
        result = td2adaptor.compile(small_robot_td(tmp_path), interfaces=[EXAMPLE / "interfaces"])
        assert result.model is not None
        directory = Directory(tdd.url)
        robots = [f"paged_{i}" for i in range(5)]
        for robot in robots:
            td = exposed_td(result.model, robot=robot, broker=broker.url)
            directory.put(td["id"], registration_document(json.dumps(td), 0))
        fleet_view = Fleet()
        reader = DirectoryReader(tdd.url, fleet_view, page=2)
        listing = reader.read()
        assert sorted(robot_of(td, fleet_view.root) or "" for td in listing) == robots
        with urllib.request.urlopen(f"{tdd.url}/things?limit=2", timeout=10) as answer:  # what one page holds
            assert len(json.loads(answer.read())) == 2 and 'rel="next"' in answer.headers["Link"]
    finally:
        tdd.stop()
