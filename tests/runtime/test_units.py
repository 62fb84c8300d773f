"""Configuration loading, security planning and the reading of procedure responses."""

from __future__ import annotations

from pathlib import Path

import pytest

from td2adaptor.runtime import ConfigError, RuntimeConfig, SecurityError, load_config, load_fleet
from td2adaptor.runtime.bus.security import BrokerAddress, TlsOptions, is_loopback, parse_broker_url, plan_security
from td2adaptor.runtime.ros.procedures import interpret


def test_config_precedence_and_fleets(tmp_path: Path) -> None:
    path = tmp_path / "fleet.yaml"
    path.write_text(
        "bus: mqtt://127.0.0.1:1883\npoll_period: 0.25\nrobots:\n"
        "  - {robot: rb1_base_a}\n  - {robot: rb1_base_b, namespace: ns_b}\n  - {robot: rb1_base_c}\n",
        encoding="utf-8",
    )
    fleet = load_fleet(path, env={"TD2ADAPTOR_POLL_PERIOD": "0.1", "TD2ADAPTOR_MQTT_PASSWORD": "pw"})
    assert [c.robot for c in fleet] == ["rb1_base_a", "rb1_base_b", "rb1_base_c"]
    assert [c.ros_namespace for c in fleet] == ["rb1_base_a", "ns_b", "rb1_base_c"]
    assert {c.poll_period for c in fleet} == {0.1} and {c.password for c in fleet} == {"pw"}
    assert fleet[1].mqtt_client_id == "td2adaptor-rb1_base_b" and "pw" not in repr(fleet[1])
    one = load_config(path, env={}, overrides={"robot": "rb1_base_b", "mission_timeout": 5, "bus": None})
    assert (one.robot, one.namespace, one.mission_timeout, one.bus) == (
        "rb1_base_b",
        "ns_b",
        5,
        "mqtt://127.0.0.1:1883",
    )
    single = tmp_path / "one.yaml"
    single.write_text("robot: r1\nallow_insecure: yes\nproperty_period: 0\n", encoding="utf-8")
    cfg = load_config(single, env={"TD2ADAPTOR_ROBOT": "r2"})
    assert (cfg.robot, cfg.allow_insecure, cfg.property_period, cfg.bus) == ("r2", True, 0.0, "local")
    assert cfg.property_qos == 1
    assert load_config(single, env={"TD2ADAPTOR_PROPERTY_QOS": "0"}).property_qos == 0


@pytest.mark.parametrize(
    ("yaml_text", "env", "message"),
    [
        ("robot: all\n", {}, "not 'all'"),
        ("robot: a/b\n", {}, "must be 1-128"),
        ("robot: a+b\n", {}, "must be 1-128"),
        ("robot: 'a#b'\n", {}, "must be 1-128"),
        ("robt: a\n", {}, "unknown key 'robt'"),
        ("robot: a\npoll_period: soon\n", {}, "poll_period: 'soon' is not a valid float"),
        ("robot: a\npoll_period: 0\n", {}, "poll_period must be positive"),
        ("robots: [{robot: a}, {robot: a}]\n", {}, "unique"),
        ("bus: local\n", {}, "no robot id"),
        ("robot: a\n", {"TD2ADAPTOR_ALLOW_INSECURE": "perhaps"}, "allow_insecure"),
        ("robot: a\nproperty_qos: 2\n", {}, "property_qos 2 must be 0 or 1"),
        ("robot: a\nproperty_qos: once\n", {}, "property_qos: 'once' is not a valid int"),
        ("[1, 2", {}, "fleet.yaml"),
    ],
)
def test_config_errors_name_the_problem(tmp_path: Path, yaml_text: str, env: dict[str, str], message: str) -> None:
    path = tmp_path / "fleet.yaml"
    path.write_text(yaml_text, encoding="utf-8")
    with pytest.raises(ConfigError, match=message):
        load_config(path, env=env)


def test_security_planning(tmp_path: Path) -> None:
    local = parse_broker_url("mqtt://127.0.0.1:1884")
    assert (local.host, local.port, local.tls) == ("127.0.0.1", 1884, False)
    assert parse_broker_url("mqtts://broker.example").port == 8883
    assert is_loopback("localhost") and is_loopback("::1") and not is_loopback("192.0.2.1")
    nosec = {"nosec_sc": {"scheme": "nosec"}}
    basic = {"b": {"scheme": "basic"}}
    assert plan_security(nosec, local, env={}).username is None
    plan = plan_security(basic, local, env={"TD2ADAPTOR_MQTT_USERNAME": "u", "TD2ADAPTOR_MQTT_PASSWORD": "p"})
    assert (plan.username, plan.password, plan.tls) == ("u", "p", None)
    remote_tls = BrokerAddress("192.0.2.1", 8883, True)
    plan = plan_security(basic, remote_tls, username="u", password="p", env={})
    assert plan.tls == TlsOptions()
    with pytest.raises(SecurityError, match="CA file"):
        plan_security(basic, remote_tls, username="u", password="p", tls=TlsOptions(str(tmp_path / "no.pem")), env={})
    ca = tmp_path / "ca.pem"
    ca.write_text("x", encoding="utf-8")
    assert plan_security(basic, remote_tls, username="u", password="p", tls=TlsOptions(str(ca)), env={}).tls
    for bad in ("http://x", "mqtt://", "mqtt://h:99999", "mqtt://h/topic"):
        with pytest.raises(SecurityError):
            parse_broker_url(bad)
    combo = {"c": {"scheme": "combo", "allOf": ["b"]}, "b": {"scheme": "basic"}}
    with pytest.raises(SecurityError, match="basic"):
        plan_security(combo, local, env={})


@pytest.mark.parametrize(
    ("state", "event", "result", "expected", "reason"),
    [
        ("queued", "added", "ok", "queued", None),
        ("running", "start", "ok", "running", None),
        ("paused", "pause", "ok", "paused", None),
        ("finished", "finish", "ok", "finished", None),
        ("finished", "cancel", "ok", "cancelled", None),
        ("finished", "abort", "ok", "failed", "aborted"),
        ("finished", "finish", "error", "failed", "robot-error"),
        ("unknown", "abort", "error", "failed", "robot-error"),
        ("", "", "", "failed", "robot-error"),
        ("RUNNING", "START", "OK", "running", None),
    ],
)
def test_procedure_states(state: str, event: str, result: str, expected: str, reason: str | None) -> None:
    response = {
        "state": {"header": {"id": 7}, "current_state": state, "last_event": event},
        "result": {"result": result, "message": "m"},
    }
    status = interpret(response)
    assert (status.state, status.reason, status.mission_id, status.message) == (expected, reason, 7, "m")
    assert status.terminal == (expected in ("finished", "failed", "cancelled"))


def test_procedure_odd_responses() -> None:
    assert interpret(None).reason == "unreachable"
    status = interpret({"state": {"current_state": "finished"}, "last_message": {"data": "done"}})
    assert (status.state, status.message, status.mission_id) == ("finished", "done", None)
    assert interpret({"state": {"header": {"id": True}, "current_state": "queued"}}).mission_id is None
    assert RuntimeConfig(robot="x").event_source == "td2adaptor/x"
