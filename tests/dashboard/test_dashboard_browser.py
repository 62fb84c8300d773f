"""The dashboard in a real browser (headless Chromium, Selenium) against simulated RB-1s behind their edge nodes
on a real mosquitto: the robots appear from their retained TDs, a mission invoked from the form generated from
the action's input schema moves the robot with its timeline, a cancel, a robot whose edge node is killed shows
offline, a bad value is refused by the page and, past it, by the node in its own words; read-only refuses on the
server too."""

from __future__ import annotations

import json
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from selenium.webdriver.common.by import By

from tests.dashboard.harness import (
    RobotProcess,
    chromium,
    chromium_or_skip,
    css,
    dashboard,
    fill,
    serve_robot,
    serve_sim_robot,
    wait,
)
from tests.runtime.broker import Mosquitto
from tests.runtime.edge import until


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
            assert not css(driver, "#mode")[0].is_displayed()  # not read-only
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
            # r1 stopped cleanly: its TD cleared, it leaves the list
            r1.stop()
            wait(driver, lambda d: not css(d, '#robots li[data-robot="r1"]'), what="r1 gone")
            # SIGTERM with the page's stream open: the stream ends, the command says so and exits 0
            assert dash.stop() == 0 and dash.output().endswith("td2adaptor dashboard: stopped\n"), dash.output()
            wait(driver, lambda d: css(d, "#connection")[0].text != "live", what="the page seeing it")
    finally:
        r2.kill()
        r1.stop()


def open_robot(driver: Any, dash_url: str, robot: str) -> None:
    driver.get(f"{dash_url}#/robot/{robot}")
    wait(driver, lambda d: css(d, 'details[data-action="gotoRun"]') and robot_state(d, robot) == "online", what="view")


def invoke_form(driver: Any, action: str) -> Any:
    css(driver, f'details[data-action="{action}"] > summary')[0].click()
    return css(driver, f'form[data-form="invoke:{action}"]')[0]


def test_a_running_mission_is_queried_and_cancelled_from_its_timeline_and_a_property_written(
    broker: Mosquitto,
) -> None:
    chromium_or_skip()
    r1, robot = serve_sim_robot(broker.url, "r1", duration=30.0)
    try:
        with dashboard(broker.url) as dash, chromium() as driver:
            open_robot(driver, dash.url, "r1")
            form = invoke_form(driver, "gotoRun")
            fill(form, {"/procedure/goals/0/pose/x": "4"})
            form.find_element(By.CSS_SELECTOR, 'button[type="submit"]').click()
            card = wait(driver, lambda d: css(d, '#timeline li[data-action="gotoRun"][data-mission]'), what="mission")[
                0
            ]
            card.find_element(By.CSS_SELECTOR, 'button[data-op="query"]').click()
            wait(driver, lambda _: card.find_elements(By.CSS_SELECTOR, '[data-kind="state"]'), what="query answer")
            card.find_element(By.CSS_SELECTOR, 'button[data-op="cancel"]').click()
            wait(driver, lambda _: card.get_attribute("data-terminal") == "true", what="terminal event")
            assert card.get_attribute("data-outcome") == "cancelled"
            answers = [
                e.get_attribute("data-state") for e in card.find_elements(By.CSS_SELECTOR, '[data-kind="state"]')
            ]
            assert answers[0] in ("queued", "running") and answers[-1] == "cancelled", answers
            # the door's writeproperty form, generated from the property's schema
            form = css(driver, 'form[data-form="write:door"]')[0]
            fill(form, {"/data": "0.75"})
            form.find_element(By.CSS_SELECTOR, 'button[type="submit"]').click()
            assert until(lambda: robot.door_command == 0.75, 10), robot.door_command
    finally:
        r1.stop()


def test_a_bad_value_is_refused_by_the_page_and_past_it_by_the_node(broker: Mosquitto) -> None:
    chromium_or_skip()
    r1 = serve_robot(broker.url, "r1")
    try:
        with dashboard(broker.url) as dash, chromium() as driver:
            open_robot(driver, dash.url, "r1")
            form = invoke_form(driver, "gotoRun")
            fill(form, {"/procedure/goals/0/pose/x": "fast"})
            form.find_element(By.CSS_SELECTOR, 'button[type="submit"]').click()
            wait(driver, lambda _: form.get_attribute("data-result") == "refused-by-page", what="the page's refusal")
            assert "/procedure/goals/0/pose/x: must be a finite number" in form.text
            assert css(driver, "#timeline li") == []  # nothing was sent
            # the TD's schema leaves objects open; the node's contract closes them: a member the page lets through
            form = invoke_form(driver, "pickRun")
            form.find_element(By.CSS_SELECTOR, "button[data-json-toggle]").click()
            text = form.find_element(By.CSS_SELECTOR, 'textarea[name="json"]')
            text.clear()
            text.send_keys('{"procedure": {"nope": 1}}')
            form.find_element(By.CSS_SELECTOR, 'button[type="submit"]').click()
            card = wait(driver, lambda d: css(d, '#timeline li[data-action="pickRun"][data-outcome="refused"]'))[0]
            refusal = card.find_element(By.CSS_SELECTOR, '[data-kind="error"]')
            assert refusal.get_attribute("data-code") == "invalid-event"
            assert "/procedure: Additional properties are not allowed ('nope' was unexpected)" in refusal.text
            wait(driver, lambda d: "invalid-event" in css(d, '#robots li[data-robot="r1"]')[0].text, what="last error")
    finally:
        r1.stop()


def test_read_only_shows_no_form_and_the_server_refuses_a_write_or_invoke(broker: Mosquitto) -> None:
    chromium_or_skip()
    r1 = serve_robot(broker.url, "r1")
    try:
        with dashboard(broker.url, "--read-only") as dash, chromium() as driver:
            open_robot(driver, dash.url, "r1")
            assert css(driver, "form") == [] and css(driver, "#mode")[0].is_displayed()
            for path, body in (("actions/gotoRun", {"op": "invoke", "input": {}}), ("properties/door", {"value": {}})):
                assert post(f"{dash.url}api/robots/r1/{path}", body)[0] == 403
    finally:
        r1.stop()


def post(url: str, body: Any, headers: dict[str, str] | None = None) -> tuple[int, dict[str, Any]]:
    request = urllib.request.Request(
        url, data=json.dumps(body).encode(), headers={"Content-Type": "application/json", **(headers or {})}
    )
    try:
        with urllib.request.urlopen(request, timeout=10) as answer:
            return answer.status, json.loads(answer.read())
    except urllib.error.HTTPError as exc:
        with exc:
            text = exc.read()
        return exc.code, json.loads(text) if text.startswith(b"{") else {"text": text.decode()}


def test_the_server_answers_only_its_own_pages(broker: Mosquitto) -> None:
    """No browser needed: another site's page (Origin), a form post (not JSON), a DNS-rebound name (Host) and a
    topic the TD does not name are refused; what the TD names is published."""
    r1 = serve_robot(broker.url, "r1")
    try:
        with dashboard(broker.url) as dash:
            url = f"{dash.url}api/robots/r1/properties/door"
            wait_for_robot(dash.url, "r1")
            assert post(url, {"value": {"data": 1.0}}, {"Origin": "http://evil.example"})[0] == 403
            request = urllib.request.Request(
                url, data=b'{"value": {"data": 1}}', headers={"Content-Type": "text/plain"}
            )
            with pytest.raises(urllib.error.HTTPError) as refused:
                urllib.request.urlopen(request, timeout=10)
            refused.value.close()
            assert refused.value.code == 415
            assert post(url, {"value": {"data": 1.0}}, {"Host": "evil.example"})[0] == 400
            assert post(f"{dash.url}api/robots/r1/actions/nothing", {"op": "invoke"})[0] == 404
            status, answer = post(url, {"value": {"data": 0.5}})
            assert status == 200 and answer["topic"] == "td2adaptor/r1/wot-thing/DoorComponent/door"
    finally:
        r1.stop()


def wait_for_robot(url: str, robot: str) -> None:
    def listed() -> bool:
        with urllib.request.urlopen(f"{url}api/fleet", timeout=5) as answer:
            return any(r["id"] == robot for r in json.loads(answer.read())["robots"])

    assert until(listed, 20), f"{robot} never listed"


def responses_seen(driver: Any) -> list[str]:
    """Every response the page received, as Chromium logged it: headers, bodies, each server-sent event."""
    out: list[str] = []
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        params = message.get("params", {})
        if message["method"] == "Network.responseReceived":
            out.append(json.dumps(params["response"].get("headers", {})))
            if params["response"].get("mimeType") != "text/event-stream":
                try:
                    body = driver.execute_cdp_cmd("Network.getResponseBody", {"requestId": params["requestId"]})
                except Exception:  # noqa: BLE001 - a body Chromium no longer keeps (none of ours: checked below)
                    continue
                out.append(body["body"])
        elif message["method"] == "Network.eventSourceMessageReceived":
            out.append(params["data"])
    return out


def test_no_secret_reaches_the_page_from_a_broker_with_credentials(tmp_path: Path) -> None:
    chromium_or_skip()
    users = {"r1": "edge-Secret-41", "viewer": "dash-Secret-42"}
    broker = Mosquitto(tmp_path / "broker", users=users)
    broker.start()
    edge_env = {"TD2ADAPTOR_MQTT_USERNAME": "r1", "TD2ADAPTOR_MQTT_PASSWORD": users["r1"]}
    dash_env = {"TD2ADAPTOR_MQTT_USERNAME": "viewer", "TD2ADAPTOR_MQTT_PASSWORD": users["viewer"]}
    r1 = serve_robot(broker.url, "r1", env=edge_env)
    try:
        with dashboard(broker.url, env=dash_env) as dash, chromium(performance_log=True) as driver:
            open_robot(driver, dash.url, "r1")
            form = invoke_form(driver, "gotoRun")
            fill(form, {"/procedure/goals/0/pose/x": "1"})
            form.find_element(By.CSS_SELECTOR, 'button[type="submit"]').click()
            wait(driver, lambda d: css(d, '#timeline li[data-terminal="true"]'), what="the mission's end")
            seen = responses_seen(driver)
            page = driver.page_source
            output = dash.output()
        bodies = "\n".join(seen)
        assert '"Robotnik RB-1"' in bodies and '"finished"' in bodies  # the responses were read, TD and events
        for secret in users.values():
            assert secret not in bodies and secret not in page and secret not in output
    finally:
        r1.stop()
        broker.stop()


SCHEMA = {
    "type": "object",
    "properties": {
        "mode": {"type": "string", "enum": ["fast", "careful"]},
        "speed": {"type": "number", "minimum": 0, "maximum": 2},
        "count": {"type": "integer", "minimum": 1, "maximum": 10},
        "loop": {"type": "boolean"},
        "kind": {"const": "goal"},
        "label": {"type": "string", "maxLength": 4},
        "waypoints": {
            "type": "array",
            "maxItems": 2,
            "items": {"type": "object", "properties": {"x": {"type": "number"}, "tag": {"type": "string"}}},
        },
        "correlationId": {"type": "string"},
    },
    "required": ["mode", "kind"],
}


def test_the_form_generator_covers_enums_ranges_booleans_constants_and_nested_arrays(broker: Mosquitto) -> None:
    """schemaform.js in the browser on a schema with every kind the TDs use: fields by JSON pointer, the value it
    collects (empty fields left out), and the page's refusals (out of range, not whole, too long, missing)."""
    chromium_or_skip()
    with dashboard(broker.url) as dash, chromium() as driver:
        driver.get(dash.url)
        wait(driver, lambda d: d.execute_script("return document.readyState") == "complete", what="the page")
        driver.execute_async_script(
            """const [schema, done] = arguments;
            import("/static/schemaform.js").then(({ schemaForm }) => {
              window.sent = [];
              const submit = async (value) => { window.sent.push(value); return null; };
              const form = schemaForm(schema, { label: "go", name: "probe", submit });
              document.body.prepend(form);
              done();
            });""",
            SCHEMA,
        )
        form = css(driver, 'form[data-form="probe"]')[0]
        names = [e.get_attribute("name") for e in form.find_elements(By.CSS_SELECTOR, "[name]")]
        assert {"/mode", "/speed", "/count", "/loop", "/kind", "/label"} <= set(names), names
        assert "/waypoints/0/x" in names and "/correlationId" not in names  # the page sets correlationId itself
        submit = form.find_element(By.CSS_SELECTOR, 'button[type="submit"]')

        def send(values: dict[str, str]) -> str:
            fill(form, values)
            submit.click()
            wait(driver, lambda _: form.get_attribute("data-result") is not None, what="the form's verdict")
            verdict = str(form.get_attribute("data-result"))
            driver.execute_script("arguments[0].removeAttribute('data-result')", form)
            return verdict

        assert send({"/speed": "3", "/count": "2.5", "/label": "toolong"}) == "refused-by-page"
        problems = form.find_element(By.CSS_SELECTOR, ".problems").text
        for words in (
            "/mode: is required",
            "/speed: must be ≤ 2",
            "/count: must be a whole number",
            "/label: takes at",
        ):
            assert words in problems, problems
        from selenium.webdriver.support.ui import Select

        Select(form.find_element(By.CSS_SELECTOR, '[name="/mode"]')).select_by_visible_text('"careful"')
        Select(form.find_element(By.CSS_SELECTOR, '[name="/loop"]')).select_by_visible_text("true")
        form.find_element(By.CSS_SELECTOR, 'button[data-add="/waypoints"]').click()
        assert send({"/speed": "1.5", "/count": "3", "/label": "ab", "/waypoints/0/x": "-2", "/waypoints/1/tag": "b"})
        sent = driver.execute_script("return window.sent")
        assert sent == [
            {
                "mode": "careful",
                "speed": 1.5,
                "count": 3,
                "loop": True,
                "kind": "goal",
                "label": "ab",
                "waypoints": [{"x": -2}, {"tag": "b"}],
            }
        ], sent


def test_the_list_says_when_the_edge_node_is_up_but_the_robot_is_absent(broker: Mosquitto) -> None:
    """The status as the edge node words it (runtime/node/status.py: the robot's presence, the owner process,
    missions, last error), published by the runtime's own `status_event`: the page shows each as it changes."""
    chromium_or_skip()
    from td2adaptor.model.exposed import exposed_td
    from td2adaptor.runtime import RuntimeConfig
    from td2adaptor.runtime.engine.engine import status_event
    from td2adaptor.support.jsondump import dump
    from tests.runtime.client import AppClient
    from tests.runtime.rb1 import rb1_model

    model = rb1_model()
    config = RuntimeConfig(robot="r9", bus=broker.url)
    owner = {"host": "edge-7", "pid": 4242, "started": "2026-11-27T20:00:00Z", "node": "n1"}
    app = AppClient(broker, ["td2adaptor/r9/status"])
    try:
        app.client.publish("td2adaptor/r9/td", dump(exposed_td(model, robot="r9", broker=broker.url)), 1, True)

        def status(**members: Any) -> None:
            message = status_event(config, model, "online", **members)
            app.client.publish(message.topic, message.payload, 1, True).wait_for_publish(10)

        error = {"code": "busy", "message": "the component is running another procedure", "time": "2026-11-27T20:01Z"}
        status(robot="absent", owner=owner, missions=0, lastError=error)
        with dashboard(broker.url) as dash, chromium() as driver:
            driver.get(dash.url)
            wait(driver, lambda d: robot_state(d, "r9") == "absent", what="absent")
            item = css(driver, '#robots li[data-robot="r9"]')[0]
            assert "owner: host edge-7 pid 4242" in item.text and "busy: the component is running" in item.text
            status(robot="present", owner=owner, missions=1)
            wait(driver, lambda d: robot_state(d, "r9") == "online", what="present again")
            assert "missions: 1" in css(driver, '#robots li[data-robot="r9"]')[0].text
    finally:
        app.client.publish("td2adaptor/r9/td", b"", 1, True).wait_for_publish(10)
        app.close()
