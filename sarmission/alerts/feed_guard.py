"""Who may use the operator feed: access token, Host check and Origin check.

The feed serves casualty positions and takes acknowledgements, so:

- bound beyond loopback it needs an access token on every request (``Authorization: Bearer``,
  or the HttpOnly ``SameSite=Strict`` cookie the page gets when opened once with ``/?token=``);
- the ``Host`` header must name the feed (a page on another name that resolves to the feed's
  address, DNS rebinding, is refused even where no token is needed);
- a state-changing request from a browser (it sends ``Origin``) must come from the feed's own
  origin, and one without ``Origin`` must carry the token in its header.
"""

from __future__ import annotations

import hashlib
import hmac
import ipaddress
import logging
import re
import secrets
import stat
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from urllib.parse import urlsplit

from sarmission.errors import SarmissionError

log = logging.getLogger(__name__)

#: Printable ASCII without spaces: fits a header, a cookie-free URL query once quoted, a file.
_TOKEN = re.compile(r"[\x21-\x7e]{16,256}")
_NAME = re.compile(r"[a-z0-9](?:[a-z0-9.-]{0,251}[a-z0-9])?")
_PORT = re.compile(r":[0-9]{1,5}")
_WILDCARDS = frozenset(("", "0.0.0.0", "::"))
_MAX_HEADER = 4096


def is_wildcard(host: str) -> bool:
    """Whether binding ``host`` listens on every interface."""
    return host in _WILDCARDS


def is_loopback(address: str) -> bool:
    """Whether ``address`` (an IP literal or ``localhost``) only reaches this machine."""
    if address.lower() == "localhost":
        return True
    ip = _ip(address)
    return ip is not None and ip.is_loopback


def new_token() -> str:
    """A fresh access token (256 random bits, URL-safe)."""
    return secrets.token_urlsafe(32)


def check_token(token: str) -> str:
    """``token`` if usable (16-256 printable ASCII characters, no spaces), else ValueError."""
    if not _TOKEN.fullmatch(token):
        raise ValueError(
            "the feed access token must be 16-256 printable ASCII characters, no spaces"
        )
    return token


def read_token_file(path: str | Path) -> str:
    """The access token in ``path`` (surrounding whitespace ignored). Warns when others may read
    the file; raises SarmissionError when it is missing or holds no usable token."""
    path = Path(path)
    try:
        text = path.read_text(encoding="ascii").strip()
        mode = path.stat().st_mode
    except (OSError, UnicodeDecodeError) as exc:
        raise SarmissionError(f"cannot read the feed token file {path}: {exc}") from exc
    try:
        check_token(text)
    except ValueError as exc:
        raise SarmissionError(f"{path}: {exc}") from None
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        log.warning("feed token file %s is readable by other users (chmod 600 it)", path)
    return text


class Credential(Enum):
    """How a request proved it knows the token (``NONE``: no token is configured)."""

    NONE = "none"
    BEARER = "bearer"
    COOKIE = "cookie"
    QUERY = "query"


@dataclass(frozen=True)
class Refusal:
    """Why a request is refused: HTTP status and a one-line reason."""

    status: int
    message: str


class Guard:
    """Access rules of one bound feed.

    Args:
        token: the access token, or None for none (loopback binds only).
        bind_host: the host the feed was asked to bind (an IP literal, a name, or a wildcard).
        bound_ip: the address actually bound.
        port: the bound port (names the cookie, so two feeds on one machine keep theirs).
        allowed_hosts: further names the ``Host`` header may carry (e.g. ``drone.local``).
    """

    def __init__(
        self,
        token: str | None,
        bind_host: str,
        bound_ip: str,
        port: int,
        allowed_hosts: Iterable[str] = (),
    ) -> None:
        self.token = token
        self.wildcard = is_wildcard(bind_host)
        names = {_normal(bind_host), _normal(bound_ip)} - {""}
        if self.wildcard or is_loopback(bound_ip):
            names.add("localhost")
        names.update(_normal(h) for h in allowed_hosts)
        self.host_names = frozenset(names)
        self.cookie_name = f"sarmission_feed_{port}"
        self._cookie_value = (
            hmac.new(token.encode(), b"sarmission feed cookie", hashlib.sha256).hexdigest()
            if token
            else ""
        )

    # ------------------------------------------------------------------ Host

    def check_host(self, header: str | None) -> Refusal | None:
        """None when the ``Host`` header names this feed, else the refusal (400 or 421)."""
        if not header:
            return Refusal(400, "one Host header is required")
        host = host_of(header)
        if host is None:
            return Refusal(400, "malformed Host header")
        if host in self.host_names or self.wildcard and _ip(host) is not None:
            return None
        return Refusal(421, f"this feed does not serve the host name {host!r}")

    # ------------------------------------------------------------------ token

    def credential(
        self, authorization: str | None, cookie: str | None, query_token: str | None
    ) -> Credential | None:
        """Which presented credential matches the token (any one suffices); None when none
        does. ``Credential.NONE`` when no token is configured."""
        if self.token is None:
            return Credential.NONE
        if authorization and len(authorization) <= _MAX_HEADER:
            scheme, _, value = authorization.strip().partition(" ")
            if scheme.lower() == "bearer" and _same(value.strip(), self.token):
                return Credential.BEARER
        value = _cookie(cookie, self.cookie_name)
        if value is not None and _same(value, self._cookie_value):
            return Credential.COOKIE
        if query_token is not None and _same(query_token, self.token):
            return Credential.QUERY
        return None

    def set_cookie(self) -> str:
        """The ``Set-Cookie`` value that lets a browser that showed the token keep using it."""
        return (
            f"{self.cookie_name}={self._cookie_value}; Path=/; HttpOnly; SameSite=Strict; "
            "Max-Age=86400"
        )

    # ------------------------------------------------------------------ Origin

    def check_change(
        self, credential: Credential, origin: str | None, host_header: str
    ) -> Refusal | None:
        """None when a state-changing request may go ahead: its ``Origin``, when sent, is the
        feed's own (the one the browser reached it by: the checked ``Host``); without ``Origin``
        (not a browser) a configured token must come in the ``Authorization`` header."""
        if origin is None:
            if credential in (Credential.NONE, Credential.BEARER):
                return None
            return Refusal(403, "a request without Origin must send Authorization: Bearer")
        if not _same_origin(origin, host_header):
            return Refusal(403, "cross-origin request refused")
        if credential is Credential.QUERY:
            return Refusal(401, "send the token in Authorization: Bearer or the page's cookie")
        return None


class WarnLimiter:
    """Logs a warning at most once per ``every_s`` seconds, with how many were held back: a
    client probing the feed cannot flood the log."""

    def __init__(self, every_s: float = 30.0) -> None:
        self.every_s = every_s
        self._lock = threading.Lock()
        self._next = 0.0
        self._held = 0

    def warn(self, message: str, *args: object) -> None:
        with self._lock:
            now = time.monotonic()
            if now < self._next:
                self._held += 1
                return
            held, self._held, self._next = self._held, 0, now + self.every_s
        suffix = f" ({held} more since the last such warning)" if held else ""
        log.warning(message + suffix, *args)


def host_of(header: str) -> str | None:
    """The host of a ``Host`` header (``name``, ``1.2.3.4``, ``[::1]``, each with an optional
    port), lower-cased and IP literals normalised; None when malformed."""
    value = header.strip().lower()
    if not value or len(value) > 300:
        return None
    if value.startswith("["):
        inner, bracket, rest = value[1:].partition("]")
        if not bracket or not isinstance(_ip(inner), ipaddress.IPv6Address):
            return None
        host = inner
    else:
        host, colon, port = value.partition(":")
        rest = colon + port
    if rest and not _PORT.fullmatch(rest):
        return None
    if _ip(host) is None and not _NAME.fullmatch(host):
        return None
    return _normal(host)


def _port_of(header: str) -> int:
    value = header.strip()
    tail = value.rsplit("]", 1)[-1]
    _, colon, port = tail.partition(":")
    return int(port) if colon else 80


def _same_origin(origin: str, host_header: str) -> bool:
    """Whether ``Origin`` is ``http://`` plus the host and port of ``host_header``."""
    if len(origin) > 300:
        return False
    try:
        parts = urlsplit(origin.strip())
        origin_port = parts.port or 80
    except ValueError:
        return False
    if parts.scheme != "http" or parts.path or parts.query or parts.hostname is None:
        return False
    host = host_of(host_header)
    return (
        host is not None
        and _normal(parts.hostname) == host
        and (origin_port == _port_of(host_header))
    )


def _ip(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        return ipaddress.ip_address(text)
    except ValueError:
        return None


def _normal(host: str) -> str:
    host = host.strip().strip("[]").lower()
    ip = _ip(host)
    return str(ip) if ip is not None else host


def _same(given: str, expected: str) -> bool:
    """Constant-time comparison of a presented secret with the expected one."""
    return hmac.compare_digest(given.encode("utf-8", "replace"), expected.encode())


def _cookie(header: str | None, name: str) -> str | None:
    """The value of cookie ``name`` in a ``Cookie`` header, None when absent."""
    if not header or len(header) > _MAX_HEADER:
        return None
    for part in header.split(";"):
        key, eq, value = part.strip().partition("=")
        if eq and key == name:
            return value
    return None
