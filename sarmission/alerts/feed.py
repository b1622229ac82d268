"""Operator feed: a small HTTP server over an :class:`~sarmission.alerts.store.AlertStore`.

Routes (every error is one line of JSON, ``{"error": ..., "status": ...}``):

- ``GET /``: the operator page (self-contained HTML, live over ``/events``).
- ``GET /events``: Server-Sent Events. On connect, every stored alert as an ``alert`` event,
  the map (``map``: the current mission's area and drone track), then ``hello``; afterwards
  ``alert`` for each new alert or candidate and ``update`` for every change to one
  (acknowledgement, delivery, position attached later, a candidate confirmed or discarded, an
  operator's decision). Data is the alert's JSON document; ``id`` is the store's event
  sequence number, so a reconnecting browser (``Last-Event-ID``, digits only) gets only what
  it missed. Map changes come as ``track`` (new drone points) and ``area`` events, at most one
  of each per second, and ``map`` again when the store turns to another mission
  (:mod:`sarmission.alerts.feed_map`).
- ``GET /api/alerts[?since=T]``: JSON list of alerts (``since``: lock time, POSIX seconds).
- ``GET /api/alerts/<id>``: one alert.
- ``POST /api/alerts/<id>/ack``: acknowledge; body ``{"by": "name"}`` (1-64 printable
  characters), ``Content-Type: application/json`` required (a cross-site form cannot send it).
  Returns the alert.
- ``POST /api/alerts/<id>/confirm``, ``POST /api/alerts/<id>/dismiss``: an operator's decision;
  body ``{"by": "name"}`` (required), same rules as ``/ack``. Returns the alert with
  ``"unchanged": true`` when it already had that decision; the newer of two contradicting
  decisions wins (:meth:`~sarmission.alerts.store.AlertStore.record_decision`). Unknown id: 404.
  A change the store could not record (locked by another process too long, not writable): 503,
  nothing recorded, retry.
- ``GET /api/map[?mission=ID][&since=T]``: ``{"mission_id", "area", "track", "alerts",
  "dismissed"}`` of the mission (default: the one the store heard of last); see
  :func:`~sarmission.alerts.feed_map.map_document`.
- ``GET /alerts.jsonl[?since=T][&follow=1]``: one alert per line; with ``follow=1`` the
  response stays open and each new alert is written as it is stored, and again when a position
  is attached to an alert stored without one, when a candidate is confirmed or discarded, and
  on an operator's decision (same ``alert_id``: the later line supersedes).
- ``GET /alerts.geojson``, ``GET /alerts.kml``: exports (see :mod:`sarmission.alerts.export`).
- ``GET /thumb/<id>.jpg``: the alert's thumbnail.
- ``GET /healthz``: ``{"ok": true, "alerts": n, "last_event": seq, ...}``.

Access (:mod:`sarmission.alerts.feed_guard`): bound beyond loopback, every route needs the
access token (generated when none is given); a loopback feed needs one only when given. Tools
send ``Authorization: Bearer <token>``. A browser opens ``/?token=<token>`` once: the page is
served with an HttpOnly ``SameSite=Strict`` cookie derived from the token, which its own
requests (events, acknowledgements, decisions, thumbnails, exports) then carry, and it drops
the token from the address bar; the query token is accepted on ``/`` only, so it never rides
along in other URLs. The ``Host`` header must name the feed (its bind address, ``localhost`` on
loopback or wildcard binds, any IP literal on a wildcard bind, or a name in ``allowed_hosts``):
421 otherwise. An acknowledgement or decision with an ``Origin`` must come from the feed's own
origin, one without must carry the token header: 403 otherwise. Unknown query parameters are
refused.

Bounds (:mod:`sarmission.alerts.feed_limits`): at most ``max_connections`` connections (503
beyond, answered without a thread) and ``max_streams`` open streams (``/events`` and followed
JSON lines; 503 beyond); a request must arrive whole within ``request_timeout`` seconds, a write
may block ``send_timeout`` seconds; streams end when their client leaves.
"""

from __future__ import annotations

import io
import json
import logging
import re
import select
import socket
import sqlite3
import threading
import time
from collections.abc import Callable, Iterable
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import quote, urlsplit

from sarmission.alerts import feed_input as checked
from sarmission.alerts.export import alerts_geojson_bytes, alerts_kml
from sarmission.alerts.feed_guard import (
    Credential,
    Guard,
    Refusal,
    WarnLimiter,
    check_token,
    is_loopback,
    is_wildcard,
    new_token,
)
from sarmission.alerts.feed_input import BadRequest
from sarmission.alerts.feed_limits import BusyRejecter, DeadlineReader, Slots, tune_socket
from sarmission.alerts.feed_map import MapFollower, map_document
from sarmission.alerts.model import Alert
from sarmission.alerts.page import PAGE_HTML
from sarmission.alerts.store import AlertEvent, AlertStore, describe_failure
from sarmission.errors import SarmissionError

log = logging.getLogger(__name__)

_ID = r"([0-9A-Za-z_.-]{1,64})"
_ALERT = re.compile(rf"^/api/alerts/{_ID}$")
_CHANGE = re.compile(rf"^/api/alerts/{_ID}/(ack|confirm|dismiss)$")
#: What each decision route records.
_DECISIONS = {"confirm": "confirmed", "dismiss": "dismissed"}
_THUMB = re.compile(rf"^/thumb/{_ID}\.jpg$")
_TOKEN_IN_TARGET = re.compile(r"([?&]token=)[^&#]*")
_PAGE_CSP = (
    "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
    "img-src 'self'; connect-src 'self'; base-uri 'none'; form-action 'none'; "
    "frame-ancestors 'none'"
)
#: Query parameters each GET route takes (routes not named take none).
_PARAMS: dict[str, frozenset[str]] = {
    "/": frozenset(("token",)),
    "/api/alerts": frozenset(("since",)),
    "/alerts.jsonl": frozenset(("since", "follow")),
    "/api/map": frozenset(("mission", "since")),
}
#: How often a waiting stream checks for shutdown and client disconnects (seconds).
_TICK_S = 0.5
#: SSE comment sent when idle, so proxies keep the stream open.
_KEEPALIVE_S = 15.0


class _Server(ThreadingHTTPServer):
    """One thread per connection, at most ``feed.max_connections`` of them."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address: tuple[str, int], feed: FeedServer) -> None:
        self.feed = feed
        self.address_family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        self.busy = BusyRejecter(
            f"the feed is at its limit of {feed.max_connections} connections; retry shortly"
        )
        super().__init__(address, _Handler)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self.feed.connections.take():
            self.feed.refusals.warn(
                "feed: %d connections open, refusing more", self.feed.max_connections
            )
            self.busy.reject(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self.feed.connections.give()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self.feed.connections.give()

    def service_actions(self) -> None:
        self.busy.reap()

    def server_close(self) -> None:
        super().server_close()
        self.busy.close()

    def handle_error(self, request: Any, client_address: Any) -> None:
        log.exception("feed: error serving %s", client_address)


class FeedServer:
    """Serves ``store`` over HTTP on ``host:port`` (localhost by default; ``port=0`` picks a
    free port) from a background thread between :meth:`start` and :meth:`stop`.

    Args:
        token: access token required on every request; None: none on a loopback bind, a
            generated one (see :attr:`token`, :attr:`page_url`) on any other.
        allowed_hosts: names, besides the bind address, that clients may use in ``Host``.
        max_connections: connections served at once (503 beyond).
        max_streams: ``/events`` and followed JSON-lines streams open at once (503 beyond).
        request_timeout: seconds for a request line, headers and body to arrive.
        send_timeout: seconds a write to a client may block.
    """

    def __init__(
        self,
        store: AlertStore,
        host: str = "127.0.0.1",
        port: int = 8765,
        *,
        token: str | None = None,
        allowed_hosts: Iterable[str] = (),
        max_connections: int = 64,
        max_streams: int = 16,
        request_timeout: float = 10.0,
        send_timeout: float = 30.0,
    ) -> None:
        if not 1 <= max_streams <= max_connections:
            raise ValueError("need 1 <= max_streams <= max_connections")
        if not (request_timeout > 0 and send_timeout > 0):
            raise ValueError("timeouts must be positive")
        self.store = store
        self.host = host
        self.token = check_token(token) if token is not None else None
        #: True when :meth:`start` generated the token (it is shown once, by the caller).
        self.token_generated = False
        self.allowed_hosts = tuple(allowed_hosts)
        self.max_connections = max_connections
        self.request_timeout = request_timeout
        self.send_timeout = send_timeout
        self.connections = Slots(max_connections)
        self.streams = Slots(max_streams)
        self.refusals = WarnLimiter()
        self.guard: Guard | None = None
        self._requested_port = port
        self._server: _Server | None = None
        self._thread: threading.Thread | None = None
        self.stopping = threading.Event()

    @property
    def port(self) -> int:
        """The bound port (after :meth:`start`)."""
        if self._server is None:
            raise RuntimeError("feed server not started")
        return self._server.server_address[1]

    @property
    def url(self) -> str:
        """Base URL, e.g. ``http://127.0.0.1:8765``."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}"

    @property
    def page_url(self) -> str:
        """The operator page's URL, with ``?token=`` when a token is needed (a secret)."""
        return self.url + "/" + (f"?token={quote(self.token, safe='')}" if self.token else "")

    @property
    def loopback(self) -> bool:
        """Whether the bound address only reaches this machine (after :meth:`start`)."""
        if self._server is None:
            raise RuntimeError("feed server not started")
        return is_loopback(self._server.server_address[0])

    def announcement(self) -> str:
        """The console line that tells the operator where the feed is: the one place a
        generated token is shown (it is never logged)."""
        where = " (all interfaces: use this computer's address)" if is_wildcard(self.host) else ""
        if self.token is None:
            return f"operator feed on {self.url}/{where}"
        if self.token_generated:
            return (
                f"operator feed on {self.page_url}{where}; reachable from the network: open "
                "this address once in the browser, tools send Authorization: Bearer <token>"
            )
        return (
            f"operator feed on {self.url}/{where}; access token from the token file: open "
            "/?token=<token> once in the browser, tools send Authorization: Bearer <token>"
        )

    def start(self) -> FeedServer:
        """Bind and serve in a daemon thread; returns self. Beyond loopback, a token is generated
        when none was given and a warning is logged. Raises SarmissionError if the address
        cannot be bound."""
        if self._server is not None:
            raise RuntimeError("feed server already started")
        self.stopping.clear()
        try:
            self._server = _Server((self.host, self._requested_port), self)
        except OSError as exc:
            raise SarmissionError(
                f"cannot serve the alert feed on {self.host}:{self._requested_port}: {exc}"
            ) from exc
        if not self.loopback:
            if self.token is None:
                self.token, self.token_generated = new_token(), True
            log.warning(
                "alert feed on %s is reachable from the network: every request needs "
                "the access token",
                self.url,
            )
        self.guard = Guard(
            self.token, self.host, self._server.server_address[0], self.port, self.allowed_hosts
        )
        self._thread = threading.Thread(
            target=self._server.serve_forever,
            kwargs={"poll_interval": 0.2},
            name="sarmission-feed",
            daemon=True,
        )
        self._thread.start()
        log.info("alert feed on %s", self.url)
        return self

    def stop(self) -> None:
        """Stop serving; open streams end within about half a second."""
        if self._server is None:
            return
        self.stopping.set()
        self._server.shutdown()
        self._server.server_close()
        if self._thread is not None:
            self._thread.join()
        self._server = None
        self._thread = None

    def __enter__(self) -> FeedServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    server_version = "sarmission-feed"
    _reader: DeadlineReader
    _responded = False
    # set by parse_request; a request that times out before it still gets a 408
    command = ""
    path = ""
    requestline = ""
    request_version = "HTTP/1.0"
    default_request_version = "HTTP/1.0"  # answer even a malformed request line with headers

    # ------------------------------------------------------------------ plumbing

    def setup(self) -> None:
        super().setup()
        feed = self.server.feed
        tune_socket(self.connection, feed.send_timeout)
        self._reader = DeadlineReader(self.connection, feed.request_timeout, feed.send_timeout)
        self.rfile.close()  # the plain socket reader; requests are read against the deadline
        self.rfile = io.BufferedReader(self._reader)

    def handle(self) -> None:
        try:
            super().handle()
            if self._reader.expired and not self._responded:
                self.connection.settimeout(1.0)
                self._error(HTTPStatus.REQUEST_TIMEOUT, "the request did not arrive in time")
                self.wfile.flush()
        except (ConnectionError, TimeoutError):
            log.debug("feed: client %s went away", self.client_address)

    def log_message(self, format: str, *args: Any) -> None:
        text = format % args if args else format
        log.debug("feed %s: %s", self.client_address[0], _redact(text))

    def send_response(self, code: int, message: str | None = None) -> None:
        self._responded = True
        super().send_response(code, message)

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """Errors found by the HTTP parser (bad request line, headers too large, unknown
        method) as one-line JSON like every other error."""
        self.close_connection = True
        status = HTTPStatus(code)
        self._error(status, message or status.phrase)

    @property
    def feed(self) -> FeedServer:
        return self.server.feed

    @property
    def store(self) -> AlertStore:
        return self.server.feed.store

    def _send(
        self,
        status: int,
        body: bytes,
        content_type: str,
        headers: dict[str, str] | None = None,
    ) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        for key, value in (headers or {}).items():
            self.send_header(key, value)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: int, value: Any, headers: dict[str, str] | None = None) -> None:
        self._send(status, json.dumps(value).encode(), "application/json", headers)

    def _error(
        self, status: HTTPStatus, message: str, headers: dict[str, str] | None = None
    ) -> None:
        path = _redact(getattr(self, "path", "") or "")[:200]
        self._json(status, {"error": message, "status": int(status), "path": path}, headers)

    def _refuse(self, refusal: Refusal) -> None:
        self.feed.refusals.warn(
            "feed: refused a request from %s: %s", self.client_address[0], refusal.message
        )
        headers = (
            {"WWW-Authenticate": 'Bearer realm="sarmission feed"'}
            if (refusal.status == HTTPStatus.UNAUTHORIZED)
            else None
        )
        self._error(HTTPStatus(refusal.status), refusal.message, headers)

    def _start_stream(self, content_type: str) -> None:
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", content_type)
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("X-Accel-Buffering", "no")
        self.end_headers()
        self.wfile.flush()

    def _client_gone(self) -> bool:
        """True when the client has closed its end (readable socket with nothing to read)."""
        try:
            readable, _, _ = select.select([self.connection], [], [], 0)
            return bool(readable) and self.connection.recv(1, socket.MSG_PEEK) == b""
        except OSError:
            return True

    def _streaming(self) -> bool:
        return not (self.server.feed.stopping.is_set() or self.store.closed or self._client_gone())

    # ------------------------------------------------------------------ admission

    def _admit(self, query: str, query_token: bool) -> tuple[Credential, dict[str, str]] | None:
        """Host, query and token checks shared by every route: the credential used and the
        query parameters, or None once the refusal is sent."""
        guard = self.feed.guard
        assert guard is not None
        if len(self.path) > checked.MAX_TARGET:
            self._error(HTTPStatus.REQUEST_URI_TOO_LONG, "request target too long")
            return None
        hosts = self.headers.get_all("Host") or []
        refusal = guard.check_host(hosts[0] if len(hosts) == 1 else None)
        if refusal is not None:
            self._refuse(refusal)
            return None
        path = urlsplit(self.path).path
        allowed = _PARAMS.get(path, frozenset()) if self.command == "GET" else frozenset()
        try:
            params = checked.parse_query(query, allowed | {"token"} if query_token else allowed)
        except BadRequest as exc:
            message = str(exc)
            if "token" in query and not query_token:
                message = "a token in the query is accepted on / only: send Authorization: Bearer"
            self._error(HTTPStatus(exc.status), message)
            return None
        credential = guard.credential(
            self.headers.get("Authorization"), self.headers.get("Cookie"), params.pop("token", None)
        )
        if credential is None:
            self._refuse(
                Refusal(
                    401,
                    "access token required: open the feed's /?token= address "
                    "once, or send Authorization: Bearer <token>",
                )
            )
            return None
        return credential, params

    # ------------------------------------------------------------------ routing

    def do_GET(self) -> None:
        url = urlsplit(self.path)
        admitted = self._admit(url.query, query_token=url.path == "/")
        if admitted is None:
            return
        credential, params = admitted
        try:
            self._route_get(url.path, params, credential)
        except BadRequest as exc:
            self._error(HTTPStatus(exc.status), str(exc))

    def _route_get(self, path: str, params: dict[str, str], credential: Credential) -> None:
        route = _GET_ROUTES.get(path)
        if route is not None:
            route(self, params, credential)
        elif m := _ALERT.match(path):
            self._get_alert(m.group(1))
        elif m := _THUMB.match(path):
            self._get_thumbnail(m.group(1))
        elif m := _CHANGE.match(path):
            self._error(HTTPStatus.METHOD_NOT_ALLOWED, f"use POST to {m.group(2)}")
        else:
            self._error(HTTPStatus.NOT_FOUND, "not found")

    # -- GET routes (see _GET_ROUTES) -----------------------------------------------------------
    def _get_page(self, params: dict[str, str], credential: Credential) -> None:
        headers = {"Content-Security-Policy": _PAGE_CSP}
        if credential is Credential.QUERY and self.feed.guard is not None:
            headers["Set-Cookie"] = self.feed.guard.set_cookie()
        self._send(HTTPStatus.OK, PAGE_HTML.encode(), "text/html; charset=utf-8", headers)

    def _get_events(self, params: dict[str, str], credential: Credential) -> None:
        self._stream(self._events, checked.last_event_id(self.headers))

    def _get_alerts(self, params: dict[str, str], credential: Credential) -> None:
        alerts = self.store.list(checked.since(params))
        self._json(HTTPStatus.OK, [a.to_json_dict() for a in alerts])

    def _get_map(self, params: dict[str, str], credential: Credential) -> None:
        mission, since = checked.mission(params), checked.since(params)
        self._json(HTTPStatus.OK, map_document(self.store, mission, since))

    def _get_jsonl(self, params: dict[str, str], credential: Credential) -> None:
        since, follow = checked.since(params), checked.follow(params)
        if follow:
            self._stream(self._jsonl, since, True)
        else:
            self._jsonl(since, False)

    def _get_geojson(self, params: dict[str, str], credential: Credential) -> None:
        self._send(
            HTTPStatus.OK,
            alerts_geojson_bytes(self.store.list()),
            "application/geo+json",
            {"Content-Disposition": 'inline; filename="alerts.geojson"'},
        )

    def _get_kml(self, params: dict[str, str], credential: Credential) -> None:
        self._send(
            HTTPStatus.OK,
            alerts_kml(self.store.list()),
            "application/vnd.google-earth.kml+xml",
            {"Content-Disposition": 'attachment; filename="alerts.kml"'},
        )

    def _get_health(self, params: dict[str, str], credential: Credential) -> None:
        self._json(
            HTTPStatus.OK,
            {
                "ok": True,
                "alerts": self.store.count(),
                "last_event": self.store.last_event_seq(),
                "time": time.time(),
                "connections": self.feed.connections.held,
                "streams": self.feed.streams.held,
            },
        )

    def _get_alert(self, alert_id: str) -> None:
        alert = self.store.get(alert_id)
        if alert is None:
            self._error(HTTPStatus.NOT_FOUND, f"no alert {alert_id}")
        else:
            self._json(HTTPStatus.OK, alert.to_json_dict())

    def _get_thumbnail(self, alert_id: str) -> None:
        alert = self.store.get(alert_id)
        if alert is None or not alert.thumbnail:
            self._error(HTTPStatus.NOT_FOUND, f"no thumbnail for alert {alert_id}")
        else:
            self._send(HTTPStatus.OK, alert.thumbnail, "image/jpeg")

    def do_POST(self) -> None:
        url = urlsplit(self.path)
        admitted = self._admit(url.query, query_token=False)
        if admitted is None:
            return
        credential, _ = admitted
        m = _CHANGE.match(url.path)
        if m is None:
            if _is_get_route(url.path):
                self._error(HTTPStatus.METHOD_NOT_ALLOWED, "use GET")
            else:
                self._error(HTTPStatus.NOT_FOUND, "not found")
            return
        assert self.feed.guard is not None
        refusal = self.feed.guard.check_change(
            credential, self.headers.get("Origin"), self.headers.get("Host", "")
        )
        if refusal is not None:
            self._refuse(refusal)
            return
        if self.headers.get_content_type() != "application/json":
            self._error(HTTPStatus.UNSUPPORTED_MEDIA_TYPE, "send Content-Type: application/json")
            return
        alert_id, verb = m.groups()
        try:
            body = self.rfile.read(checked.content_length(self.headers))
            by = checked.ack_by(body) if verb == "ack" else checked.decided_by(body)
        except BadRequest as exc:
            self._error(HTTPStatus(exc.status), str(exc))
            return
        try:
            if verb == "ack":
                doc = self.store.acknowledge(alert_id, by).to_json_dict()
            else:
                decided = self.store.record_decision(alert_id, _DECISIONS[verb], by)
                doc = decided.alert.to_json_dict() | {"unchanged": not decided.changed}
        except KeyError:
            self._error(HTTPStatus.NOT_FOUND, f"no alert {alert_id}")
            return
        except sqlite3.Error as exc:
            self._store_failed(alert_id, verb, by, exc)
            return
        log.info(
            "alert %s: %s by %s",
            alert_id,
            "acknowledged" if verb == "ack" else _DECISIONS[verb],
            by,
        )
        self._json(HTTPStatus.OK, doc)

    def _store_failed(self, alert_id: str, verb: str, by: str, exc: sqlite3.Error) -> None:
        """Answer 503 for a change the store failed to record (e.g. locked by another process
        past its wait, or not writable): the transaction was rolled back, so nothing of it
        stands and the operator must retry. One warning line, no traceback: it is the
        store's condition, not a fault of the feed."""
        what = "acknowledgement" if verb == "ack" else "decision"
        failure = describe_failure(exc)
        log.warning(
            "feed: %s of alert %s by %s not recorded: the alert store %s",
            what,
            alert_id,
            by,
            failure,
        )
        self._error(
            HTTPStatus.SERVICE_UNAVAILABLE,
            f"the {what} was not recorded: the alert store {failure}; retry",
            {"Retry-After": "2"},
        )

    # ------------------------------------------------------------------ streams

    def _stream(self, serve: Any, *args: Any) -> None:
        """Run a stream if a stream slot is free, else answer 503."""
        streams = self.feed.streams
        if not streams.take():
            self._error(
                HTTPStatus.SERVICE_UNAVAILABLE,
                f"the feed is at its limit of {streams.cap} open streams; retry shortly",
                {"Retry-After": "5"},
            )
            return
        try:
            serve(*args)
        finally:
            streams.give()

    def _events(self, last: int | None) -> None:
        resume = last if last is not None and last <= self.store.last_event_seq() else None
        with self.store.subscribe(after=resume) as sub:
            self._start_stream("text/event-stream; charset=utf-8")
            self.wfile.write(b"retry: 1000\n\n")
            if resume is None:
                for alert in self.store.list():
                    self._sse("alert", alert, sub.cursor)
            follower = MapFollower(self.store)
            self._sse_map(follower)
            self.wfile.write(b"event: hello\ndata: {}\n\n")
            self.wfile.flush()
            idle_since = time.monotonic()
            while self._streaming():
                events = sub.get(timeout=_TICK_S)
                for event in events:
                    self._sse("alert" if event.kind == "new" else "update", event.alert, event.seq)
                if self._sse_map(follower):
                    idle_since = time.monotonic()
                if events:
                    idle_since = time.monotonic()
                elif time.monotonic() - idle_since > _KEEPALIVE_S:
                    self.wfile.write(b": keepalive\n\n")
                    idle_since = time.monotonic()
                self.wfile.flush()

    def _sse(self, name: str, alert: Alert, seq: int) -> None:
        data = json.dumps(alert.to_json_dict())
        self.wfile.write(f"event: {name}\nid: {seq}\ndata: {data}\n\n".encode())

    def _sse_map(self, follower: MapFollower) -> bool:
        """Write the map events due now (without an ``id``: they are state, not log entries,
        and must not move a reconnecting browser's place in the log); whether any were."""
        due = follower.poll()
        for name, data in due:
            self.wfile.write(f"event: {name}\ndata: {json.dumps(data)}\n\n".encode())
        return bool(due)

    def _jsonl(self, since: float | None, follow: bool) -> None:
        with self.store.subscribe() as sub:
            self._start_stream("application/x-ndjson; charset=utf-8")
            sent: set[str] = set()
            for alert in self.store.list(since):
                self._line(alert)
                sent.add(alert.alert_id)
            self.wfile.flush()
            while follow and self._streaming():
                new = [e for e in sub.get(timeout=_TICK_S) if _is_line(e, sent, since)]
                for event in new:
                    self._line(event.alert)
                    sent.add(event.alert.alert_id)
                if new:
                    self.wfile.flush()

    def _line(self, alert: Alert) -> None:
        self.wfile.write(json.dumps(alert.to_json_dict()).encode() + b"\n")


def _is_line(event: AlertEvent, sent: set[str], since: float | None) -> bool:
    """Whether a followed JSON-lines stream writes ``event``: a new alert not yet written, an
    alert's position found after it was stored, its tier settled, an operator's decision or
    its confidence rated again."""
    return (
        event.kind in _RELINED or event.kind == "new" and event.alert.alert_id not in sent
    ) and (since is None or event.alert.lock_time >= since)


#: Changes after which a followed JSON-lines stream writes the alert again.
_RELINED = frozenset(("position", "confirmed", "discarded", "decided", "rated"))


def _redact(text: str) -> str:
    """``text`` with any ``token=`` query value masked (request lines are logged)."""
    return _TOKEN_IN_TARGET.sub(r"\1***", text)


#: The GET routes of fixed paths (alerts and thumbnails by id are matched by pattern).
_GET_ROUTES: dict[str, Callable[[_Handler, dict[str, str], Credential], None]] = {
    "/": _Handler._get_page,
    "/events": _Handler._get_events,
    "/api/alerts": _Handler._get_alerts,
    "/api/map": _Handler._get_map,
    "/alerts.jsonl": _Handler._get_jsonl,
    "/alerts.geojson": _Handler._get_geojson,
    "/alerts.kml": _Handler._get_kml,
    "/healthz": _Handler._get_health,
}


def _is_get_route(path: str) -> bool:
    return path in _GET_ROUTES or bool(_ALERT.match(path) or _THUMB.match(path))
