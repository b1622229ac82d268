"""The team's TAK gets each confirmed alert as a CoT marker over real sockets: sent when
confirmed, moved when refined, renewed every refresh, deleted when an operator dismisses it;
candidates never; a TAK Server that is down costs warnings, not the mission."""

from __future__ import annotations

import socket
import ssl
import threading
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from alert_samples import make_alert
from conftest import wait_until

from sarmission.alerts.cot import COT_TYPE, COT_TYPE_DELETE, CotSender
from sarmission.alerts.cot_relay import CotRelay
from sarmission.alerts.store import AlertStore
from sarmission.errors import SarmissionError

#: Test-only TLS material (tests/fixtures/tak_tls/README.md).
TLS = Path(__file__).parent / "fixtures" / "tak_tls"


class UdpTak:
    """A TAK client's UDP input: every datagram, parsed."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.1)
        self.url = f"udp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.events: list[ET.Element] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            self.events.append(ET.fromstring(data))

    def of(self, uid: str) -> list[ET.Element]:
        return [e for e in self.events if e.get("uid") == uid]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        self.sock.close()


@pytest.fixture
def tak():
    receiver = UdpTak()
    yield receiver
    receiver.close()


def point(event: ET.Element) -> tuple[float, float, float]:
    p = event.find("point")
    assert p is not None
    return float(p.get("lat")), float(p.get("lon")), float(p.get("ce"))


def test_confirmed_alerts_go_out_move_when_refined_and_leave_when_dismissed(tmp_path, tak):
    with AlertStore(tmp_path / "alerts.db") as store:
        earlier = make_alert(1)  # confirmed in an earlier run of the mission
        store.add(earlier)
        candidate = make_alert(2, tier="candidate")
        store.add(candidate)
        other_mission = make_alert(3, mission_id="elsewhere")
        store.add(other_mission)
        relay = CotRelay(store, [CotSender(tak.url)], "test-mission", refresh_s=0.5).start()
        try:
            assert wait_until(lambda: tak.of(earlier.cot_uid), 5.0)
            assert point(tak.of(earlier.cot_uid)[0])[:2] == pytest.approx(earlier.position)
            assert tak.of(earlier.cot_uid)[0].get("type") == COT_TYPE
            # the candidate is confirmed: its marker appears
            store.promote(candidate.alert_id, "2.0 s, 31 sightings")
            assert wait_until(lambda: tak.of(candidate.cot_uid), 5.0)
            # its position is refined: the same marker moves, with the new error
            moved = (candidate.position[0] + 1e-4, candidate.position[1])
            store.refine_position(candidate.alert_id, moved, 1.5, "ground plane", "refined")
            assert wait_until(lambda: point(tak.of(candidate.cot_uid)[-1])[:2] == moved, 5.0)
            assert point(tak.of(candidate.cot_uid)[-1])[2] == 1.5
            # renewed every refresh without any change
            n = len(tak.of(earlier.cot_uid))
            assert wait_until(lambda: len(tak.of(earlier.cot_uid)) >= n + 2, 5.0)
            # dismissed by an operator: one delete event for its marker, and no more refreshes
            store.record_decision(earlier.alert_id, "dismissed", "op")
            assert wait_until(lambda: tak.of(f"{earlier.cot_uid}.delete"), 5.0)
            (delete,) = tak.of(f"{earlier.cot_uid}.delete")
            assert delete.get("type") == COT_TYPE_DELETE
            assert delete.find("detail/link").get("uid") == earlier.cot_uid
            n = len(tak.of(earlier.cot_uid))
            later = len(tak.of(candidate.cot_uid))
            assert wait_until(lambda: len(tak.of(candidate.cot_uid)) >= later + 2, 5.0)
            assert len(tak.of(earlier.cot_uid)) == n
        finally:
            relay.stop()
        assert tak.of(other_mission.cot_uid) == []
        sent = store.get(candidate.alert_id).sent["cot"]
        assert sent.count >= 3 and relay.sent >= sent.count
        assert relay.deleted == 1 and "1 markers deleted" in relay.summary()


def test_a_marker_says_again_how_likely_a_person_once_decisions_rate_it_again(tmp_path, tak):
    """An operator's decision on one alert rates the mission's undecided alerts again: their
    markers go out at once with the new confidence in their remarks, and the refresh sends
    that confidence, not the one first sent."""
    with AlertStore(tmp_path / "alerts.db") as store:
        ids = []
        for target in (1, 2):
            alert = make_alert(target, tier="candidate")
            store.add(alert)
            store.promote(alert.alert_id, "held 3 s", 1.7e9 + target, -2.0)
            ids.append(alert.alert_id)
        first, second = (store.get(i) for i in ids)
        before = first.format_confidence()
        assert before
        relay = CotRelay(store, [CotSender(tak.url)], "test-mission", refresh_s=60.0).start()
        try:
            assert wait_until(lambda: tak.of(second.cot_uid), 5.0)
            assert before in tak.of(second.cot_uid)[-1].find("detail/remarks").text
            store.decide(first.alert_id, "confirmed", "ana")
            after = store.get(second.alert_id).format_confidence()
            assert after != before
            assert wait_until(
                lambda: after in tak.of(second.cot_uid)[-1].find("detail/remarks").text, 5.0
            )
            relay.refresh()
            assert after in tak.of(second.cot_uid)[-1].find("detail/remarks").text
        finally:
            relay.stop()


def test_what_is_confirmed_just_before_stop_still_goes_out(tmp_path, tak):
    with AlertStore(tmp_path / "alerts.db") as store:
        relay = CotRelay(store, [CotSender(tak.url)], "test-mission").start()
        alert = make_alert(1)
        store.add(alert)
        relay.stop()
        assert wait_until(lambda: tak.of(alert.cot_uid), 2.0)


def test_a_tak_server_that_is_down_costs_warnings_then_gets_the_marker(tmp_path, caplog):
    """TCP to a port nobody listens on: the sends fail and are warned about; once the server
    is up, the next refresh delivers the marker."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with AlertStore(tmp_path / "alerts.db") as store:
        alert = make_alert(1)
        store.add(alert)
        with caplog.at_level("WARNING"):
            relay = CotRelay(
                store, [CotSender(f"tcp://127.0.0.1:{port}", 0.5)], "test-mission", refresh_s=0.3
            ).start()
        try:
            assert relay.failures.total >= 1 and relay.sent == 0
            assert any("CoT to tcp://127.0.0.1:" in r.getMessage() for r in caplog.records)
            # the next change (or refresh) makes the relay try again
            server = socket.socket()
            server.bind(("127.0.0.1", port))
            server.listen()
            server.settimeout(5.0)
            store.refine_position(alert.alert_id, alert.position, 3.0, "ground plane", "refined")
            conn, _ = server.accept()
            conn.settimeout(5.0)
            data = b""
            while b"</event>" not in data:
                data += conn.recv(65536)
            assert ET.fromstring(data[: data.index(b"</event>") + 8]).get("uid") == alert.cot_uid
            conn.close()
            server.close()
        finally:
            relay.stop()
        assert "sends failed" in relay.summary()


class FlakySender(CotSender):
    """A UDP sender whose sends fail while ``down`` (a TAK Server unreachable)."""

    def __init__(self, url: str) -> None:
        super().__init__(url)
        self.down = False
        self.failed = 0

    def send(self, event: bytes) -> None:
        if self.down:
            self.failed += 1
            raise ConnectionRefusedError("TAK Server down")
        super().send(event)


def test_a_dismissal_while_tak_is_down_deletes_the_marker_once_it_is_back(tmp_path, tak):
    """The delete that failed is tried again at the refresh, and the dismissed marker is
    never sent again."""
    with AlertStore(tmp_path / "alerts.db") as store:
        alert = make_alert(1)
        store.add(alert)
        sender = FlakySender(tak.url)
        relay = CotRelay(store, [sender], "test-mission", refresh_s=0.3).start()
        try:
            assert wait_until(lambda: tak.of(alert.cot_uid), 5.0)
            sender.down = True
            store.record_decision(alert.alert_id, "dismissed", "op")
            assert wait_until(lambda: sender.failed >= 2, 5.0)  # the delete and its retry
            markers = len(tak.of(alert.cot_uid))
            sender.down = False
            assert wait_until(lambda: tak.of(f"{alert.cot_uid}.delete"), 5.0)
            sends = store.get(alert.alert_id).sent["cot"].count
            assert (
                wait_until(lambda: store.get(alert.alert_id).sent["cot"].count > sends, 1.0)
                is False
            )
        finally:
            relay.stop()
        assert len(tak.of(alert.cot_uid)) == markers
        assert len(tak.of(f"{alert.cot_uid}.delete")) == 1
        assert relay.deleted == 1 and "0 live" in relay.summary()


def test_a_position_refined_while_tak_is_down_goes_out_at_the_next_refresh(tmp_path, tak):
    """A refresh sends the alert as the store holds it now, not as it was last sent."""
    with AlertStore(tmp_path / "alerts.db") as store:
        alert = make_alert(1)
        store.add(alert)
        sender = FlakySender(tak.url)
        relay = CotRelay(store, [sender], "test-mission", refresh_s=0.3).start()
        try:
            assert wait_until(lambda: tak.of(alert.cot_uid), 5.0)
            sender.down = True
            before = len(tak.of(alert.cot_uid))
            moved = (alert.position[0] + 1e-4, alert.position[1])
            store.refine_position(alert.alert_id, moved, 1.5, "ground plane", "refined")
            assert wait_until(lambda: sender.failed >= 1, 5.0)
            sender.down = False
            assert wait_until(lambda: len(tak.of(alert.cot_uid)) > before + 1, 5.0)
            assert all(point(e) == (*moved, 1.5) for e in tak.of(alert.cot_uid)[before:])
        finally:
            relay.stop()


def test_a_relay_started_after_a_dismissal_deletes_the_marker_sent_before(tmp_path, tak):
    """The relay stopped (a restart) between an alert's marker and its dismissal: the next
    one deletes the marker the store says went out; a dismissed alert never sent is left
    alone."""
    with AlertStore(tmp_path / "alerts.db") as store:
        sent, never_sent = make_alert(1), make_alert(2)
        store.add(sent)
        relay = CotRelay(store, [CotSender(tak.url)], "test-mission").start()
        assert wait_until(lambda: tak.of(sent.cot_uid), 5.0)
        relay.stop()
        store.add(never_sent)
        store.record_decision(sent.alert_id, "dismissed", "op")
        store.record_decision(never_sent.alert_id, "dismissed", "op")
        relay = CotRelay(store, [CotSender(tak.url)], "test-mission").start()
        try:
            assert wait_until(lambda: tak.of(f"{sent.cot_uid}.delete"), 5.0)
        finally:
            relay.stop()
        assert len(tak.of(sent.cot_uid)) == 1
        assert tak.of(never_sent.cot_uid) == tak.of(f"{never_sent.cot_uid}.delete") == []
        assert relay.deleted == 1


@pytest.mark.parametrize(
    "url", ["http://tak:8087", "udp://:6969", "tcp://tak", "239.2.3.1:6969", "tls://tak:x"]
)
def test_a_mistyped_destination_is_a_clear_error(url):
    with pytest.raises(SarmissionError, match="must be udp://host:port, tcp://host:port or tls"):
        CotSender(url)


@pytest.mark.parametrize(
    "query, expected",
    [
        ("?cert=nope.pem", r"client certificate 'nope.pem'"),
        ("?ca=nope.pem", r"CA file 'nope.pem'"),
        ("?cert={d}/ca.pem", r"client certificate"),  # a certificate without its key
        ("?key={d}/client.key", "key= needs its cert="),
        ("?cert={d}/client.pem&key={d}/client.key&pin=1", "unknown pin"),
        ("?cert=", "cert needs one file name"),
    ],
)
def test_a_tls_destination_with_unusable_files_is_a_clear_error(query, expected):
    """The files are read when the sender is made (at argument parsing), not at the first send."""
    with pytest.raises(SarmissionError, match=expected):
        CotSender("tls://127.0.0.1:8089" + query.format(d=TLS))
    with pytest.raises(SarmissionError, match="only tls:// takes"):
        CotSender(f"tcp://127.0.0.1:8087?ca={TLS}/ca.pem")


class TlsTak:
    """A TAK Server's TLS input: server certificate of :data:`TLS`'s CA, client certificates
    required; every event of every connection, parsed; handshakes that failed counted."""

    def __init__(self) -> None:
        self.context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH, cafile=TLS / "ca.pem")
        self.context.load_cert_chain(TLS / "server.pem", TLS / "server.key")
        self.context.verify_mode = ssl.CERT_REQUIRED
        self.server = socket.socket()
        self.server.bind(("127.0.0.1", 0))
        self.server.listen()
        self.server.settimeout(0.1)
        self.port = self.server.getsockname()[1]
        self.events: list[ET.Element] = []
        self.clients: list[str] = []
        self.refused = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.server.accept()
            except TimeoutError:
                continue
            conn.settimeout(5.0)
            try:
                tls = self.context.wrap_socket(conn, server_side=True)
            except (ssl.SSLError, OSError):
                self.refused += 1
                conn.close()
                continue
            subject = dict(x[0] for x in tls.getpeercert()["subject"])
            self.clients.append(subject["commonName"])
            data = b""
            with tls:
                while not self._stop.is_set():
                    try:
                        chunk = tls.recv(65536)
                    except (TimeoutError, ssl.SSLError, OSError):
                        break
                    if not chunk:
                        break
                    data += chunk
                    while b"</event>" in data:
                        end = data.index(b"</event>") + len(b"</event>")
                        self.events.append(ET.fromstring(data[:end]))
                        data = data[end:]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(6)
        self.server.close()


def test_a_tak_server_over_tls_gets_the_marker_from_a_known_drone_only(tmp_path, caplog):
    """Mutual TLS to a TAK Server's 8089-style input: with the team's CA and the drone's client
    certificate the marker arrives (the server saw the drone's certificate); a sender that
    trusts another CA refuses the server, and one without a certificate is refused by it:
    warnings, never a marker sent in the clear."""
    tak = TlsTak()
    base = f"tls://127.0.0.1:{tak.port}"
    good = CotSender(f"{base}?cert={TLS}/client.pem&key={TLS}/client.key&ca={TLS}/ca.pem")
    wrong_ca = CotSender(f"ssl://127.0.0.1:{tak.port}?ca={TLS}/other_ca.pem", 2.0)
    no_cert = CotSender(f"{base}?ca={TLS}/ca.pem", 2.0)
    try:
        with AlertStore(tmp_path / "alerts.db") as store:
            alert = make_alert(1)
            store.add(alert)
            with caplog.at_level("WARNING"):
                relay = CotRelay(store, [wrong_ca, no_cert, good], "test-mission").start()
                try:
                    assert wait_until(lambda: tak.events, 5.0)
                finally:
                    relay.stop()
            (event,) = [e for e in tak.events if e.get("uid") == alert.cot_uid][:1]
            assert point(event)[:2] == pytest.approx(alert.position)
            assert tak.clients[0] == "sarmission test drone"
            assert store.get(alert.alert_id).sent["cot"].count >= 1
            # the server's certificate was refused by the sender that trusts another CA
            assert any("certificate verify failed" in r.getMessage() for r in caplog.records)
            # under TLS 1.3 the sender without a certificate may learn of its refusal only
            # after its send; the server never let it through
            assert wait_until(lambda: tak.refused >= 1, 5.0)
            assert len(tak.clients) == 1  # nobody else got through
    finally:
        tak.close()
