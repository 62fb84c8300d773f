"""No secret in any output (issue 16, finding 1): every failure path that handles credentials — the bus URL,
the configuration file, the environment, a broker that refuses them, one that is not there, a bad setting
beside them — is swept for the secret, at the most talkative log level."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from td2adaptor.runtime.bus.security import redact_text, redact_url
from tests.conftest import EXAMPLE, REPO
from tests.ports import free_port
from tests.runtime.broker import Mosquitto

SECRET = "S3cr3t-Pa55w0rd"
ENV_PW = "TD2ADAPTOR_MQTT_PASSWORD"
BASIC = {"basic_sc": {"scheme": "basic"}}


@pytest.fixture
def basic_td(tmp_path: Path) -> Path:
    import json

    td = json.loads((EXAMPLE / "td.json").read_text())
    td["securityDefinitions"], td["security"] = BASIC, ["basic_sc"]
    path = tmp_path / "td.json"
    path.write_text(json.dumps(td))
    return path


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Mosquitto]:
    b = Mosquitto(tmp_path / "broker", users={"edge": "the-right-one"})
    b.start()
    yield b
    b.stop()


def _run(td: Path, *args: str, env: dict[str, str] | dict[bytes, bytes] | None = None) -> str:
    return _run_raw(
        "run", str(td), "-I", str(EXAMPLE / "interfaces"), "--robot", "r1", "--log-level", "debug", *args, env=env
    )


def _run_raw(*args: str, env: dict[str, str] | dict[bytes, bytes] | None = None) -> str:
    """The command's output; it must be a clear refusal: exit 1 (invalid) or 2 (usage), never 3 (internal)
    and never a traceback. `env` in bytes sets variables that are not UTF-8."""
    environ: dict[bytes, bytes] = {k: v for k, v in os.environb.items() if not k.startswith(b"TD2ADAPTOR_")}
    for key, value in (env or {}).items():
        environ[os.fsencode(key)] = os.fsencode(value)
    proc = subprocess.run(
        [sys.executable, "-m", "td2adaptor", *args],
        cwd=REPO,
        capture_output=True,
        env=environ,
        timeout=60,
    )
    out = (proc.stdout + proc.stderr).decode("utf-8", errors="replace")
    assert proc.returncode in (1, 2), out  # every case here is a failure path, and the user's to fix
    assert "Traceback" not in out, out
    return out


def test_redact_url() -> None:
    assert redact_url(f"mqtt://edge:{SECRET}@host:1883") == "mqtt://***@host:1883"
    assert redact_url(f"mqtts://{SECRET}@host") == "mqtts://***@host"
    assert redact_url("mqtt://host:1883") == "mqtt://host:1883"
    assert redact_url("https://tdd.example:8443/api") == "https://tdd.example:8443/api"
    # characters that end the authority in a URL parser, a password with '@', no scheme, a damaged scheme
    for password in ("S3#cr3t", "S3/cr3t", "S3?cr3t", "S3@cr3t", "S3:cr3t", "S3(cr3t"):
        assert redact_url(f"mqtt://edge:{password}@host:1") == "mqtt://***@host:1", password
    assert redact_url(f"edge:{SECRET}@127.0.0.1:1") == "***@127.0.0.1:1"
    assert redact_url(f"//edge:{SECRET}@127.0.0.1:1") == "//***@127.0.0.1:1"
    assert redact_url(f"mqtt:/edge:{SECRET}@127.0.0.1:1") == "mqtt:/***@127.0.0.1:1"
    assert redact_url(f"mqtt:edge:{SECRET}@127.0.0.1:1") == "***@127.0.0.1:1"
    assert redact_url(f"  mqtt://edge:{SECRET}@h") == "  mqtt://***@h"


def test_redact_url_hides_a_password_typed_anywhere_in_a_url() -> None:
    """Issue 30, item 12: a query, a fragment, a port that is no number, a scheme td2adaptor does not know."""
    assert redact_url(f"mqtt://h:1883/?password={SECRET}") == "mqtt://h:1883/?***"
    assert redact_url(f"mqtt://h:1883/#{SECRET}") == "mqtt://h:1883/#***"
    assert redact_url(f"mqtt://h:{SECRET}") == "mqtt://h:***"
    assert redact_url(f"mqtt://[::1]:{SECRET}/") == "mqtt://[::1]:***/"
    assert redact_url(f"{SECRET}://h:1883") == "***://h:1883"
    assert redact_url(f"https://tdd.example/api?token={SECRET}") == "https://tdd.example/api?***"
    assert redact_url(f"mqtt://h:1883/{SECRET}", path=False) == "mqtt://h:1883/***"
    # what stays: a known scheme, the host, a numeric port, the path of a URL that has one
    assert redact_url("mqtts://[::1]:8883") == "mqtts://[::1]:8883"
    assert redact_url("https://tdd.example:8443/api") == "https://tdd.example:8443/api"


def test_redact_text_hides_every_url_password_in_a_message() -> None:
    message = f"Got unexpected extra arguments (mqtt://edge:{SECRET}@h https://a:{SECRET}@tdd x)"
    assert redact_text(message) == "Got unexpected extra arguments (mqtt://***@h https://***@tdd x)"
    assert redact_text(f"bus URL 'edge:{SECRET}@h' is bad") == "bus URL '***@h' is bad"
    assert redact_text("nothing to hide: mqtt://h:1") == "nothing to hide: mqtt://h:1"
    assert SECRET not in redact_text(f"Got unexpected extra argument (mqtt://h:1/?password={SECRET})")


@pytest.mark.parametrize(
    "url",
    [
        f"mqtt://edge:S3#{SECRET}@127.0.0.1:1",
        f"mqtt://edge:S3/{SECRET}@127.0.0.1:1",
        f"mqtt://edge:S3?{SECRET}@127.0.0.1:1",
        f"edge:{SECRET}@127.0.0.1:1",
        f"//edge:{SECRET}@127.0.0.1:1",
        f"mqtt:/edge:{SECRET}@127.0.0.1:1",
        f"mqtt://edge:{SECRET}@[::1",
        f"mqtt://127.0.0.1:1883/?password={SECRET}",
        f"mqtt://127.0.0.1:1883/#{SECRET}",
        f"mqtt://127.0.0.1:{SECRET}",
        f"mqtt://[::1]:{SECRET}",
    ],
)
def test_every_refused_bus_or_directory_url_is_shown_redacted(url: str) -> None:
    from td2adaptor.runtime.bus.security import SecurityError, parse_broker_url
    from td2adaptor.runtime.config import check_directory_url

    with pytest.raises(SecurityError) as bus:
        parse_broker_url(url)
    with pytest.raises(ValueError) as directory:
        check_directory_url(url.replace("mqtt", "https"))
    for failure in (bus, directory):
        assert SECRET not in str(failure.value), str(failure.value)
        assert "***" in str(failure.value) or "not a well-formed URL" in str(failure.value), str(failure.value)


def test_a_yaml_syntax_error_says_where_without_quoting_the_line(tmp_path: Path) -> None:
    from td2adaptor.runtime.config import ConfigError, load_fleet

    config = tmp_path / "fleet.yaml"
    config.write_text(f"robot: r1\nusername: edge\npassword: {SECRET}: oops\n")
    with pytest.raises(ConfigError) as failure:
        load_fleet(config, env={})
    said = str(failure.value)
    assert SECRET not in said, said
    assert str(config) in said and "line 3" in said and "mapping values are not allowed" in said, said


def test_no_secret_in_any_failure_output_of_the_command(basic_td: Path, broker: Mosquitto, tmp_path: Path) -> None:
    config = tmp_path / "fleet.yaml"
    config.write_text(f"bus: {broker.url}\nusername: edge\npassword: {SECRET}\n")
    broken = tmp_path / "broken.yaml"
    broken.write_text(f"bus: {broker.url}\nusername: edge\npassword: {SECRET}: oops\n")
    bad_setting = tmp_path / "bad.yaml"
    bad_setting.write_text(f"bus: {broker.url}\nusername: edge\npassword: {SECRET}\npoll_period: -1\n")
    env = {"TD2ADAPTOR_MQTT_USERNAME": "edge", "TD2ADAPTOR_MQTT_PASSWORD": SECRET}
    typo = tmp_path / "typo.yaml"
    typo.write_text(f"{{bus: {broker.url}, username: edge, password:{SECRET}}}\n")
    latin1 = tmp_path / "latin1.yaml"
    latin1.write_bytes(f"bus: {broker.url}\nusername: edge\npassword: \xe9{SECRET}\n".encode("latin-1"))
    cases = {
        "credentials in the bus URL": _run(basic_td, "--bus", f"mqtt://edge:{SECRET}@127.0.0.1:{broker.port}"),
        "a URL password only": _run(basic_td, "--bus", f"mqtt://{SECRET}@127.0.0.1:{broker.port}"),
        "a malformed URL with a password": _run(basic_td, "--bus", f"mqtt://edge:{SECRET}@[::1"),
        "a configuration file (then no adaptor package)": _run(basic_td, "--config", str(config)),
        "a bad setting beside the password": _run(basic_td, "--config", str(bad_setting)),
        "the environment (then no adaptor package)": _run(basic_td, "--bus", broker.url, env=env),
        "a YAML syntax error on the password line": _run(basic_td, "--config", str(broken)),
        "a '#' in the URL password": _run(basic_td, "--bus", f"mqtt://edge:S3#{SECRET}@127.0.0.1:{broker.port}"),
        "a '/' in the URL password": _run(basic_td, "--bus", f"mqtt://edge:S3/{SECRET}@127.0.0.1:{broker.port}"),
        "a '?' in the URL password": _run(basic_td, "--bus", f"mqtt://edge:S3?{SECRET}@127.0.0.1:{broker.port}"),
        "a URL without scheme": _run(basic_td, "--bus", f"edge:{SECRET}@127.0.0.1:{broker.port}"),
        "a URL without scheme, in the environment": _run(
            basic_td, env={"TD2ADAPTOR_BUS": f"edge:{SECRET}@127.0.0.1:{broker.port}"}
        ),
        "a URL with '//' only": _run(basic_td, "--bus", f"//edge:{SECRET}@127.0.0.1:{broker.port}"),
        "a URL with one '/'": _run(basic_td, "--bus", f"mqtt:/edge:{SECRET}@127.0.0.1:{broker.port}"),
        "a directory URL with a password": _run(
            basic_td, "--bus", broker.url, "--directory", f"https://a:S3#{SECRET}@tdd.example"
        ),
        "a forgotten --bus (an extra argument)": _run(basic_td, f"mqtt://edge:{SECRET}@127.0.0.1:{broker.port}"),
        "an unknown command": _run_raw("--no-such-option", f"mqtt://edge:{SECRET}@h"),
        "a URL given as the command": _run_raw(f"mqtt://edge:{SECRET}@h"),
        # issue 30, item 12
        "a password in the URL's query": _run(basic_td, "--bus", f"mqtt://127.0.0.1:{broker.port}/?password={SECRET}"),
        "a password in the URL's fragment": _run(basic_td, "--bus", f"mqtt://127.0.0.1:{broker.port}/#{SECRET}"),
        "a password as the URL's port": _run(basic_td, "--bus", f"mqtt://127.0.0.1:{SECRET}"),
        "a password as the URL's scheme": _run(basic_td, "--bus", f"{SECRET}://127.0.0.1:{broker.port}"),
        "a password as the URL's path": _run(basic_td, "--bus", f"mqtt://127.0.0.1:{broker.port}/{SECRET}"),
        "a URL with a query as an extra argument": _run(basic_td, f"mqtt://127.0.0.1:1/?password={SECRET}"),
        "a directory token in the query": _run(
            basic_td, "--bus", broker.url, "--directory", f"https://tdd.example/?token={SECRET}"
        ),
        "a directory token as the port": _run(
            basic_td, "--bus", broker.url, "--directory", f"https://tdd.example:{SECRET}/"
        ),
        "a directory token that is no HTTP header value": _run(
            basic_td,
            "--bus",
            broker.url,
            "--directory",
            "https://tdd.example",
            env={"TD2ADAPTOR_DIRECTORY_TOKEN": f"{SECRET}\nX-Injected: 1"},
        ),
        "the YAML typo {password:PW}": _run(basic_td, "--config", str(typo)),
        "a YAML file that is not UTF-8": _run(basic_td, "--config", str(latin1)),
        "a 70,000-character password": _run(basic_td, "--bus", broker.url, env={**env, ENV_PW: SECRET * 5000}),
        "a password that is not UTF-8": _run(
            basic_td,
            "--bus",
            broker.url,
            env={b"TD2ADAPTOR_MQTT_USERNAME": b"edge", ENV_PW.encode(): b"\xff" + SECRET.encode()},
        ),
        "a user name with '/'": _run(
            basic_td, "--bus", broker.url, env={**env, "TD2ADAPTOR_MQTT_USERNAME": "r1/wot-thing"}
        ),
    }
    for what, out in cases.items():
        assert SECRET not in out, f"{what}:\n{out}"
        assert out.strip(), what  # each says why it stopped
    assert (
        "carries credentials" in cases["credentials in the bus URL"] and "***@" in cases["credentials in the bus URL"]
    )
    assert "poll_period" in cases["a bad setting beside the password"]
    assert "line 3" in cases["a YAML syntax error on the password line"]
    assert "unexpected extra argument (mqtt://***@127.0.0.1" in cases["a forgotten --bus (an extra argument)"]
    said = {what: out.strip().splitlines()[-1] for what, out in cases.items()}  # the line that says why
    assert said["a password in the URL's query"].endswith(
        f"'mqtt://127.0.0.1:{broker.port}/?***': only scheme, host and port are meaningful"
    )
    assert said["a password as the URL's port"].endswith(
        "'mqtt://127.0.0.1:***': the port must be a number from 0 to 65535"
    )
    assert said["a password as the URL's scheme"].endswith(
        f"'***://127.0.0.1:{broker.port}': use mqtt://host:port, mqtts://host:port or 'local'"
    )
    assert "'https://tdd.example/?***': no query or fragment" in said["a directory token in the query"]
    assert (
        "directory_token (TD2ADAPTOR_DIRECTORY_TOKEN) must be" in said["a directory token that is no HTTP header value"]
    )
    assert "key 'password' has no blank after its ':'" in said["the YAML typo {password:PW}"]
    assert "not UTF-8 text (at byte" in said["a YAML file that is not UTF-8"]
    assert (
        "the MQTT password (TD2ADAPTOR_MQTT_PASSWORD or the configuration) is 75,000 bytes long"
        in said["a 70,000-character password"]
    )
    assert (
        "the MQTT password (TD2ADAPTOR_MQTT_PASSWORD or the configuration) is not valid UTF-8"
        in said["a password that is not UTF-8"]
    )
    assert "the MQTT user name 'r1/wot-thing' holds '/', '+', '#'" in said["a user name with '/'"]


def test_no_secret_when_the_broker_refuses_or_is_not_there(
    broker: Mosquitto, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    from td2adaptor.runtime import BusError, RuntimeConfig, open_bus
    from tests.runtime.rb1 import td_with_security

    model = td_with_security(tmp_path, BASIC)
    caplog.set_level(logging.DEBUG)  # paho's and ours, everything
    closed = f"mqtt://127.0.0.1:{free_port()}"
    said = []
    for url in (broker.url, closed):
        config = RuntimeConfig(robot="r1", bus=url, username="edge", password=SECRET)
        assert SECRET not in repr(config)
        with pytest.raises(BusError) as failure:
            bus = open_bus(config, model, env={})
            bus.connect()
        said.append(str(failure.value))
        assert SECRET not in str(failure.value) and SECRET not in repr(failure.value)
    assert "refused user 'edge'" in said[0] and "127.0.0.1" in said[1]  # each says why, in words
    assert SECRET not in caplog.text
