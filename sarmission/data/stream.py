"""Live network video (RTSP, MPEG-TS or RTP over UDP, ...), read in its own thread: the newest
frame wins.

A drone's gimbal camera streams H.264 or H.265 over RTSP, or as MPEG-TS over UDP.
:class:`StreamSource` opens the URL with OpenCV's FFmpeg backend (open and read timeouts, the
thread plan's decoding threads), decodes every frame in a reader thread and keeps only the
newest: a consumer slower than the camera always gets the latest frame, and every frame it never
saw is counted in ``dropped``. Frames the camera sent that never arrived show as gaps in the
presentation times and are counted in ``lost``.

A stream silent for ``read_timeout_s`` is reopened until it is back (or the source is closed),
with one warning when it is lost, one when it is back and, while it stays away, one a minute;
frames missing from a damaged stream are reported at most once a minute too (FFmpeg's own
messages, several per damaged packet, are kept off the console).
Meanwhile :meth:`StreamSource.read` returns a frame without an image every ``read_timeout_s``
(as a camera whose grab failed), so a live loop can still stop; iterating skips those.

Each frame is stamped on ``time.monotonic()``, the clock the telemetry is mapped to, by
:class:`StreamClock`: the stream's own presentation times keep the camera's spacing between
frames (a frame decoded late is not made younger), anchored to the earliest arrival seen.
"""

from __future__ import annotations

import logging
import math
import os
import re
import statistics
import threading
import time
from collections import deque
from collections.abc import Iterator
from urllib.parse import urlsplit

import cv2

from sarmission.data.frames import Frame, FrameSourceError

log = logging.getLogger(__name__)

#: URL schemes FFmpeg reads live video from.
STREAM_SCHEMES = frozenset({"rtsp", "rtsps", "rtp", "udp", "tcp", "srt", "rtmp", "http", "https"})
#: Schemes whose URL must name a port (the address to listen on or connect to).
_PORT_REQUIRED = frozenset({"udp", "rtp", "tcp", "srt"})
#: Seconds between the warnings of a stream that stays away.
OUTAGE_REPORT_S = 60.0


def is_stream_url(text: str) -> bool:
    """Whether ``text`` looks like a URL (``scheme://...``) rather than a path."""
    return re.match(r"^[A-Za-z][A-Za-z0-9+.-]*://", str(text)) is not None


def redact(url: str) -> str:
    """``url`` without its password (``rtsp://user:***@host/...``), for messages."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    host = parts.netloc.rpartition("@")[2]
    return parts._replace(netloc=f"{parts.username}:***@{host}").geturl()


def check_stream_url(url: str) -> str:
    """``url`` when it names a stream this reader can open; else :class:`FrameSourceError`."""
    if any(ord(c) < 33 or ord(c) == 127 for c in url) or len(url) > 2048:
        raise FrameSourceError("stream URL: control characters, spaces or over 2048 characters")
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError as exc:
        raise FrameSourceError(f"{redact(url)}: malformed stream URL ({exc})") from None
    scheme = parts.scheme.lower()
    if scheme not in STREAM_SCHEMES:
        raise FrameSourceError(
            f"{redact(url)}: unsupported stream URL scheme '{scheme}' (use "
            + ", ".join(f"{s}://" for s in sorted(STREAM_SCHEMES))
            + ")"
        )
    if scheme in _PORT_REQUIRED and port is None:
        raise FrameSourceError(
            f"{redact(url)}: a {scheme}:// stream URL needs a port, e.g. {scheme}://127.0.0.1:5600"
        )
    if scheme not in _PORT_REQUIRED and not parts.hostname:
        raise FrameSourceError(f"{redact(url)}: the stream URL names no host")
    return url


def with_udp_defaults(url: str) -> str:
    """``url`` with ``overrun_nonfatal=1`` for a ``udp://`` stream that does not say otherwise:
    when decoding falls behind and FFmpeg's receive buffer fills, the oldest data is dropped
    (damaged frames, counted as lost) instead of the stream failing and being reopened."""
    parts = urlsplit(url)
    if parts.scheme.lower() != "udp" or "overrun_nonfatal" in parts.query:
        return url
    query = "&".join(q for q in (parts.query, "overrun_nonfatal=1") if q)
    return parts._replace(query=query).geturl()


def quiet_opencv_warnings() -> None:
    """Keep OpenCV's warnings (a read timeout) and FFmpeg's messages (one or more per damaged
    packet: dozens a second on a lossy link) off the console: the stream's state is reported in
    our own, rate-limited lines. Process-wide; ``$OPENCV_FFMPEG_LOGLEVEL`` set by the user wins.
    """
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET
    if cv2.utils.logging.getLogLevel() > cv2.utils.logging.LOG_LEVEL_ERROR:
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)


class StreamClock:
    """Maps a stream's presentation times onto ``time.monotonic()``.

    ``stamp = pts + offset`` with ``offset`` the smallest ``arrival - pts`` seen (the frame that
    came with the least delay), allowed to grow by ``drift`` seconds per second so that a camera
    clock running slow is followed. Never later than the arrival. A presentation time that is
    missing, goes back or jumps by more than ``max_gap_s`` (a restarted stream) starts over from
    that frame's arrival.
    """

    def __init__(self, max_gap_s: float = 5.0, drift: float = 1e-3) -> None:
        self.max_gap_s = max_gap_s
        self.drift = drift
        self._offset: float | None = None
        self._last_pts: float | None = None

    def reset(self) -> None:
        """Forget the anchor (a new connection: its times need not follow the old ones)."""
        self._offset = self._last_pts = None

    def stamp(self, pts_s: float | None, arrival: float) -> float:
        """The capture time of a frame with presentation time ``pts_s`` that arrived at
        ``arrival`` (``time.monotonic()``)."""
        if pts_s is None or not math.isfinite(pts_s):
            self.reset()
            return arrival
        last, offset = self._last_pts, self._offset
        if last is None or offset is None or not 0 < pts_s - last <= self.max_gap_s:
            offset = arrival - pts_s
        else:
            offset = min(arrival - pts_s, offset + self.drift * (pts_s - last))
        self._offset, self._last_pts = offset, pts_s
        return min(pts_s + offset, arrival)


class FramePeriod:
    """The time between a stream's frames, from its own presentation times (the median of the
    last 31 steps, not the rate the stream announces, which can be off by a factor of two), and
    how many frames a longer step skipped. Nothing is counted before 5 steps are known."""

    def __init__(self) -> None:
        self.steps: deque[float] = deque(maxlen=31)

    def missing(self, step: float) -> int:
        """Frames missing in a step of ``step`` seconds between two frames (0 for a step
        shorter than two periods, or longer than 10 s: a restart, not a loss)."""
        if not 0 < step <= 10.0:
            return 0
        known = len(self.steps) >= 5
        period = statistics.median(self.steps) if known else 0.0
        self.steps.append(step)
        return max(0, round(step / period) - 1) if known else 0


class StreamSource:
    """A live stream at ``url``, decoded in a reader thread; the newest frame wins.

    Raises :class:`FrameSourceError` when the URL is not a stream URL, or when no frame arrives
    within ``connect_timeout_s``. Attributes: ``fps`` (the stream's nominal rate), ``received``,
    ``dropped`` (decoded, replaced before being read), ``lost`` (missing from the presentation
    times), ``skipped`` (image-less frames returned during outages), ``reconnects``.
    """

    def __init__(
        self,
        url: str,
        connect_timeout_s: float = 15.0,
        read_timeout_s: float = 3.0,
        threads: int | None = None,
        default_fps: float = 30.0,
    ) -> None:
        from sarmission.threads import thread_plan

        self.url = check_stream_url(str(url))
        self.path = redact(self.url)  # the name in messages, as a file source's path
        self.read_timeout_s = max(0.5, float(read_timeout_s))
        self.threads = threads or thread_plan().decode
        self.fps = default_fps
        self.received = self.dropped = self.lost = self.skipped = self.reconnects = 0
        self.clock = StreamClock()
        self._cond = threading.Condition()
        self._latest: Frame | None = None  # the newest frame, until it is read
        self._lost_since: float | None = None
        self._loss_report: tuple[float | None, int] = (None, 0)  # when, and ``lost`` then
        self._ended = False
        self._why = "no connection yet"
        self._stop = threading.Event()
        quiet_opencv_warnings()
        self._thread = threading.Thread(target=self._read_loop, name="stream", daemon=True)
        self._thread.start()
        with self._cond:
            self._cond.wait_for(
                lambda: self._latest is not None or self._ended, timeout=connect_timeout_s
            )
            first = self._latest
        if first is None:
            why = self._why
            self.close()
            raise FrameSourceError(f"{self.path}: no video within {connect_timeout_s:g} s ({why})")

    @property
    def length(self) -> None:
        """A live stream has no frame count."""
        return None

    # -- reader thread -------------------------------------------------------------------------

    def _open(self) -> cv2.VideoCapture | None:
        url = with_udp_defaults(self.url)
        timeout_ms = int(self.read_timeout_s * 1000)
        params = [
            cv2.CAP_PROP_OPEN_TIMEOUT_MSEC,
            max(timeout_ms, 5000),
            cv2.CAP_PROP_READ_TIMEOUT_MSEC,
            timeout_ms,
            cv2.CAP_PROP_N_THREADS,
            self.threads,
        ]
        capture = cv2.VideoCapture(url, cv2.CAP_FFMPEG, params)
        if capture.isOpened():
            fps = capture.get(cv2.CAP_PROP_FPS)
            if math.isfinite(fps) and 0 < fps <= 1000:
                self.fps = fps
            return capture
        capture.release()
        self._why = "cannot open the stream (nothing sending, wrong address, or not video)"
        return None

    def _read_loop(self) -> None:
        last_report = 0.0
        while not self._stop.is_set():
            capture = self._open()
            if capture is not None:
                self.clock.reset()
                pumped = self._pump(capture)
                capture.release()
                if pumped and not self._stop.is_set():
                    self._lost_since = last_report = time.monotonic()
                    self._why = "stream lost"
                    log.warning(
                        "%s: stream lost (no frame for %.1f s); reconnecting",
                        self.path,
                        self.read_timeout_s,
                    )
                    continue
            now = time.monotonic()
            if self._lost_since is not None and now - last_report >= OUTAGE_REPORT_S:
                last_report = now
                log.warning(
                    "%s: stream still away after %.0f s; still trying",
                    self.path,
                    now - self._lost_since,
                )
            self._stop.wait(min(1.0, self.read_timeout_s))
        with self._cond:
            self._ended = True
            self._cond.notify_all()

    def _pump(self, capture: cv2.VideoCapture) -> bool:
        """Decode frames until the stream stops or the source is closed; whether any came."""
        got_any = False
        last_pts: float | None = None
        periods = FramePeriod()
        while not self._stop.is_set():
            if not capture.grab():
                return got_any
            arrival = time.monotonic()
            pts_ms = capture.get(cv2.CAP_PROP_POS_MSEC)
            ok, image = capture.retrieve()
            if not ok or image is None or image.size == 0:
                continue
            if self._lost_since is not None:
                self.reconnects += 1
                log.warning("%s: stream back after %.1f s", self.path, arrival - self._lost_since)
                self._lost_since = None
            pts = pts_ms / 1000.0 if math.isfinite(pts_ms) and pts_ms >= 0 else None
            if pts is not None and last_pts is not None:
                missing = periods.missing(pts - last_pts)
                if missing:
                    self.lost += missing
                    self._report_loss(arrival)
            last_pts = pts
            got_any = True
            frame = Frame(self.received, self.clock.stamp(pts, arrival), image, pts)
            with self._cond:
                if self._latest is not None:
                    self.dropped += 1  # decoded, never read
                self.received += 1
                self._latest = frame
                self._cond.notify_all()
        return got_any

    def _report_loss(self, now: float) -> None:
        """A warning at the first frames lost, then at most one a minute while more are."""
        reported_at, reported = self._loss_report
        if reported_at is None or now - reported_at >= OUTAGE_REPORT_S:
            since = "so far" if reported_at is None else f"in the last {now - reported_at:.0f} s"
            log.warning(
                "%s: %d frame(s) missing from the stream %s (damaged or lost packets)",
                self.path,
                self.lost - reported,
                since,
            )
            self._loss_report = (now, self.lost)

    # -- consumer ------------------------------------------------------------------------------

    def read(self) -> Frame | None:
        """The newest frame not yet read, waiting for one; during an outage a frame without an
        image every ``read_timeout_s`` (counted in ``skipped``); None once closed."""
        with self._cond:
            self._cond.wait_for(
                lambda: self._ended or self._latest is not None, timeout=self.read_timeout_s
            )
            if self._ended:
                return None
            frame, self._latest = self._latest, None
            if frame is None:
                self.skipped += 1
                return Frame(self.received, time.monotonic(), None)
            return frame

    def __iter__(self) -> Iterator[Frame]:
        """Frames as they come (the newest each time), skipping outages, until closed."""
        while True:
            frame = self.read()
            if frame is None:
                return
            if frame.image_bgr is not None:
                yield frame

    def summary(self) -> str:
        """One line: frames received, dropped, lost, reconnections."""
        return (
            f"{self.path}: {self.received} frames received, {self.dropped} dropped while "
            f"busy, {self.lost} lost on the way, {self.reconnects} reconnection(s)"
        )

    def close(self) -> None:
        """Stop the reader (within the read timeout), release the stream and log its
        :meth:`summary`."""
        if self._stop.is_set():
            return
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        if self._thread is not threading.current_thread():
            self._thread.join(self.read_timeout_s + 6.0)
        with self._cond:
            self._ended = True
            self._latest = None
            self._cond.notify_all()
        if self.received:
            log.info(self.summary())
