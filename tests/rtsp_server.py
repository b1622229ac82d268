"""A small RTSP server for tests: ffmpeg encodes a moving test pattern as H.264 in RTP, and this
server hands it to one RTSP client over its TCP connection (RTP interleaved, RFC 2326 10.12),
as a gimbal camera's RTSP server does. Only TCP transport is offered; a client asking for UDP
gets 461 and asks again for TCP."""

from __future__ import annotations

import socket
import subprocess
import threading
import time
from pathlib import Path

from stream_sender import FFMPEG, live_h264_args


class RtspServer:
    """Serves ``rtsp://127.0.0.1:<port>/live`` (``port`` 0: one the OS picks) until
    :meth:`close`; ``requests`` lists the RTSP methods received, ``packets`` the RTP packets
    passed on."""

    def __init__(self, folder: Path, size: str = "320x240", rate: int = 25, port: int = 0) -> None:
        assert FFMPEG is not None
        self.rtp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.rtp.bind(("127.0.0.1", 0))
        self.rtp.settimeout(0.2)
        sdp = folder / "stream.sdp"
        self.encoder = subprocess.Popen(
            [
                *live_h264_args(size, rate),
                "-f",
                "rtp",
                "-sdp_file",
                str(sdp),
                f"rtp://127.0.0.1:{self.rtp.getsockname()[1]}",
            ],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 30
        while not (sdp.is_file() and "m=video" in sdp.read_text()):
            if time.monotonic() > deadline or self.encoder.poll() is not None:
                raise RuntimeError("ffmpeg wrote no SDP")
            time.sleep(0.05)
        self.sdp = (
            sdp.read_text().replace("c=IN IP4 127.0.0.1", "c=IN IP4 0.0.0.0")
            + "a=control:streamid=0\r\n"
        )
        self.listener = socket.create_server(("127.0.0.1", port))
        self.listener.settimeout(0.2)
        self.port = self.listener.getsockname()[1]
        self.url = f"rtsp://127.0.0.1:{self.port}/live"
        self.requests: list[str] = []
        self.packets = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.listener.accept()
            except TimeoutError:
                continue
            with conn:
                self._session(conn)

    def _session(self, conn: socket.socket) -> None:
        conn.settimeout(0.05)
        playing = False
        buffer = b""
        while not self._stop.is_set():
            try:
                data = conn.recv(4096)
                if not data:
                    return
                buffer += data
            except TimeoutError:
                pass
            except OSError:
                return
            while b"\r\n\r\n" in buffer:
                head, buffer = buffer.split(b"\r\n\r\n", 1)
                reply = self._answer(head.decode("latin-1"))
                if reply is None:
                    return
                conn.sendall(reply)
                playing = playing or head.startswith(b"PLAY")
            if playing and not self._forward(conn):
                return

    def _answer(self, request: str) -> bytes | None:
        lines = request.split("\r\n")
        method = lines[0].split(" ")[0]
        self.requests.append(method)
        headers = {
            k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines[1:])
        }
        cseq = headers.get("cseq", "0")
        status, extra, body = "200 OK", [], ""
        if method == "OPTIONS":
            extra = ["Public: OPTIONS, DESCRIBE, SETUP, PLAY, TEARDOWN, GET_PARAMETER"]
        elif method == "DESCRIBE":
            body = self.sdp
            extra = ["Content-Type: application/sdp", f"Content-Base: {self.url}/"]
        elif method == "SETUP":
            if "TCP" not in headers.get("transport", ""):
                status = "461 Unsupported Transport"
            else:
                extra = ["Transport: RTP/AVP/TCP;unicast;interleaved=0-1", "Session: 4242"]
        elif method in ("PLAY", "GET_PARAMETER"):
            extra = ["Session: 4242"]
        elif method == "TEARDOWN":
            return None
        else:
            status = "405 Method Not Allowed"
        lines = [
            f"RTSP/1.0 {status}",
            f"CSeq: {cseq}",
            *extra,
            f"Content-Length: {len(body.encode())}",
        ]
        return ("\r\n".join(lines) + "\r\n\r\n" + body).encode()

    def _forward(self, conn: socket.socket) -> bool:
        """Pass the RTP packets waiting from the encoder to the client; False when it left."""
        while True:
            try:
                packet = self.rtp.recv(65536) if self.packets == 0 else self._next_packet()
            except TimeoutError:
                return True
            if packet is None:
                return True
            try:
                conn.sendall(b"$\x00" + len(packet).to_bytes(2, "big") + packet)
            except OSError:
                return False
            self.packets += 1

    def _next_packet(self) -> bytes | None:
        self.rtp.setblocking(False)
        try:
            return self.rtp.recv(65536)
        except BlockingIOError:
            return None
        finally:
            self.rtp.settimeout(0.2)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.encoder.kill()
        self.encoder.wait(10)
        self.listener.close()
        self.rtp.close()
