"""Cursor-on-Target (CoT 2.0) events for TAK clients (ATAK, WinTAK, iTAK, TAK Server).

Each alert with a position becomes an event of type ``b-r-f-h-c`` ("casualty / CASEVAC
request", drawn by ATAK as a casualty marker), the closest standard CoT type for "a person in
distress here"; ``a-h-G`` would mark a hostile ground unit, which is wrong for rescue. A
life-saving appliance (:mod:`sarmission.class_roles`) is no casualty: it becomes a plain spot
marker (``b-m-p-s-m``) named "life ring".
``how="m-g"`` says it is machine generated. The uid is stable per target
(:attr:`Alert.cot_uid`), so a re-sent event updates the same marker. ``point`` carries the
position at full precision, ``ce`` the horizontal error radius in metres, ``hae`` the height
above the ellipsoid when known; unknown values are 9999999.0, per the CoT schema. A target whose
drift was estimated carries it as ``track`` (course in degrees true, speed in m/s), which TAK
draws as the marker's motion: where a drifting swimmer will be.

:class:`CotSender` sends events to ``udp://host:port`` (e.g. the SA multicast group
``udp://239.2.3.1:6969`` or a TAK client's unicast port 4242), ``tcp://host:port`` (a TAK Server's
plain streaming input, usually 8087) or ``tls://host:port`` (its TLS input, usually 8089, which
asks for a client certificate: ``?cert=client.pem&key=client.key&ca=ca.pem``, PEM files as
``openssl pkcs12`` writes them from the server's ``.p12``; ``ssl://`` is the same).
:func:`cot_delete` takes a marker off the map again (an alert an operator dismissed).
:mod:`sarmission.alerts.cot_relay` sends a mission's alerts as they change.
"""

from __future__ import annotations

import socket
import ssl
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from urllib.parse import parse_qs, urlsplit

from sarmission.alerts.model import Alert, drift_course_speed, plain_decimal, utc_iso
from sarmission.class_roles import role_of, short_label
from sarmission.errors import SarmissionError

COT_TYPE = "b-r-f-h-c"
#: A life-saving appliance seen without a person: a plain spot marker, not a casualty.
COT_TYPE_APPLIANCE = "b-m-p-s-m"
#: TAK's "delete this map item" (the item named in the event's ``link``).
COT_TYPE_DELETE = "t-x-d-d"
COT_HOW = "m-g"
#: CoT's value for "unknown" in ``hae``, ``ce`` and ``le``.
COT_UNKNOWN = 9999999.0


def alert_to_cot(alert: Alert, now: float | None = None, stale_after_s: float = 3600.0) -> bytes:
    """The alert as a CoT XML event (UTF-8 bytes, with XML declaration). ``time`` is ``now``
    (default: the current time), ``start`` the lock time, ``stale`` ``now + stale_after_s``.
    Raises ValueError for an alert without a position: CoT has no way to say "somewhere"; and
    for a candidate or an alert an operator dismissed: only confirmed alerts go to the team."""
    if alert.position is None:
        raise ValueError(f"alert {alert.alert_id} has no position; it cannot become a CoT event")
    if alert.tier != "confirmed" or alert.dismissed:
        state = "was dismissed" if alert.dismissed else "is an unconfirmed candidate"
        raise ValueError(f"alert {alert.alert_id} {state}; only confirmed alerts go out as CoT")
    now = time.time() if now is None else now
    lat, lon = alert.position
    event = ET.Element(
        "event",
        {
            "version": "2.0",
            "uid": alert.cot_uid,
            "type": COT_TYPE_APPLIANCE if role_of(alert.class_name) == "appliance" else COT_TYPE,
            "how": COT_HOW,
            "time": utc_iso(now),
            "start": utc_iso(alert.lock_time),
            "stale": utc_iso(now + stale_after_s),
        },
    )
    ET.SubElement(
        event,
        "point",
        {
            "lat": plain_decimal(lat),
            "lon": plain_decimal(lon),
            "hae": plain_decimal(COT_UNKNOWN if alert.target_hae_m is None else alert.target_hae_m),
            "ce": plain_decimal(COT_UNKNOWN if alert.error_m is None else alert.error_m),
            "le": plain_decimal(COT_UNKNOWN),
        },
    )
    detail = ET.SubElement(event, "detail")
    label = short_label(alert.class_name)
    ET.SubElement(detail, "contact", {"callsign": f"SAR T{alert.target_id} {label}"})
    remarks = ET.SubElement(detail, "remarks")
    remarks.text = (
        f"{label} score {alert.format_score()}, target {alert.target_id}, "
        f"mission {alert.mission_id}, locked {utc_iso(alert.lock_time)}, "
        f"error {alert.format_error() or 'unknown'}, alert {alert.alert_id}"
        + (
            ""
            if alert.position_time is None
            else f", position as of {utc_iso(alert.position_time)}"
        )
        + ("" if alert.drift_ne is None else f", {alert.format_drift()}")
    )
    if alert.drift_ne is not None:  # TAK draws the marker's motion from course and speed
        course, speed = drift_course_speed(alert.drift_ne)
        ET.SubElement(detail, "track", {"course": f"{course:.1f}", "speed": f"{speed:.2f}"})
    ET.SubElement(
        detail,
        "precisionlocation",
        {"geopointsrc": "CALC", "altsrc": "???" if alert.target_hae_m is None else "CALC"},
    )
    return ET.tostring(event, encoding="utf-8", xml_declaration=True)


def cot_delete(uid: str, now: float | None = None) -> bytes:
    """A delete event (type ``t-x-d-d``, TAK's "delete this map item") for the marker ``uid``:
    what an operator dismissed comes off the team's maps. Its point is CoT's unknown one."""
    now = time.time() if now is None else now
    event = ET.Element(
        "event",
        {
            "version": "2.0",
            "uid": f"{uid}.delete",
            "type": COT_TYPE_DELETE,
            "how": COT_HOW,
            "time": utc_iso(now),
            "start": utc_iso(now),
            "stale": utc_iso(now + 60.0),
        },
    )
    unknown = plain_decimal(COT_UNKNOWN)
    ET.SubElement(
        event, "point", {"lat": "0", "lon": "0", "hae": unknown, "ce": unknown, "le": unknown}
    )
    detail = ET.SubElement(event, "detail")
    ET.SubElement(detail, "link", {"uid": uid, "relation": "none", "type": "none"})
    ET.SubElement(detail, "__forcedelete")
    return ET.tostring(event, encoding="utf-8", xml_declaration=True)


#: The query keys of a TLS destination: its CA bundle, client certificate and client key.
TLS_KEYS = ("ca", "cert", "key")


@dataclass(frozen=True)
class CotDestination:
    """A parsed CoT destination: ``scheme`` (udp, tcp or tls), ``host``, ``port`` and, for TLS,
    the PEM files (None: the system's trusted CAs; no client certificate)."""

    url: str
    scheme: str
    host: str
    port: int
    ca: str | None = None
    cert: str | None = None
    key: str | None = None


def parse_cot_url(url: str) -> CotDestination:
    """``udp://host:port``, ``tcp://host:port`` or ``tls://host:port?cert=F&key=F&ca=F``
    (``ssl://`` as ``tls://``) as a :class:`CotDestination`; opens no file. Raises
    :class:`SarmissionError` with one line saying what is wrong."""
    usage = (
        f"CoT destination {url!r} must be udp://host:port, tcp://host:port or "
        "tls://host:port[?cert=FILE&key=FILE&ca=FILE]"
    )
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError:
        raise SarmissionError(usage) from None
    scheme = "tls" if parts.scheme == "ssl" else parts.scheme
    if scheme not in ("udp", "tcp", "tls") or not parts.hostname or port is None:
        raise SarmissionError(usage)
    if parts.path not in ("", "/") or parts.fragment:
        raise SarmissionError(usage)
    query = parse_qs(parts.query, keep_blank_values=True, strict_parsing=False)
    if query and scheme != "tls":
        raise SarmissionError(f"CoT destination {url!r}: only tls:// takes ?{'&'.join(query)}")
    unknown = sorted(set(query) - set(TLS_KEYS))
    if unknown:
        raise SarmissionError(
            f"CoT destination {url!r}: unknown {', '.join(unknown)} (known: {', '.join(TLS_KEYS)})"
        )
    files: dict[str, str] = {}
    for name, values in query.items():
        if len(values) != 1 or not values[0]:
            raise SarmissionError(f"CoT destination {url!r}: {name} needs one file name")
        files[name] = values[0]
    if "key" in files and "cert" not in files:
        raise SarmissionError(f"CoT destination {url!r}: key= needs its cert=")
    return CotDestination(url, scheme, parts.hostname, port, **files)


def tls_context(dest: CotDestination) -> ssl.SSLContext:
    """The client TLS context of ``dest``: the server verified against ``ca`` (or the system's
    CAs) and its host name; the client certificate presented when given. Raises
    :class:`SarmissionError` naming the file that cannot be read or used."""
    try:
        context = ssl.create_default_context(cafile=dest.ca)
    except (OSError, ssl.SSLError) as exc:
        raise SarmissionError(f"CoT {dest.url}: CA file {dest.ca!r}: {_reason(exc)}") from None
    if dest.cert is not None:
        try:
            context.load_cert_chain(dest.cert, dest.key)
        except (OSError, ssl.SSLError) as exc:
            what = f"{dest.cert!r}" + ("" if dest.key is None else f" / {dest.key!r}")
            raise SarmissionError(
                f"CoT {dest.url}: client certificate {what}: {_reason(exc)}"
            ) from None
    return context


def _reason(exc: BaseException) -> str:
    """An OS or TLS error in a few words."""
    return getattr(exc, "strerror", None) or getattr(exc, "reason", None) or str(exc)


class CotSender:
    """Sends CoT events to ``udp://host:port``, ``tcp://host:port`` or ``tls://host:port``
    (:func:`parse_cot_url`). TCP and TLS connect on the first send and reconnect once if the
    connection has dropped; a TLS destination's files are read when the sender is made, so a
    wrong one is an error before anything starts."""

    def __init__(self, url: str, timeout_s: float = 3.0) -> None:
        self.destination = parse_cot_url(url)
        self.url = url
        self.scheme = self.destination.scheme
        self.address = (self.destination.host, self.destination.port)
        self.timeout_s = timeout_s
        self._tls = tls_context(self.destination) if self.scheme == "tls" else None
        self._sock: socket.socket | None = None

    def send(self, event: bytes) -> None:
        """Send one event (as made by :func:`alert_to_cot`). Raises OSError on failure."""
        if self.scheme == "udp":
            if self._sock is None:
                family = socket.getaddrinfo(*self.address, type=socket.SOCK_DGRAM)[0][0]
                self._sock = socket.socket(family, socket.SOCK_DGRAM)
            self._sock.sendto(event, self.address)
            return
        for attempt in range(2):
            try:
                if self._sock is None:
                    self._sock = self._connect()
                self._sock.sendall(event)
                return
            except OSError:
                self.close()
                if attempt:
                    raise

    def _connect(self) -> socket.socket:
        """A connected TCP socket, wrapped in TLS (handshake done) for a TLS destination."""
        sock = socket.create_connection(self.address, timeout=self.timeout_s)
        if self._tls is None:
            return sock
        try:
            return self._tls.wrap_socket(sock, server_hostname=self.destination.host)
        except BaseException:
            sock.close()
            raise

    def send_alert(self, alert: Alert) -> None:
        """Build the alert's CoT event and send it."""
        self.send(alert_to_cot(alert))

    def close(self) -> None:
        """Close the socket (a later send opens a new one)."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> CotSender:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
