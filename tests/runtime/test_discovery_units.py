"""Discovery settings and the registered document, without a directory: configuration from the YAML file, the
environment and the command line, URLs refused with the credentials kept out of the message, the registered
copy of the TD, the retry schedule, and a robot with no TD to register."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest
from click.testing import CliRunner

from td2adaptor.cli.main import cli
from td2adaptor.runtime.config import ConfigError, RuntimeConfig, load_config
from td2adaptor.runtime.node.app import register
from td2adaptor.runtime.node.discovery import DISCOVERY_CONTEXT, Directory, backoff, registration_document
from tests.conftest import EXAMPLE


def test_directory_settings_come_from_yaml_env_and_overrides(tmp_path: Path) -> None:
    path = tmp_path / "edge.yaml"
    path.write_text("robot: r1\ndirectory: http://tdd.local:5000/\ndirectory_ttl: 30\n", encoding="utf-8")
    config = load_config(path, env={})
    assert (config.directory, config.directory_ttl) == ("http://tdd.local:5000", 30)  # no trailing slash
    env = {"TD2ADAPTOR_DIRECTORY": "https://tdd.example/api", "TD2ADAPTOR_DIRECTORY_TOKEN": "tok"}
    config = load_config(path, env=env, overrides={"directory_ttl": 0})
    assert (config.directory, config.directory_token, config.directory_ttl) == ("https://tdd.example/api", "tok", 0)
    assert "tok" not in repr(config)
    assert RuntimeConfig(robot="r1").directory is None  # off by default


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("ftp://tdd.local", "use http(s)://host[:port][/path]"),
        ("http://", "use http(s)://host[:port][/path]"),
        ("http://tdd.local:99999", "the port must be a number from 0 to 65535"),
        ("http://tdd.local/?x=1", "no query or fragment"),
        ("http://admin:hunter2@tdd.local", "carries credentials"),
    ],
)
def test_bad_directory_urls_are_refused_without_showing_credentials(url: str, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        RuntimeConfig(robot="r1", directory=url)
    assert message in str(info.value) and "hunter2" not in str(info.value)


def test_a_negative_ttl_is_refused() -> None:
    with pytest.raises(ConfigError, match="directory_ttl must be >= 0"):
        RuntimeConfig(robot="r1", directory="http://tdd.local", directory_ttl=-1)


def test_run_refuses_a_directory_url_with_credentials_in_one_line() -> None:
    args = ["run", str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces"), "--robot", "r1"]
    result = CliRunner().invoke(cli, [*args, "--directory", "http://u:hunter2@tdd.local"])
    assert result.exit_code == 1
    assert "carries credentials" in result.output and "hunter2" not in result.output
    assert "--directory" in CliRunner().invoke(cli, ["run", "--help"]).output


def test_the_registered_document_is_the_td_with_the_discovery_context_and_its_ttl() -> None:
    td = {"@context": "https://www.w3.org/2022/wot/td/v1.1", "id": "urn:x", "title": "X"}
    doc = registration_document(json.dumps(td), 60)
    assert doc["@context"] == ["https://www.w3.org/2022/wot/td/v1.1", DISCOVERY_CONTEXT]
    assert doc["registration"] == {"ttl": 60} and doc["id"] == "urn:x"
    again = registration_document(json.dumps(doc), 0)  # the context is not added twice; no ttl: no expiry
    assert again["@context"].count(DISCOVERY_CONTEXT) == 1 and again["registration"] == {"ttl": 60}
    assert "registration" not in registration_document(json.dumps(td), 0)


def test_retries_back_off_exponentially_up_to_a_minute() -> None:
    assert [backoff(n) for n in (1, 2, 3, 4, 7, 50)] == [1.0, 2.0, 4.0, 8.0, 60.0, 60.0]


def test_thing_urls_escape_the_id_and_the_token_stays_out_of_repr() -> None:
    directory = Directory("http://tdd.local:5000/base", token="s3cret")
    assert directory.thing_url("urn:dev:wot:a/b c") == "http://tdd.local:5000/base/things/urn%3Adev%3Awot%3Aa%2Fb%20c"
    assert "s3cret" not in repr(directory)


def test_a_robot_without_a_published_td_is_not_registered(caplog: pytest.LogCaptureFixture) -> None:
    config = RuntimeConfig(robot="r1", directory="http://127.0.0.1:9")  # a local bus names no broker: no TD
    with caplog.at_level(logging.WARNING, logger="td2adaptor.runtime"):
        assert register(config, None) is None
    assert "robot r1: no Thing Description to register" in caplog.text
    assert register(RuntimeConfig(robot="r1"), None) is None  # no directory: nothing to say


def test_a_server_that_answers_no_http_is_a_directory_error() -> None:
    """Something else on the directory's port (it answers, but not HTTP): reported like no answer at all."""
    import socket
    import threading

    from td2adaptor.runtime.node.discovery import DirectoryError

    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]

    def answer() -> None:
        conn, _ = server.accept()
        with conn:
            conn.recv(65536)
            conn.sendall(b"SSH-2.0-OpenSSH_9.2\r\n")

    thread = threading.Thread(target=answer, daemon=True)
    thread.start()
    try:
        with pytest.raises(DirectoryError, match=rf"PUT http://127.0.0.1:{port}/things/urn%3Ax: no answer \("):
            Directory(f"http://127.0.0.1:{port}").put("urn:x", {"id": "urn:x"}, timeout=10)
    finally:
        thread.join(10)
        server.close()


def test_a_td_without_id_is_reported_and_not_registered(caplog: pytest.LogCaptureFixture) -> None:
    from td2adaptor.runtime.bus.bus import Message

    config = RuntimeConfig(robot="r1", directory="http://127.0.0.1:9")
    td = Message("td2adaptor/r1/td", json.dumps({"title": "no id"}).encode(), retain=True)
    with caplog.at_level(logging.ERROR, logger="td2adaptor.runtime"):
        assert register(config, td) is None
    assert "robot r1: its Thing Description has no id, so a directory cannot hold it" in caplog.text


def test_the_ros1_graph_is_named_by_its_master_the_same_however_its_uri_is_spelt() -> None:
    """Processes of a shared fleet compare their graphs' names (share.py: a member on another graph cannot see a
    robot): `http://localhost:11311/` and `http://127.0.0.1:11311` are one master, and a loopback master on two
    hosts is two."""
    import socket

    from td2adaptor.runtime.node.graphwatch import ros1_graph

    names = {ros1_graph(uri, {}).name for uri in ("http://localhost:11311/", "http://127.0.0.1:11311", None)}
    assert names == {f"ros1 master localhost:11311 on {socket.gethostname()}"}
    assert ros1_graph("http://Master.Site:11312/", {}).name == "ros1 master master.site:11312"
    assert ros1_graph(None, {"ROS_MASTER_URI": "http://10.0.0.2:11311"}).name == "ros1 master 10.0.0.2:11311"


def test_a_ros1_master_that_does_not_answer_is_said_in_one_wording_naming_it_and_how_to_name_another() -> None:
    """The ROS 1 graph's look (discovery, graphwatch.py) and the ROS 1 bridge's start (bridge.py) said each in
    their own words that the master does not answer (one asked "is it running?", the other named roscore): one
    sentence now (ros/words.py), naming the master and the three ways to name another."""
    from td2adaptor.runtime.node.graphwatch import Ros1Graph, Signature
    from td2adaptor.runtime.ros.bridge import master_unreachable
    from tests.ports import free_port

    nobody = f"http://127.0.0.1:{free_port()}/"
    with pytest.raises(OSError) as looked:
        Ros1Graph(nobody).robots(Signature(("x",), (), ()), set())
    said = str(looked.value)
    assert said == master_unreachable(nobody), (said, master_unreachable(nobody))
    assert said.startswith(f"the ROS 1 master {nobody} does not answer (Connection refused): "), said
    for way in ("roscore", "--master-uri", "ros_master_uri", "ROS_MASTER_URI"):
        assert way in said, (way, said)
    assert "Errno" not in said and "Error" not in said, said
