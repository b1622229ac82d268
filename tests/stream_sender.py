"""Live video for tests: ffmpeg sends a moving test pattern as H.264 in MPEG-TS over UDP to
127.0.0.1 in real time, as a drone's camera does; a relay can corrupt and drop its datagrams."""

from __future__ import annotations

import shutil
import socket
import subprocess
import threading
import time

import pytest

FFMPEG = shutil.which("ffmpeg")
needs_ffmpeg = pytest.mark.skipif(
    FFMPEG is None, reason="needs the ffmpeg command (apt-get install ffmpeg)"
)


def live_h264_args(size: str, rate: int) -> list[str]:
    """ffmpeg's command up to its output options: a moving test pattern of ``size`` at ``rate``
    frames/s, read in real time and encoded as low-latency H.264 with a keyframe every second."""
    assert FFMPEG is not None
    return [
        FFMPEG, "-hide_banner", "-loglevel", "error", "-re",
        "-f", "lavfi", "-i", f"testsrc2=size={size}:rate={rate}",
        "-c:v", "libx264", "-preset", "ultrafast", "-tune", "zerolatency",
        "-g", str(rate), "-pix_fmt", "yuv420p",
    ]  # fmt: skip


class UdpStream:
    """``ffmpeg`` sending ``seconds`` of ``size`` video at ``rate`` fps to ``127.0.0.1:port``."""

    def __init__(
        self, port: int, seconds: float = 60.0, size: str = "320x240", rate: int = 25
    ) -> None:
        assert FFMPEG is not None
        self.process = subprocess.Popen(
            [
                *live_h264_args(size, rate),
                "-t",
                str(seconds),
                "-f",
                "mpegts",
                f"udp://127.0.0.1:{port}?pkt_size=1316",
            ],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait(10)

    def __enter__(self) -> UdpStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


class CorruptingRelay:
    """Forwards UDP datagrams from its own port to ``target``, overwriting 64 bytes of every
    ``corrupt_every``-th one and dropping every ``drop_every``-th."""

    def __init__(self, target: int, corrupt_every: int = 7, drop_every: int = 23) -> None:
        self.target = ("127.0.0.1", target)
        self.corrupt_every, self.drop_every = corrupt_every, drop_every
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.forwarded = self.corrupted = self.dropped = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        n = 0
        while not self._stop.is_set():
            try:
                data = bytearray(self.sock.recv(65536))
            except TimeoutError:
                continue
            n += 1
            if n % self.drop_every == 0:
                self.dropped += 1
                continue
            if n % self.corrupt_every == 0 and len(data) > 100:
                data[40:104] = bytes((n * 37 + i) % 256 for i in range(64))
                self.corrupted += 1
            out.sendto(bytes(data), self.target)
            self.forwarded += 1
        out.close()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.sock.close()


class StallingRelay:
    """Forwards UDP datagrams from its own port to ``target``, except that from ``stall_at``
    seconds after the first one it holds them for ``stall_s`` seconds, then sends the backlog at
    once: a link that stalls and catches up, leaving the receiver a burst of old video."""

    def __init__(self, target: int, stall_at: float, stall_s: float) -> None:
        self.target = ("127.0.0.1", target)
        self.stall_at, self.stall_s = stall_at, stall_s
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.held = 0
        self.released_at: float | None = None  # time.monotonic() of the burst
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        out.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 22)
        first: float | None = None
        backlog: list[bytes] = []
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                data = b""
            now = time.monotonic()
            first = now if first is None and data else first
            stalling = first is not None and 0 <= now - first - self.stall_at < self.stall_s
            if stalling:
                if data:
                    backlog.append(data)
                    self.held += 1
                continue
            if backlog:
                for held in backlog:
                    out.sendto(held, self.target)
                    time.sleep(0.0001)  # a burst the receive buffer can take
                backlog.clear()
                self.released_at = time.monotonic()
            if data:
                out.sendto(data, self.target)
        out.close()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.sock.close()


class TcpFiles:
    """A TCP server on 127.0.0.1 that sends each connection the next of ``files`` (the last
    one again once they are used up) and closes it ``hold_s`` seconds later: a sender whose
    stream ends, or that restarts with other data."""

    def __init__(self, files: list[bytes], hold_s: float = 0.2) -> None:
        self.files = files
        self.hold_s = hold_s
        self.connections = 0
        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.url = f"tcp://127.0.0.1:{self.port}"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except (TimeoutError, OSError):
                continue
            data = self.files[min(self.connections, len(self.files) - 1)]
            self.connections += 1
            threading.Thread(target=self._send, args=(conn, data), daemon=True).start()

    def _send(self, conn: socket.socket, data: bytes) -> None:
        with conn:
            try:
                conn.sendall(data)
                self._stop.wait(self.hold_s)
            except OSError:
                pass

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.sock.close()

    def __enter__(self) -> TcpFiles:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
