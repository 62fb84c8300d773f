"""Runtime configuration: one robot (id, ROS namespace, bus, timings, credentials), from code, env or YAML.

Precedence: explicit overrides (the CLI) > environment (`TD2ADAPTOR_*`) > YAML file > defaults. A YAML file
may describe a fleet: top-level keys are shared defaults, `robots:` a list of per-robot overrides.
"""

from __future__ import annotations

import dataclasses
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import yaml

from td2adaptor.model.events import ALL_ROBOTS, ROBOT_ID, TOPIC_ROOT
from td2adaptor.runtime.bus.security import redact_url
from td2adaptor.runtime.ros.genport import TRAIL_LIMIT

#: what an HTTP `Authorization: Bearer` token may hold (RFC 6750 is narrower; this keeps the header well formed)
_TOKEN = re.compile(r"[\x21-\x7e]{1,8192}")
#: a robot namespace ROS 1 and ROS 2 both take (the generated packages' check_robot_name, without the '/' around)
_NAMESPACE = re.compile(r"[A-Za-z][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*")
ENV_DIRECTORY_TOKEN = "TD2ADAPTOR_DIRECTORY_TOKEN"


class ConfigError(Exception):
    """A configuration value is missing or wrong; the message names it."""


def check_directory_url(url: str) -> str:
    """`url` as a directory base URL (http(s)://host[:port][/path], no trailing slash); raises ValueError with a
    message that shows the URL redacted. Credentials do not belong in it (they would show in process lists)."""
    shown = redact_url(url)
    try:
        parts = urlsplit(url)
    except ValueError:  # its words may quote the URL
        raise ValueError(f"directory URL {shown!r} is not a well-formed URL") from None
    try:
        parts.port  # noqa: B018 - raises ValueError for a bad port
    except ValueError:  # "Port could not be cast to integer value as '<what was typed>'"
        raise ValueError(f"directory URL {shown!r}: the port must be a number from 0 to 65535") from None
    if parts.scheme not in ("http", "https") or not parts.hostname:
        raise ValueError(f"directory URL {shown!r}: use http(s)://host[:port][/path] of a Thing Description Directory")
    if parts.username or parts.password:
        raise ValueError(
            f"directory URL {shown!r} carries credentials: give a token in the configuration "
            f"(directory_token) or in {ENV_DIRECTORY_TOKEN} instead"
        )
    if parts.query or parts.fragment:
        raise ValueError(f"directory URL {shown!r}: no query or fragment (the directory's base URL)")
    return url.rstrip("/")


@dataclass(frozen=True)
class RuntimeConfig:
    robot: str
    namespace: str | None = None  # ROS namespace ({{robotName}}); default: the robot id
    bus: str = "local"  # "local" or mqtt://host:port / mqtts://host:port
    td_broker: str | None = None  # the broker URL the robot's published TD names; default: bus (local: no TD)
    client_id: str | None = None  # default td2adaptor-<robot>
    source: str | None = None  # `source` of emitted events; default td2adaptor/<robot>
    topic_root: str = TOPIC_ROOT
    poll_period: float = 0.5  # seconds between queries of a running procedure
    mission_timeout: float = 600.0  # overall limit of one mission
    call_timeout: float = 10.0  # one robot call
    max_query_failures: int = 3  # consecutive failed queries before a mission is given up
    feedback_period: float = 0.0  # ROS action feedback: 0 one event per message, else at most one per period
    goal_feedback_grace: float | None = None  # after a goal's result, wait this long for trailing feedback; None:
    # the ROS version's default (genport.FEEDBACK_GRACE: 0.01 s on ROS 2, 0.1 s on ROS 1)
    action_server_timeout: float = 2.5  # ROS 2: a goal's action server silent this long (no feedback, no answer to
    # a probe) is taken as gone and the goal fails `unreachable`; 0: only when discovery says so (its lease)
    property_period: float = 1.0  # property events: at most one per property and period (0: off)
    property_mode: str = "sample"  # "sample": every property_period; "message": one event per ROS message
    property_interval: float = 0.0  # message mode: at least this long between two events of a property (0: none)
    property_qos: int = 1  # the MQTT QoS of property events: 1, or 0 (at most once) for high-rate sensor streams
    max_event_bytes: int = 65536
    username: str | None = None
    password: str | None = field(default=None, repr=False)
    tls_ca_file: str | None = None
    tls_cert_file: str | None = None
    tls_key_file: str | None = None
    allow_insecure: bool = False
    allow_anonymous_broker: bool = False  # run although the TD requires authentication and the broker does not
    session_expiry: int = 3600
    mqtt_version: str = "5"  # "5", or "3.1.1" for brokers that speak only that
    keepalive: int = 30
    ros_master_uri: str | None = None  # for the ROS 1 adapter
    ros_domain_id: int | None = None  # for the ROS 2 adapter
    freshness_window: float = 300.0  # an inbound event older than this (by its `time`) is expired, not run
    clock_skew: float = 30.0  # how far a sender's clock may run ahead of ours (a `time` that far ahead is fresh)
    require_id_and_time: bool = False  # refuse inbound events without `id` or `time` (WoT: without correlationId)
    state_dir: str | None = None  # where event ids are remembered (default: the user cache's state/; "" keeps none)
    directory: str | None = None  # a W3C WoT Thing Description Directory to register the robot's TD with
    directory_ttl: int = 600  # seconds the directory keeps the TD without a refresh (0: until it is deleted)
    directory_token: str | None = field(default=None, repr=False)  # Bearer token for the directory, if it wants one
    directory_ca_file: str | None = None  # CA bundle for an https directory with a private CA
    presence_period: float = 1.0  # seconds between looks at the robot's ROS side (its status `robot`); 0: none
    # the fleet's (every robot of the process has the same; not compared: changing them restarts no robot)
    fleet: str | None = field(default=None, compare=False)  # the fleet's name in admin topics (default: package)
    fleet_admin_key: str | None = field(default=None, repr=False, compare=False)  # signs admin requests
    discover_grace: float = field(default=10.0, compare=False)  # `run --discover`: a robot gone this long retires
    share: bool = field(default=False, compare=False)  # `run --share`: serve a share of the fleet with other processes
    share_keepalive: int = field(default=2, compare=False)  # the member connection's MQTT keepalive
    share_timeout: float = field(default=3.0, compare=False)  # a member silent this long: its robots are taken over

    def __post_init__(self) -> None:
        if not ROBOT_ID.match(self.robot) or self.robot == ALL_ROBOTS:
            raise ConfigError(
                f"robot id {self.robot!r} must be 1-128 letters, digits, '_', '.', '-' (and not {ALL_ROBOTS!r})"
            )
        if self.namespace is not None:  # refused here, naming the key, rather than by the package when it starts
            bare = self.namespace.strip("/")
            if bare and (not _NAMESPACE.fullmatch(bare) or "__" in bare):
                raise ConfigError(
                    f"namespace {self.namespace!r} of robot {self.robot} is not a ROS namespace: use letters, "
                    "digits, '_' and single '/' between names that start with a letter, no '__'"
                )
        for name in ("poll_period", "call_timeout", "mission_timeout"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"{name} must be positive")
        if not self.freshness_window > 0 or self.clock_skew < 0:
            raise ConfigError("freshness_window must be positive and clock_skew >= 0")
        if not 0 <= self.action_server_timeout < float("inf"):
            raise ConfigError("action_server_timeout must be >= 0 seconds (0: only discovery tells a server is gone)")
        if self.feedback_period < 0:
            raise ConfigError("feedback_period must be >= 0 (0: one feedback event per ROS feedback message)")
        if self.goal_feedback_grace is not None and not 0 <= self.goal_feedback_grace <= TRAIL_LIMIT:
            raise ConfigError(f"goal_feedback_grace must be between 0 and {TRAIL_LIMIT:g} seconds")
        if self.property_period < 0 or self.max_query_failures < 1 or self.max_event_bytes < 256:
            raise ConfigError("property_period >= 0, max_query_failures >= 1 and max_event_bytes >= 256 required")
        if self.property_mode not in ("sample", "message"):
            raise ConfigError(f"property_mode {self.property_mode!r} must be sample or message")
        if not 0 <= self.property_interval < float("inf"):
            raise ConfigError("property_interval must be >= 0 (0: every message)")
        if self.property_qos not in (0, 1):
            raise ConfigError(f"property_qos {self.property_qos!r} must be 0 or 1")
        if self.mqtt_version not in ("5", "3.1.1"):
            raise ConfigError(f"mqtt_version {self.mqtt_version!r} must be 5 or 3.1.1")
        if self.directory is not None:
            try:
                object.__setattr__(self, "directory", check_directory_url(self.directory))
            except ValueError as exc:
                raise ConfigError(str(exc)) from None
        if self.directory_token is not None and not _TOKEN.fullmatch(self.directory_token):
            raise ConfigError(
                "directory_token (TD2ADAPTOR_DIRECTORY_TOKEN) must be 1-8192 printable ASCII characters without "
                "blanks, as a Bearer token is (not shown)"
            )
        if not 0 <= self.presence_period < float("inf"):
            raise ConfigError("presence_period must be >= 0 seconds (0: the robot's ROS side is not watched)")
        if self.directory_ttl < 0:
            raise ConfigError("directory_ttl must be >= 0 (0: the directory keeps the TD until it is deleted)")
        if self.fleet is not None and (not ROBOT_ID.match(self.fleet) or self.fleet == ALL_ROBOTS):
            raise ConfigError(f"fleet {self.fleet!r} must be 1-128 letters, digits, '_', '.', '-' (a topic level)")
        if self.fleet_admin_key is not None and not 16 <= len(self.fleet_admin_key) <= 4096:
            raise ConfigError("fleet_admin_key (TD2ADAPTOR_FLEET_ADMIN_KEY) must be 16-4096 characters (not shown)")
        if not 0 <= self.discover_grace < float("inf"):
            raise ConfigError("discover_grace must be >= 0 seconds")
        if not 1 <= self.share_keepalive <= 65535:
            raise ConfigError("share_keepalive must be 1-65535 seconds")
        if not 0.5 <= self.share_timeout <= 3600:
            raise ConfigError("share_timeout must be 0.5-3600 seconds")
        if not self.topic_root or any(c in self.topic_root for c in "+#\x00") or self.topic_root.startswith("/"):
            raise ConfigError(f"topic_root {self.topic_root!r} is not a valid MQTT topic prefix")

    @property
    def ros_namespace(self) -> str:
        return self.namespace if self.namespace is not None else self.robot

    @property
    def mqtt_client_id(self) -> str:
        return self.client_id or f"td2adaptor-{self.robot}"

    @property
    def event_source(self) -> str:
        return self.source or f"td2adaptor/{self.robot}"

    @property
    def ids_file(self) -> Path | None:
        """The file that remembers this robot's event ids across restarts; None keeps them in memory only."""
        if self.state_dir == "":
            return None
        if self.state_dir is not None:
            return Path(self.state_dir) / f"{self.robot}.ids.sqlite3"
        from td2adaptor.support.cache import cache_dir

        base = cache_dir()
        return None if base is None else base / "state" / f"{self.robot}.ids.sqlite3"


_FIELDS = {f.name: f for f in dataclasses.fields(RuntimeConfig)}
_ENV_PREFIX = "TD2ADAPTOR_"
_ENV_ALIASES = {"TD2ADAPTOR_MQTT_USERNAME": "username", "TD2ADAPTOR_MQTT_PASSWORD": "password"}


def _coerce(name: str, value: Any) -> Any:
    """A YAML/env value as the field's type (env values are strings)."""
    kind = str(_FIELDS[name].type)
    if value is None:
        return None
    try:
        if kind.startswith("bool"):
            if isinstance(value, str):
                if value.lower() in ("1", "true", "yes", "on"):
                    return True
                if value.lower() in ("0", "false", "no", "off", ""):
                    return False
                raise ValueError(value)
            return bool(value)
        if kind.startswith("int"):
            if isinstance(value, bool):
                raise ValueError(value)
            return int(value)
        if kind.startswith("float"):
            return float(value)
    except ValueError:
        raise ConfigError(f"{name}: {value!r} is not a valid {kind.split(' ')[0]}") from None
    return str(value)


_KEY_SHOWN = re.compile(r"[A-Za-z0-9_.-]{1,64}")


def _unknown_key(key: Any, where: str) -> ConfigError:
    """The error for a key that is no setting, which never quotes more of the key than a setting name can be:
    `{password:S3cr3t}` (no blank after the ':') is one key, `password:S3cr3t`, with the value in it."""
    known = f"(known: {', '.join(_FIELDS)})"
    text = key if isinstance(key, str) else ""
    name, colon, _ = text.partition(":")
    if colon and name.strip() in _FIELDS:
        return ConfigError(
            f"{where}: key {name.strip()!r} has no blank after its ':', so the key and its value were read as one "
            f"key (not shown): write '{name.strip()}: VALUE'"
        )
    if _KEY_SHOWN.fullmatch(text):
        return ConfigError(f"{where}: unknown key {text!r} {known}")
    return ConfigError(f"{where}: a key that is no setting name (not shown: it may hold a value) {known}")


def _section(data: Any, where: str) -> dict[str, Any]:
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping")
    unknown = sorted((k for k in data if k not in _FIELDS and k != "robots"), key=str)
    if unknown:
        raise _unknown_key(unknown[0], where)
    return {k: _coerce(k, v) for k, v in data.items() if k != "robots"}


def from_env(env: Mapping[str, str]) -> dict[str, Any]:
    """The settings of `TD2ADAPTOR_*` variables; an empty variable is unset (launch files leave optional
    arguments empty), so it neither overrides the YAML file nor fails as a number."""
    out: dict[str, Any] = {}
    for key, value in env.items():
        name = _ENV_ALIASES.get(key) or (key[len(_ENV_PREFIX) :].lower() if key.startswith(_ENV_PREFIX) else "")
        if name in _FIELDS and value != "":
            out[name] = _coerce(name, value)
    return out


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """What is wrong with a YAML file and where, without PyYAML's quote of the line: the line may be the
    password's (`password: S3cr3t: oops` is a syntax error)."""
    if not isinstance(exc, yaml.MarkedYAMLError):
        return f"not valid YAML ({type(exc).__name__})"
    mark = exc.problem_mark or exc.context_mark
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    what = "; ".join(part for part in (exc.context, exc.problem) if part)
    return f"not valid YAML: {where}{what or 'syntax error'}"


def _read_yaml(path: str | Path) -> Any:
    try:
        return yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
    except OSError as exc:  # its words alone: str(exc) says "[Errno 2] ...: '<path>'", the path a second time
        raise ConfigError(f"{path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:  # its words quote the bytes, which may be a password's
        raise ConfigError(f"{path}: not UTF-8 text (at byte {exc.start})") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: {_yaml_problem(exc)}") from None


def load_fleet(
    path: str | Path | None = None,
    *,
    env: Mapping[str, str] | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> list[RuntimeConfig]:
    """Every robot a YAML file (and env, and overrides) describes: one process can serve them all."""
    env = os.environ if env is None else env
    base: dict[str, Any] = {}
    robots: list[dict[str, Any]] = [{}]
    if path is not None:
        data = _read_yaml(path)
        base = _section(data, str(path))
        if isinstance(data, Mapping) and "robots" in data:
            items = data["robots"]
            if not isinstance(items, list) or not items:
                raise ConfigError(f"{path}: robots must be a non-empty list")
            robots = [_section(item, f"{path}: robots[{i}]") for i, item in enumerate(items)]
    env_values = from_env(env)
    given = {k: v for k, v in (overrides or {}).items() if v is not None}
    if len(robots) > 1 and given.get("robot"):  # one robot of a fleet file
        robots = [r for r in robots if r.get("robot") == given["robot"]]
        if not robots:
            raise ConfigError(f"{path} has no robot {given['robot']!r}")
    configs = []
    for robot in robots:
        values = {**base, **robot, **env_values, **given}
        if len(robots) > 1:  # a fleet: each robot keeps its own id and namespace
            values.update({k: robot[k] for k in ("robot", "namespace", "client_id", "source") if k in robot})
        if not values.get("robot"):
            raise ConfigError("no robot id: give --robot, TD2ADAPTOR_ROBOT or 'robot:' in the YAML file")
        try:
            configs.append(RuntimeConfig(**values))
        except TypeError as exc:
            raise ConfigError(str(exc)) from None
    ids = [c.robot for c in configs]
    if len(set(ids)) != len(ids):
        raise ConfigError(f"robot ids must be unique: {ids}")
    return configs


def load_config(
    path: str | Path | None = None,
    *,
    env: Mapping[str, str] | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> RuntimeConfig:
    """One robot's configuration (a fleet file must then describe exactly one robot)."""
    configs = load_fleet(path, env=env, overrides=overrides)
    if len(configs) != 1:
        raise ConfigError(f"{path} describes {len(configs)} robots; pick one with --robot or run the fleet")
    return configs[0]


#: the keys each robot of a fleet keeps for itself (a robot that joins at run time brings them, the rest is shared)
ROBOT_KEYS = ("robot", "namespace", "client_id", "source")
STAND_IN = "stand-in"


def load_defaults(
    path: str | Path | None = None,
    *,
    env: Mapping[str, str] | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The settings a robot that joins a running fleet gets (discovered, or added by an admin request): the
    YAML file's top-level keys, the environment and `overrides`, without the per-robot keys; checked as one
    robot's (a `ConfigError` says what is wrong)."""
    env = os.environ if env is None else env
    base: dict[str, Any] = {}
    if path is not None:
        base = _section(_read_yaml(path), str(path))
    values = {**base, **from_env(env), **{k: v for k, v in (overrides or {}).items() if v is not None}}
    values = {k: v for k, v in values.items() if k not in ROBOT_KEYS}
    robot_config(values, STAND_IN)
    return values


def names_robots(path: str | Path | None) -> bool:
    """Whether the YAML file names a robot (`robot:` or `robots:`); `run --discover` serves only the robots it
    finds otherwise. A file that cannot be read names none here (reading it again says why)."""
    if path is None:
        return False
    try:
        data = _read_yaml(path)
    except ConfigError:
        return False
    return isinstance(data, Mapping) and ("robot" in data or "robots" in data)


def robot_config(defaults: Mapping[str, Any], robot: str, namespace: str | None = None) -> RuntimeConfig:
    """One robot of a fleet from its shared settings (`load_defaults`); raises `ConfigError`."""
    try:
        return RuntimeConfig(**{**defaults, "robot": robot, "namespace": namespace})
    except TypeError as exc:
        raise ConfigError(str(exc)) from None
