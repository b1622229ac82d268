"""The operator feed against hostile and careless clients, over real sockets: access token on
every route, Host and Origin checks, input validation, connection and stream caps, stalled
requests, and threads given back when clients leave."""

from __future__ import annotations

import json
import logging
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from alert_samples import make_alert
from conftest import wait_until

from sarmission.alerts.feed import FeedServer
from sarmission.alerts.feed_guard import read_token_file
from sarmission.alerts.store import AlertStore
from sarmission.errors import SarmissionError

TOKEN = "feed-test-token-0123456789abcdef"


@pytest.fixture
def store(tmp_path: Path) -> Iterator[AlertStore]:
    with AlertStore(tmp_path / "alerts.db") as s:
        yield s


@pytest.fixture
def alert_id(store: AlertStore) -> str:
    alert = make_alert(1)
    store.add(alert)
    return alert.alert_id


@pytest.fixture
def secured(store: AlertStore) -> Iterator[FeedServer]:
    with FeedServer(store, port=0, token=TOKEN) as server:
        yield server


def request(
    port: int,
    method: str,
    target: str,
    headers: dict[str, str] | None = None,
    body: bytes = b"",
    host: str | None = None,
) -> tuple[int, dict[str, str], bytes]:
    """One raw HTTP/1.0 request; returns status, headers (lower-cased names) and body."""
    lines = [f"{method} {target} HTTP/1.0"]
    if host is not None:
        lines.append(f"Host: {host}")
    for name, value in (headers or {}).items():
        lines.append(f"{name}: {value}")
    if body:
        lines.append(f"Content-Length: {len(body)}")
    raw = ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + body
    return exchange(port, raw)


def exchange(port: int, raw: bytes) -> tuple[int, dict[str, str], bytes]:
    """Send ``raw`` and read the whole answer (the feed closes after each response)."""
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(raw)
        data = b""
        while chunk := sock.recv(65536):
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    status_line, *header_lines = head.decode("latin-1").split("\r\n")
    headers = {}
    for line in header_lines:
        name, _, value = line.partition(":")
        headers[name.strip().lower()] = value.strip()
    return int(status_line.split()[1]), headers, body


def get(
    feed: FeedServer, target: str, headers: dict[str, str] | None = None, host: str | None = None
) -> tuple[int, dict[str, str], bytes]:
    host = f"127.0.0.1:{feed.port}" if host is None else host
    return request(feed.port, "GET", target, headers, host=host)


def ack(
    feed: FeedServer,
    alert_id: str,
    headers: dict[str, str],
    body: bytes = b'{"by": "kim"}',
    host: str | None = None,
) -> tuple[int, dict[str, str], bytes]:
    return request(
        feed.port,
        "POST",
        f"/api/alerts/{alert_id}/ack",
        {"Content-Type": "application/json", **headers},
        body,
        host=f"127.0.0.1:{feed.port}" if host is None else host,
    )


def one_line_error(status: int, headers: dict[str, str], body: bytes, expected: int) -> str:
    """The error message of a one-line JSON error with status ``expected``."""
    assert status == expected, body
    assert headers["content-type"] == "application/json"
    assert b"\n" not in body.strip() and b"Traceback" not in body
    doc = json.loads(body)
    assert doc["status"] == expected and doc["error"]
    return doc["error"]


BEARER = {"Authorization": f"Bearer {TOKEN}"}


def first_status(feed: FeedServer, target: str, headers: dict[str, str]) -> int:
    """The status of a GET whose answer may be a stream that stays open."""
    lines = [f"GET {target} HTTP/1.0", f"Host: 127.0.0.1:{feed.port}"]
    lines += [f"{name}: {value}" for name, value in headers.items()]
    with socket.create_connection(("127.0.0.1", feed.port), timeout=10) as sock:
        sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        return int(sock.recv(4096).split(b" ", 2)[1])


def every_route(alert_id: str) -> list[str]:
    return [
        "/",
        "/events",
        "/api/alerts",
        f"/api/alerts/{alert_id}",
        "/api/map",
        "/alerts.jsonl",
        "/alerts.jsonl?follow=1",
        "/alerts.geojson",
        "/alerts.kml",
        f"/thumb/{alert_id}.jpg",
        "/healthz",
    ]


# ---------------------------------------------------------------------------- token


def test_every_route_needs_the_token(secured: FeedServer, alert_id: str) -> None:
    wrong = {"Authorization": "Bearer " + "x" * len(TOKEN)}
    for route in every_route(alert_id):
        for headers in (
            {},
            wrong,
            {"Authorization": f"Basic {TOKEN}"},
            {"Cookie": f"sarmission_feed_{secured.port}=forged"},
        ):
            status, reply_headers, body = get(secured, route, headers)
            assert one_line_error(status, reply_headers, body, 401), route
            assert reply_headers["www-authenticate"].startswith("Bearer")
            assert b"swimmer" not in body and b"\xff\xd8" not in body
        assert first_status(secured, route, BEARER) == 200, route
    status, headers, body = ack(secured, alert_id, {})
    assert one_line_error(status, headers, body, 401)
    assert status == 401 and not secured.store.get(alert_id).acknowledged
    assert ack(secured, alert_id, BEARER)[0] == 200  # a tool: token header, no Origin
    assert secured.store.get(alert_id).ack_by == "kim"


def test_query_token_on_the_page_sets_a_cookie_for_the_rest(
    secured: FeedServer, alert_id: str
) -> None:
    assert get(secured, "/?token=wrong-token-0123456789")[0] == 401
    status, headers, body = get(secured, f"/?token={TOKEN}")
    assert status == 200 and b"EventSource" in body
    cookie = headers["set-cookie"]
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie and TOKEN not in cookie
    jar = {"Cookie": cookie.split(";")[0]}
    assert get(secured, "/api/alerts", jar)[0] == 200
    assert get(secured, f"/thumb/{alert_id}.jpg", jar)[0] == 200
    # the token in other URLs is refused, so it does not spread into links and logs
    status, headers, body = get(secured, f"/api/alerts?token={TOKEN}")
    assert "Authorization" in one_line_error(status, headers, body, 400)
    # a browser's acknowledgement: cookie plus its own Origin
    origin = {"Origin": f"http://127.0.0.1:{secured.port}"}
    assert ack(secured, alert_id, {**jar, **origin})[0] == 200


def test_loopback_feed_needs_no_token_unless_given(store: AlertStore) -> None:
    with FeedServer(store, port=0) as feed:
        assert feed.token is None and feed.page_url == feed.url + "/"
        assert get(feed, "/api/alerts")[0] == 200


def test_network_bind_generates_a_token_and_warns(
    store: AlertStore, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="sarmission.alerts.feed")
    with FeedServer(store, "0.0.0.0", 0, allowed_hosts=["drone.local"]) as feed:
        assert feed.token_generated and feed.token and len(feed.token) >= 32
        assert feed.page_url.endswith(f"/?token={feed.token}")
        assert feed.page_url in feed.announcement()  # shown once, on the console
        warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
        assert any("reachable from the network" in w for w in warnings)
        assert not any(feed.token in r.getMessage() for r in caplog.records)
        assert get(feed, "/healthz")[0] == 401
        auth = {"Authorization": f"Bearer {feed.token}"}
        # a wildcard bind answers to IP literals, localhost and the names it was given
        for host in (
            f"127.0.0.1:{feed.port}",
            "10.1.2.3",
            "[::1]:80",
            "localhost",
            f"Drone.Local:{feed.port}",
        ):
            assert get(feed, "/healthz", auth, host=host)[0] == 200, host
        status, headers, body = get(feed, "/healthz", auth, host="rebind.example.com")
        assert "rebind.example.com" in one_line_error(status, headers, body, 421)


def test_bad_token_values_are_refused(store: AlertStore) -> None:
    for token in ("short", "has a space in it 0123456789", "\u00e9" * 20):
        with pytest.raises(ValueError):
            FeedServer(store, port=0, token=token)


def test_token_file(tmp_path: Path, secured: FeedServer, caplog: pytest.LogCaptureFixture) -> None:
    path = tmp_path / "feed.token"
    path.write_text(f"  {TOKEN}\n")
    path.chmod(0o600)
    assert read_token_file(path) == TOKEN
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    path.chmod(0o644)
    assert read_token_file(path) == TOKEN
    assert any("readable by other users" in r.getMessage() for r in caplog.records)
    for text in ("", "too-short", "two words 0123456789abcdef"):
        path.write_text(text)
        with pytest.raises(SarmissionError, match="feed.token"):
            read_token_file(path)
    with pytest.raises(SarmissionError, match="cannot read"):
        read_token_file(tmp_path / "missing.token")
    assert TOKEN not in secured.announcement() and "token file" in secured.announcement()


# ---------------------------------------------------------------------------- Host, Origin


def test_foreign_host_is_refused_even_with_the_token(secured: FeedServer, alert_id: str) -> None:
    for host in (
        "evil.example",
        f"evil.example:{secured.port}",
        "127.0.0.1.nip.io",
        "localhost.evil.example",
    ):
        status, headers, body = get(secured, "/api/alerts", BEARER, host=host)
        assert one_line_error(status, headers, body, 421)
        assert ack(secured, alert_id, BEARER, host=host)[0] == 421
    for host in ("", "a b", "[::1", "127.0.0.1:port", "x" * 400):
        status, headers, body = get(secured, "/api/alerts", BEARER, host=host)
        assert one_line_error(status, headers, body, 400)
    status, headers, body = request(secured.port, "GET", "/api/alerts", BEARER)  # no Host
    assert "Host" in one_line_error(status, headers, body, 400)
    status, headers, body = get(
        secured, "/api/alerts", BEARER, host=f"127.0.0.1:{secured.port}\r\nHost: evil.example"
    )
    assert "Host" in one_line_error(status, headers, body, 400)
    assert not secured.store.get(alert_id).acknowledged


def test_dns_rebinding_against_a_loopback_feed_is_refused(store: AlertStore, alert_id: str) -> None:
    with FeedServer(store, port=0) as feed:  # no token: the Host check is the defence
        host = f"attacker.example:{feed.port}"
        assert get(feed, "/api/alerts", host=host)[0] == 421
        origin = {"Origin": f"http://{host}"}
        assert ack(feed, alert_id, origin, host=host)[0] == 421
        assert get(feed, "/api/alerts", host=f"localhost:{feed.port}")[0] == 200
        assert not store.get(alert_id).acknowledged


def test_foreign_origin_cannot_acknowledge(secured: FeedServer, alert_id: str) -> None:
    status, headers, body = get(secured, f"/?token={TOKEN}")
    jar = {"Cookie": headers["set-cookie"].split(";")[0]}
    port = secured.port
    for origin in (
        "http://evil.example",
        f"http://evil.example:{port}",
        "null",
        f"https://127.0.0.1:{port}",
        f"http://127.0.0.1:{port + 1}",
        "http://[::1",
    ):
        for credential in (jar, BEARER):
            status, headers, body = ack(secured, alert_id, {**credential, "Origin": origin})
            assert one_line_error(status, headers, body, 403), origin
    # the page's cookie without Origin is not a browser: it must use the token header
    assert ack(secured, alert_id, jar)[0] == 403
    assert not secured.store.get(alert_id).acknowledged
    same = {"Origin": f"http://127.0.0.1:{port}"}
    assert ack(secured, alert_id, {**jar, **same})[0] == 200


# ---------------------------------------------------------------------------- input


def test_bad_last_event_id_is_a_400_not_a_traceback(
    secured: FeedServer, caplog: pytest.LogCaptureFixture
) -> None:
    for value in ("9" * 5000, "12abc", "-1", "1.5", "\u00b9\u00b2", "0x10", "1 2"):
        status, headers, body = get(secured, "/events", {**BEARER, "Last-Event-ID": value})
        assert "Last-Event-ID" in one_line_error(status, headers, body, 400), value
    status, headers, body = request(
        secured.port,
        "GET",
        "/events",
        {**BEARER, "Last-Event-ID": "1"},
        host=f"127.0.0.1:{secured.port}\r\nLast-Event-ID: 2",
    )
    assert one_line_error(status, headers, body, 400)
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR]


def test_bad_query_parameters_are_one_line_400s(secured: FeedServer) -> None:
    for target in (
        "/api/alerts?since=nan",
        "/api/alerts?since=inf",
        "/api/alerts?since=",
        "/api/alerts?since=1e999",
        "/api/alerts?since=" + "1" * 100,
        "/api/alerts?since=1&since=2",
        "/api/alerts?sinse=1",
        "/alerts.jsonl?follow=2",
        "/alerts.jsonl?follow=1&x=1",
        "/healthz?x",
        "/api/alerts?since=%ff",
        "/api/alerts?" + "&".join(f"a{i}=1" for i in range(20)),
    ):
        status, headers, body = get(secured, target, BEARER)
        assert one_line_error(status, headers, body, 400), target
    status, headers, body = get(secured, "/api/alerts?x=" + "y" * 3000, BEARER)
    assert one_line_error(status, headers, body, 414)
    assert get(secured, "/api/alerts?since=1700000000.5", BEARER)[0] == 200
    assert get(secured, "/alerts.jsonl?follow=no", BEARER)[0] == 200


def test_bad_ack_requests_are_one_line_errors(
    secured: FeedServer, alert_id: str, caplog: pytest.LogCaptureFixture
) -> None:
    cases: list[tuple[dict[str, str], bytes, int]] = [
        ({}, b'{"by": 42}', 400),
        ({}, b'{"by": ""}', 400),
        ({}, b'{"by": "' + b"n" * 65 + b'"}', 400),
        ({}, b'{"by": "bell\\u0007"}', 400),
        ({}, b'{"by": "kim", "admin": true}', 400),
        ({}, b'["kim"]', 400),
        ({}, b"[" * 4000, 400),
        ({}, b"\xff\xfe", 400),
        ({}, b"{" + b" " * 5000 + b"}", 413),
    ]
    for headers, body, expected in cases:
        status, reply_headers, reply = ack(secured, alert_id, {**BEARER, **headers}, body)
        assert one_line_error(status, reply_headers, reply, expected), body[:40]
    target = f"/api/alerts/{alert_id}/ack"
    base = (
        f"POST {target} HTTP/1.0\r\nHost: 127.0.0.1:{secured.port}\r\n"
        f"Authorization: Bearer {TOKEN}\r\nContent-Type: application/json\r\n"
    )
    for extra, expected in (
        ("Content-Length: ten\r\n", 400),
        ("Content-Length: -1\r\n", 400),
        ("Content-Length: 99999999999999999999\r\n", 400),
        ("Content-Length: 2\r\nContent-Length: 2\r\n", 400),
        ("Transfer-Encoding: chunked\r\n", 411),
    ):
        status, headers, body = exchange(secured.port, (base + extra + "\r\n{}").encode())
        assert one_line_error(status, headers, body, expected), extra
    assert not secured.store.get(alert_id).acknowledged
    # what the HTTP parser itself refuses is JSON too
    status, headers, body = request(
        secured.port, "DELETE", "/api/alerts", BEARER, host=f"127.0.0.1:{secured.port}"
    )
    assert one_line_error(status, headers, body, 501)
    status, headers, body = exchange(secured.port, b"GET /" + b"a" * 70000 + b" HTTP/1.0\r\n\r\n")
    assert one_line_error(status, headers, body, 414)
    status, headers, body = exchange(secured.port, b"NONSENSE\r\n\r\n")
    assert one_line_error(status, headers, body, 400)
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR]


def test_decisions_are_guarded_like_acknowledgements(
    secured: FeedServer, alert_id: str, caplog: pytest.LogCaptureFixture
) -> None:
    port = secured.port
    evil = {"Origin": "http://evil.example"}

    def post(
        verb: str,
        headers: dict[str, str],
        body: bytes = b'{"by": "kim"}',
        content_type: str = "application/json",
    ) -> tuple[int, dict[str, str], bytes]:
        return request(
            port,
            "POST",
            f"/api/alerts/{alert_id}/{verb}",
            {"Content-Type": content_type, **headers},
            body,
            host=f"127.0.0.1:{port}",
        )

    for verb in ("confirm", "dismiss"):
        assert one_line_error(*post(verb, {}), 401)
        assert one_line_error(*post(verb, {**BEARER, **evil}), 403)
        assert one_line_error(*post(verb, BEARER, content_type="text/plain"), 415)
        assert one_line_error(
            *request(
                port,
                "POST",
                f"/api/alerts/{alert_id}/{verb}",
                BEARER,
                b'{"by": "kim"}',
                host=f"evil.example:{port}",
            ),
            421,
        )
        for body, expected in (
            (b"{}", 400),
            (b'{"by": "  "}', 400),
            (b'{"by": null}', 400),
            (b'{"by": "kim", "when": 1}', 400),
            (b"[" * 4000, 400),
            (b'{"by": "' + b"n" * 65 + b'"}', 400),
            (b"\xff", 400),
            (b"{" + b" " * 5000 + b"}", 413),
        ):
            assert one_line_error(*post(verb, BEARER, body), expected), (verb, body[:30])
        assert "no alert" in one_line_error(
            *request(
                port,
                "POST",
                "/api/alerts/unknown-id/" + verb,
                {"Content-Type": "application/json", **BEARER},
                b'{"by": "kim"}',
                host=f"127.0.0.1:{port}",
            ),
            404,
        )
    alert = secured.store.get(alert_id)
    assert alert.decision is None and secured.store.decisions(alert_id) == []
    status, _, body = post("dismiss", BEARER)
    assert status == 200 and json.loads(body)["decided_by"] == "kim"
    for target in ("/api/map?mission=", "/api/map?since=x", "/api/map?mission=m&token=x"):
        assert one_line_error(*get(secured, target, BEARER), 400), target
    assert not [r for r in caplog.records if r.levelno >= logging.ERROR]


# ---------------------------------------------------------------------------- limits


def idle_sockets(port: int, n: int) -> list[socket.socket]:
    return [socket.create_connection(("127.0.0.1", port), timeout=10) for _ in range(n)]


def test_connection_cap_answers_503_and_recovers(store: AlertStore) -> None:
    with FeedServer(store, port=0, max_connections=4, max_streams=2, request_timeout=60.0) as feed:
        held = idle_sockets(feed.port, 4)
        try:
            assert wait_until(lambda: feed.connections.held == 4, timeout=10)
            status, headers, body = get(feed, "/healthz")
            assert "limit of 4 connections" in one_line_error(status, headers, body, 503)
            assert headers["retry-after"] == "5"
        finally:
            for sock in held:
                sock.close()
        assert wait_until(lambda: get(feed, "/healthz")[0] == 200, timeout=15)


def test_stream_cap_answers_503_and_recovers(store: AlertStore) -> None:
    with FeedServer(store, port=0, max_streams=2) as feed:
        streams = [socket.create_connection(("127.0.0.1", feed.port), timeout=10) for _ in range(2)]
        try:
            for sock, target in zip(streams, ("/events", "/alerts.jsonl?follow=1"), strict=True):
                sock.sendall(f"GET {target} HTTP/1.0\r\nHost: localhost\r\n\r\n".encode())
                assert sock.recv(4096).startswith(b"HTTP/1.0 200")
            status, headers, body = get(feed, "/events")
            assert "open streams" in one_line_error(status, headers, body, 503)
            assert get(feed, "/api/alerts")[0] == 200  # plain requests still served
        finally:
            for sock in streams:
                sock.close()
        assert wait_until(lambda: feed.streams.held == 0, timeout=15)
        assert get(feed, "/alerts.jsonl?follow=0")[0] == 200
        status, headers, _ = get(feed, "/healthz")
        assert status == 200


def closed_by_server(sock: socket.socket) -> bytes | None:
    """What the server sent before closing ``sock``, or None while it is still open."""
    sock.setblocking(False)
    data = b""
    try:
        while chunk := sock.recv(65536):
            data += chunk
        return data
    except BlockingIOError:
        return None
    except ConnectionError:
        return data


def test_stalled_and_trickling_requests_are_closed(store: AlertStore) -> None:
    with FeedServer(store, port=0, request_timeout=1.0) as feed:
        silent = socket.create_connection(("127.0.0.1", feed.port), timeout=10)
        trickle = socket.create_connection(("127.0.0.1", feed.port), timeout=10)
        done: dict[str, bytes] = {}
        stop = threading.Event()

        def drip() -> None:  # one byte every 0.1 s: never idle, never finished
            for byte in b"GET /api/alerts HTTP/1.0\r\nHost: localhost\r\nX-Pad: " + b"a" * 500:
                if stop.wait(0.1):
                    return
                try:
                    trickle.send(bytes([byte]))
                except OSError:
                    return

        dripper = threading.Thread(target=drip, daemon=True)
        dripper.start()
        try:

            def both_closed() -> bool:
                for name, sock in (("silent", silent), ("trickle", trickle)):
                    if name not in done and (answer := closed_by_server(sock)) is not None:
                        done[name] = answer
                return len(done) == 2

            assert wait_until(both_closed, timeout=30, step=0.1)
            for answer in done.values():
                assert answer.startswith(b"HTTP/1.0 408") and b'"status": 408' in answer
            assert wait_until(lambda: feed.connections.held == 0, timeout=10)
        finally:
            stop.set()
            dripper.join()
            silent.close()
            trickle.close()


def request_threads() -> int:
    """Threads serving a request (socketserver names them after process_request_thread); other
    tests' stray threads may come and go meanwhile, so the whole process count would not do."""
    return sum("process_request_thread" in t.name for t in threading.enumerate())


def test_threads_come_back_when_clients_leave(store: AlertStore) -> None:
    with FeedServer(store, port=0, max_connections=64, max_streams=40, request_timeout=1.0) as feed:
        assert get(feed, "/healthz")[0] == 200
        assert wait_until(lambda: request_threads() == 0, timeout=10)
        stalled = idle_sockets(feed.port, 10)  # kept open: the server must drop them itself
        streams = []
        for i in range(40):
            target = "/events" if i % 2 else "/alerts.jsonl?follow=1"
            sock = socket.create_connection(("127.0.0.1", feed.port), timeout=10)
            sock.sendall(f"GET {target} HTTP/1.0\r\nHost: localhost\r\n\r\n".encode())
            streams.append(sock)
        try:
            for sock in streams:
                assert sock.recv(4096).startswith(b"HTTP/1.0 200")
            assert wait_until(lambda: feed.streams.held == 40, timeout=10)
            assert request_threads() >= 40
        finally:
            for sock in streams:
                sock.close()
        try:
            assert wait_until(lambda: request_threads() == 0, timeout=30), (
                f"{request_threads()} request threads left"
            )
            assert feed.connections.held == 0 and feed.streams.held == 0
        finally:
            for sock in stalled:
                sock.close()
