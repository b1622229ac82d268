"""Live video for tests: ffmpeg sends a moving test pattern as H.264 in MPEG-TS over UDP to
127.0.0.1 in real time, as a drone's camera does; a relay can corrupt and drop its datagrams."""

from __future__ import annotations

import shutil
import socket
import subprocess
import threading

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
