"""How the TD's `securityDefinitions` decide the bus connection.

* `basic`: MQTT username and password, from the configuration or the environment
  (`TD2ADAPTOR_MQTT_USERNAME`, `TD2ADAPTOR_MQTT_PASSWORD`); missing credentials are an error, not a silent
  anonymous connection. Over plain TCP to another host the password would travel in clear: refused unless
  TLS is on or `allow_insecure` is set.
* `nosec` (or no definitions): only to a loopback broker unless `allow_insecure` is set.
* TLS (`mqtts://` or a CA file in the configuration) with an optional client certificate.
* Other schemes (apikey, bearer, oauth2, ...) have no MQTT meaning here and are refused.
"""

from __future__ import annotations

import ipaddress
import os
import re
import socket
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

ENV_USERNAME = "TD2ADAPTOR_MQTT_USERNAME"
ENV_PASSWORD = "TD2ADAPTOR_MQTT_PASSWORD"


class SecurityError(Exception):
    """The configuration does not satisfy the TD's security (or would be unsafe); says what to change."""


@dataclass(frozen=True)
class BrokerAddress:
    host: str
    port: int
    tls: bool

    def __str__(self) -> str:
        return f"{'mqtts' if self.tls else 'mqtt'}://{self.host}:{self.port}"

    @property
    def url(self) -> str:
        """`mqtt(s)://host:port` as a URI (an IPv6 address in brackets), e.g. for a TD's hrefs."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{'mqtts' if self.tls else 'mqtt'}://{host}:{self.port}"


@dataclass(frozen=True)
class TlsOptions:
    ca_file: str | None = None
    cert_file: str | None = None
    key_file: str | None = None


@dataclass(frozen=True)
class ConnectionSecurity:
    """What the MQTT client must do: credentials and TLS (None: plain TCP)."""

    username: str | None = None
    password: str | None = None
    tls: TlsOptions | None = None
    schemes: tuple[str, ...] = ()


#: schemes a message may name; any other word before `:/` may be something else typed there (a password)
_KNOWN_SCHEMES = frozenset({"mqtt", "mqtts", "tcp", "ssl", "http", "https", "ws", "wss"})
# a scheme counts only when slashes follow it ("mqtt://", "mqtt:/", "//"); in "edge:pw@host" the "edge:" is the
# user, not a scheme, and is hidden with the password
_SCHEME = re.compile(r"([A-Za-z][A-Za-z0-9+.-]*):(?=/)")
_WORD_TO_REDACT = re.compile(r"\S*(?:@|://|\?|#)\S*")
_OPENINGS = "([{'\"`<"
MQTT_STRING_MAX = 65535  # bytes of an MQTT string (user name) or binary data (password)


def _redact_port(authority: str) -> str:
    """`host[:port]` with a port that is not a number hidden: it may be a password typed where a port goes."""
    if authority.startswith("["):  # an IPv6 address; what follows its "]" is the port
        close = authority.find("]")
        if close < 0:
            return authority
        host, port = authority[: close + 1], authority[close + 1 :]
        return host + (port if port == "" or port[1:].isdigit() and port[0] == ":" else ":***")
    host, colon, port = authority.partition(":")
    return host + (colon + port if port.isdigit() or port == "" else ":***")


def redact_url(url: str, *, path: bool = True) -> str:
    """`url` fit for a message (messages end up in logs), whatever it holds and whether or not it is well formed:
    everything before its last `@` beyond the scheme (a `user:password@`, whatever the password holds: '#',
    '/', '?', '@') becomes `***@`; a query or fragment `?***` / `#***`; a port that is not a number `:***`; a
    scheme td2adaptor does not know `***`; with `path=False` (a bus URL, where a path means nothing) a path
    `/***`. What stays is a known scheme, the host, a numeric port and (by default) the path."""
    lead = len(url) - len(url.lstrip())
    out, rest = url[:lead], url[lead:]
    scheme = _SCHEME.match(rest)
    if scheme:
        out += (scheme.group(1) if scheme.group(1).lower() in _KNOWN_SCHEMES else "***") + ":"
        rest = rest[scheme.end() :]
    slashes = len(rest) - len(rest.lstrip("/"))
    out, rest = out + rest[:slashes], rest[slashes:]
    at = rest.rfind("@")
    if at >= 0:
        out, rest = out + "***@", rest[at + 1 :]
    end = next((i for i, c in enumerate(rest) if c in "/?#"), len(rest))
    out, rest = out + _redact_port(rest[:end]), rest[end:]
    cut = next((i for i, c in enumerate(rest) if c in "?#"), len(rest))
    where = rest[:cut]
    out += where if path or where in ("", "/") else "/***"
    if cut < len(rest):
        out += "?***" if rest[cut] == "?" and "#" not in rest[:cut] else "#***"
    return out


def redact_text(text: str) -> str:
    """`text` with every blank-separated word that may be a URL (holding `@`, `://`, `?` or `#`) redacted as one
    (`redact_url`), opening brackets and quotes kept: for messages that may quote what a user typed."""

    def word(match: re.Match[str]) -> str:
        found = match.group()
        opening = len(found) - len(found.lstrip(_OPENINGS))
        return found[:opening] + redact_url(found[opening:])

    return _WORD_TO_REDACT.sub(word, text)


def parse_broker_url(url: str) -> BrokerAddress:
    """`mqtt://host[:port]` or `mqtts://host[:port]` (default ports 1883 / 8883); no credentials in URLs.

    Every message names the URL redacted (`redact_url`, its path too): the one that refuses credentials in a
    URL must not print them either, nor a password typed in its query, fragment, port, path or scheme; and
    none quotes the URL parser's own words, which may quote the URL."""
    shown = redact_url(url, path=False)
    try:
        parts = urlsplit(url)
    except ValueError:
        raise SecurityError(f"bus URL {shown!r} is not a well-formed URL") from None
    if parts.scheme not in ("mqtt", "mqtts", "tcp", "ssl"):
        raise SecurityError(f"bus URL {shown!r}: use mqtt://host:port, mqtts://host:port or 'local'")
    if parts.username or parts.password:
        raise SecurityError(
            f"bus URL {shown!r} carries credentials: give them in the configuration or in {ENV_USERNAME} / "
            f"{ENV_PASSWORD} instead, so they do not show up in process lists and logs"
        )
    if not parts.hostname:
        raise SecurityError(f"bus URL {shown!r} has no host")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise SecurityError(f"bus URL {shown!r}: only scheme, host and port are meaningful")
    tls = parts.scheme in ("mqtts", "ssl")
    try:
        port = parts.port or (8883 if tls else 1883)
    except ValueError:
        raise SecurityError(f"bus URL {shown!r}: the port must be a number from 0 to 65535") from None
    return BrokerAddress(parts.hostname, port, tls)


def is_loopback(host: str) -> bool:
    """Whether every address `host` names is a loopback address (names are resolved, not guessed)."""
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None)
    except OSError:
        return False
    addresses = {info[4][0] for info in infos}
    return bool(addresses) and all(ipaddress.ip_address(str(a).split("%")[0]).is_loopback for a in addresses)


def schemes_of(security_definitions: Any) -> tuple[str, ...]:
    """The schemes of a TD's securityDefinitions, combos expanded, in order, without duplicates."""
    if not isinstance(security_definitions, Mapping):
        return ()
    out: list[str] = []
    for definition in security_definitions.values():
        scheme = definition.get("scheme") if isinstance(definition, Mapping) else None
        if isinstance(scheme, str) and scheme != "combo" and scheme not in out:
            out.append(scheme)
    return tuple(out)


def login_name(username: str | None, env: Mapping[str, str] | None = None) -> str | None:
    """The MQTT user name the node logs in with: the configuration's, else `TD2ADAPTOR_MQTT_USERNAME` (`env`,
    by default the process environment); None for none."""
    return username or (os.environ if env is None else env).get(ENV_USERNAME) or None


def _utf8_size(text: str) -> int | None:
    """The length of `text` in UTF-8, None when it has no UTF-8 form (a lone surrogate: what Python makes of
    bytes that are not UTF-8 in the environment or on the command line)."""
    try:
        return len(text.encode("utf-8"))
    except UnicodeEncodeError:
        return None


def check_credentials(username: str | None, password: str | None) -> None:
    """Refuse, in words and without showing it, a user name or password MQTT cannot carry (not UTF-8, more than
    65,535 bytes, a NUL in the name), and a user name with `/`, `+` or `#`: in a broker's ACL patterns
    (mosquitto's `%u`) such a name would stand for another robot's topics (docs/security.md)."""
    for what, text, setting in (("user name", username, ENV_USERNAME), ("password", password, ENV_PASSWORD)):
        if text is None:
            continue
        size = _utf8_size(text)
        if size is None:
            raise SecurityError(f"the MQTT {what} ({setting} or the configuration) is not valid UTF-8 text")
        if size > MQTT_STRING_MAX:
            raise SecurityError(
                f"the MQTT {what} ({setting} or the configuration) is {size:,} bytes long; MQTT carries at most "
                f"{MQTT_STRING_MAX:,}"
            )
    if username is not None and any(c in username for c in "/+#\x00"):
        raise SecurityError(
            f"the MQTT user name {username!r} holds '/', '+', '#' or a NUL: a broker's ACL patterns (mosquitto's "
            "%u) would read it as topic levels or wildcards, opening other robots' topics; use the robot id"
        )


def plan_security(
    security_definitions: Any,
    address: BrokerAddress,
    *,
    username: str | None = None,
    password: str | None = None,
    tls: TlsOptions | None = None,
    allow_insecure: bool = False,
    env: Mapping[str, str] | None = None,
) -> ConnectionSecurity:
    """Decide credentials and TLS for `address`, or raise `SecurityError` saying what is missing."""
    env = os.environ if env is None else env
    schemes = schemes_of(security_definitions) or ("nosec",)
    unsupported = [s for s in schemes if s not in ("nosec", "basic", "auto")]
    if unsupported:
        raise SecurityError(
            f"security scheme {unsupported[0]!r} of the Thing Description cannot be used on an MQTT bus "
            "(supported: basic, nosec, auto)"
        )
    username = login_name(username, env)
    password = password if password is not None else env.get(ENV_PASSWORD)
    check_credentials(username, password)
    use_tls = tls if tls is not None else (TlsOptions() if address.tls else None)
    for label, path in (
        ("CA file", use_tls.ca_file if use_tls else None),
        ("client certificate", use_tls.cert_file if use_tls else None),
        ("client key", use_tls.key_file if use_tls else None),
    ):
        if path and not os.path.isfile(path):
            raise SecurityError(f"TLS {label} {path!r} does not exist")
    if "basic" in schemes and (not username or password is None):
        raise SecurityError(
            "the Thing Description requires basic security: set the MQTT username and password in the "
            f"configuration or in {ENV_USERNAME} and {ENV_PASSWORD}"
        )
    loopback = is_loopback(address.host)
    if username:
        if use_tls is None and not loopback and not allow_insecure:
            raise SecurityError(
                f"refusing to send a password in clear to {address}: use mqtts:// (TLS), or allow_insecure"
            )
    elif not loopback and not allow_insecure:
        raise SecurityError(
            f"the Thing Description declares no credentials (nosec), so the bus may only be a broker on this "
            f"machine; {address} is not a loopback address (allow_insecure / --allow-insecure connects anyway)"
        )
    return ConnectionSecurity(username, password if username else None, use_tls, schemes)
