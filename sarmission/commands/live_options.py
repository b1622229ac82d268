"""The options of a live session and the session they open: shared by ``run`` and ``sim replay``.

Link, alert store, feed and signing options; the simulated vehicle's end of a UDP link; Ctrl-C
and SIGTERM as a stop request; :func:`run_live`, which opens the session, runs it and closes it.
"""

from __future__ import annotations

import argparse
import hashlib
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sarmission.commands.mission_options import build_detector, build_recorder

if TYPE_CHECKING:
    from sarmission.mission.config import MissionConfig
    from sarmission.mission.controller import Detector
    from sarmission.mission.live import LiveSession
    from sarmission.mission.live_sources import LiveSource


def add_session_options(parser: argparse.ArgumentParser) -> None:
    """``--alerts-db --feed --feed-token-file --cot --signing-key-file --connect-timeout
    --target-system --target-component`` of a live session."""
    parser.add_argument(
        "--alerts-db", default="alerts.db", help="durable alert store (default: %(default)s)"
    )
    parser.add_argument(
        "--feed",
        metavar="HOST:PORT",
        default=None,
        help="serve the operator feed (HTTP/SSE), e.g. 127.0.0.1:8765; beyond "
        "loopback (e.g. 0.0.0.0:8765) every request needs an access token",
    )
    parser.add_argument(
        "--feed-token-file",
        metavar="PATH",
        default=None,
        help="the feed's access token (16-256 printable characters; chmod 600). "
        "Default: none on loopback, else one is generated and printed once",
    )
    parser.add_argument(
        "--cot",
        metavar="URL",
        type=_cot_url,
        action="append",
        default=[],
        help="send confirmed alerts to TAK as Cursor-on-Target, kept current as positions "
        "are refined: udp://239.2.3.1:6969 (SA multicast), udp://HOST:4242 (a TAK client), "
        "tcp://HOST:8087 (a TAK Server) or tls://HOST:8089?cert=F&key=F&ca=F (its TLS "
        "input, PEM files); repeat for several; added to the mission's [alerts] cot",
    )
    parser.add_argument(
        "--signing-key-file",
        default=None,
        help="MAVLink 2 signing key: 32 raw bytes, 64 hex digits, or a "
        "passphrase (sha256, as MAVProxy)",
    )
    parser.add_argument(
        "--connect-timeout",
        type=float,
        default=30.0,
        help="seconds to wait for the autopilot's HEARTBEAT (default: %(default)s)",
    )
    parser.add_argument(
        "--target-system",
        type=_mavlink_id,
        default=None,
        metavar="ID",
        help="only adopt the autopilot with this MAVLink system id (default: "
        "the first autopilot heard; pin it where anyone else could be on the "
        "link)",
    )
    parser.add_argument(
        "--target-component",
        type=_mavlink_id,
        default=None,
        metavar="ID",
        help="only adopt this component of it (default: any; ArduPilot and "
        "PX4 flight controllers are 1)",
    )


def _cot_url(text: str) -> str:
    """A CoT destination's form, checked while parsing (its TLS files are read once, by
    :func:`run_live`, before anything starts)."""
    from sarmission.alerts.cot import parse_cot_url
    from sarmission.errors import SarmissionError

    try:
        parse_cot_url(text)
    except SarmissionError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _mavlink_id(text: str) -> int:
    """A MAVLink system or component id, 1-255."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an id 1-255, got {text!r}") from None
    if not 1 <= value <= 255:
        raise argparse.ArgumentTypeError(f"expected an id 1-255, got {value}")
    return value


def parse_address(text: str) -> tuple[str, int]:
    """``"127.0.0.1:8765"`` -> ``("127.0.0.1", 8765)``."""
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        raise ValueError(f"expected HOST:PORT, got {text!r}")
    return host.strip("[]"), int(port)


def read_signing_key(path: str) -> bytes:
    """A 32-byte MAVLink 2 key from a file (raw, hex, or a passphrase hashed with sha256)."""
    data = Path(path).read_bytes()
    if len(data) == 32:
        return data
    text = data.decode("utf-8", errors="replace").strip()
    if len(text) == 64 and all(c in "0123456789abcdefABCDEF" for c in text):
        return bytes.fromhex(text)
    if not text:
        raise ValueError(f"{path}: empty signing key file")
    return hashlib.sha256(text.encode("utf-8")).digest()


def vehicle_url(connect: str) -> str:
    """The simulated vehicle's end of the controller's UDP link (listen <-> send swapped)."""
    scheme, _, rest = connect.partition(":")
    if scheme in ("udp", "udpin"):
        return f"udpout:{rest}"
    if scheme == "udpout":
        return f"udpin:{rest}"
    raise ValueError(f"--sim needs a udp:, udpin: or udpout: connection, got {connect!r}")


@contextmanager
def stop_on_signals() -> Iterator[threading.Event]:
    """An event set by SIGINT/SIGTERM while inside (handlers only in the main thread)."""
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}

    def handler(signum: int, frame: Any) -> None:
        print(f"\n{signal.Signals(signum).name}: stopping after this frame", flush=True)
        stop.set()

    for s in previous:
        signal.signal(s, handler)
    try:
        yield stop
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def run_live(
    args: argparse.Namespace,
    mission: MissionConfig,
    open_source: Callable[[MissionConfig], tuple[LiveSource, Any]],
    detector: Detector | None = None,
    console: Callable[[str], None] | None = None,
) -> LiveSession:
    """One live session of ``mission`` with the link/store/feed/recorder options of ``args``.

    ``open_source(mission)`` returns the frame source and the started simulated vehicle (or None
    for a real one); it is called once the detector and recorder are ready, and the vehicle is
    stopped at the end. Returns the closed session (its controller's statistics stay readable).
    """
    from sarmission.alerts.feed_guard import read_token_file
    from sarmission.mission.live import LiveSession

    say = console or (lambda line: print(line, flush=True))
    key = read_signing_key(args.signing_key_file) if args.signing_key_file else None
    feed = parse_address(args.feed) if args.feed else None
    feed_token = read_token_file(args.feed_token_file) if args.feed_token_file else None
    if detector is None:
        detector, note = build_detector(args, mission)
        say(note)
    from sarmission.alerts.cot import CotSender

    # the TAK destinations are made (TLS files read) before the video or the vehicle opens
    cot_senders = [CotSender(url) for url in dict.fromkeys([*mission.alerts.cot, *args.cot])]
    recorder = build_recorder(args)
    source, vehicle = open_source(mission)
    try:
        session = LiveSession(
            mission,
            detector,
            source,
            args.connect,
            args.alerts_db,
            signing_key=key,
            recorder=recorder,
            feed_address=feed,
            feed_token=feed_token,
            cot_senders=cot_senders,
            mission_id=args.mission_id,
            transport_latency_s=(mission.telemetry.latency_s if vehicle is not None else 0),
            connect_timeout_s=args.connect_timeout,
            target_system=args.target_system,
            target_component=args.target_component,
            console=say,
        )
        say(
            f"mission '{mission.name}': policy {', '.join(mission.actions.policy)}; "
            f"alerts in {args.alerts_db}"
        )
        with stop_on_signals() as stop:
            try:
                session.run(stop, args.max_frames, args.duration)
            finally:
                say(session.close())
        if vehicle is not None:
            say(
                f"simulator: {len(vehicle.statustexts)} STATUSTEXT and "
                f"{len(vehicle.commands)} commands received, {vehicle.bad_packets} bad packets"
            )
    finally:
        if vehicle is not None:
            vehicle.stop()
    return session
