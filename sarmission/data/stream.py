"""Live network video (RTSP, MPEG-TS or RTP over UDP, ...), read in its own thread: the newest
frame wins, and the reader never falls behind the camera.

A drone's gimbal camera streams H.264 or H.265 over RTSP, or as MPEG-TS over UDP.
:class:`StreamSource` opens the URL with FFmpeg through PyAV (open and read timeouts, the thread
plan's decoding threads; RTSP over TCP, as OpenCV's reader asked for it), decodes every frame
in a reader thread to its YUV planes (:class:`~sarmission.yuv.YuvImage`, no BGR copy; turned
as displayed when the stream says it is rotated) and keeps
only the newest: a consumer slower than the camera always gets the latest frame, and every
frame it never saw is counted in ``dropped``. Frames the camera sent that never arrived show as
gaps in the presentation times and are counted in ``lost``.

Decoding a 4K stream can itself cost more than the cores left beside detection, and a link
that stalls delivers seconds of old video at once. The reader measures how late it reads each
packet (its ``lag``: the read less the packet's presentation time on the least-delayed
arrival's clock); past ``max_lag_s / 2`` it stops decoding frames nothing refers to (B-frames,
where the stream has them), past ``max_lag_s`` it throws packets away undecoded until the next
keyframe (for at most ``2 * max_lag_s``, for streams refreshed without keyframes, whose next
frames then show damage until the refresh) and starts again from there. Both are counted in
``behind``, so that the latency stays bounded instead of growing with FFmpeg's receive buffer.

A stream silent for ``read_timeout_s``, or that ends, is reopened until it is back (or the
source is closed), after a wait that grows from half a second to a few seconds while
connections keep ending or failing; with a warning when it is lost, one when it is back (the
outage counted from its last frame; each at most once a minute) and, while it stays away, one
a minute;
frames missing from a damaged stream are reported at most once a minute too (FFmpeg's own
messages are kept off the console).
Meanwhile :meth:`StreamSource.read` returns a frame without an image every ``read_timeout_s``
(as a camera whose grab failed), so a live loop can still stop; iterating skips those.

Each frame is stamped on ``time.monotonic()``, the clock the telemetry is mapped to, by
:class:`StreamClock`: the stream's own presentation times keep the camera's spacing between
frames (a frame decoded late is not made younger), anchored to the earliest arrival seen.
"""

from __future__ import annotations

import logging
import math
import re
import statistics
import threading
import time
from collections import deque
from collections.abc import Iterator
from typing import Any
from urllib.parse import urlsplit

from sarmission.data.frames import Frame, FrameSourceError
from sarmission.ratelimit import RateLimitedLog

log = logging.getLogger(__name__)

#: URL schemes FFmpeg reads live video from.
STREAM_SCHEMES = frozenset({"rtsp", "rtsps", "rtp", "udp", "tcp", "srt", "rtmp", "http", "https"})
#: Schemes whose URL must name a port (the address to listen on or connect to).
_PORT_REQUIRED = frozenset({"udp", "rtp", "tcp", "srt"})
#: Seconds between the warnings of a stream that stays away.
OUTAGE_REPORT_S = 60.0
#: Wait (s) before the first reconnection; it doubles with each connection in a row that ends
#: or fails, up to :data:`RECONNECT_MAX_S`.
RECONNECT_MIN_S = 0.5
#: Longest wait (s) between two connection attempts.
RECONNECT_MAX_S = 4.0
#: A connection that delivered frames for this long (s) resets the wait to its minimum.
RECONNECT_RESET_S = 30.0
#: Default of how late (s) a decoded frame may come before the reader skips work to catch up.
MAX_LAG_S = 1.0


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


def _failure(exc: BaseException) -> str:
    """An unexpected exception as a short reason: its class and first line."""
    text = str(exc).splitlines()[0][:200] if str(exc) else ""
    return f"{exc.__class__.__name__}: {text}" if text else exc.__class__.__name__


def _close_quietly(container: Any) -> None:
    """Close a container whose data may have broken it; a failure to close is logged."""
    try:
        container.close()
    except Exception as exc:
        log.debug("closing the stream failed: %s", _failure(exc))


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

    def expected(self, pts_s: float | None) -> float | None:
        """When a frame of presentation time ``pts_s`` would arrive with the least delay seen
        (None before the first frame, or for a time that would restart the anchor)."""
        last, offset = self._last_pts, self._offset
        if pts_s is None or not math.isfinite(pts_s) or last is None or offset is None:
            return None
        if abs(pts_s - last) > self.max_gap_s:
            return None
        return pts_s + offset

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

    def missing(self, step: float, learn: bool = True) -> int:
        """Frames missing in a step of ``step`` seconds between two frames (0 for a step
        shorter than two periods, or longer than 10 s: a restart, not a loss). ``learn=False``
        leaves the step out of the period (frames were left out on purpose)."""
        if not 0 < step <= 10.0:
            return 0
        known = len(self.steps) >= 5
        period = statistics.median(self.steps) if known else 0.0
        if learn:
            self.steps.append(step)
        return max(0, round(step / period) - 1) if known else 0


class CatchUp:
    """When the reader skips work to keep up with the camera (module docstring), from the lag
    of each packet it reads (how long after the least-delayed arrival its frame is read): no
    B-frames while a packet comes more than ``max_lag_s / 2`` late (until below
    ``max_lag_s / 4``), no packets at all from one more than ``max_lag_s`` late until a
    keyframe, or for at most ``2 * max_lag_s``."""

    def __init__(self, max_lag_s: float) -> None:
        self.max_lag_s = max_lag_s
        self.nonref = False
        self.until: float | None = None  # skipping packets until a keyframe or this time

    @property
    def decoding_all(self) -> bool:
        """Whether every frame the stream sent is being decoded."""
        return not self.nonref and self.until is None

    def skip(self, keyframe: bool, now: float) -> bool:
        """Whether to throw this packet away undecoded."""
        if self.until is None:
            return False
        if keyframe or now >= self.until:
            self.until = None
            return False
        return True

    def update(self, lag_s: float, now: float) -> str:
        """Update on a packet's lag; the decoder's ``skip_frame`` setting from now on."""
        if lag_s > self.max_lag_s:
            self.until = now + 2.0 * self.max_lag_s
        if lag_s > self.max_lag_s / 2:
            self.nonref = True
        elif lag_s < self.max_lag_s / 4:
            self.nonref = False
        return "NONREF" if self.nonref else "DEFAULT"


class StreamSource:
    """A live stream at ``url``, decoded in a reader thread; the newest frame wins.

    Raises :class:`FrameSourceError` when the URL is not a stream URL, or when no frame arrives
    within ``connect_timeout_s``. Attributes: ``fps`` (the stream's nominal rate), ``received``,
    ``dropped`` (decoded, replaced before being read), ``behind`` (not decoded, to catch up with
    the camera: module docstring), ``lost`` (missing from the presentation times), ``skipped``
    (image-less frames returned during outages), ``reconnects``; ``lag_s`` how late the last
    packet was read.
    """

    def __init__(
        self,
        url: str,
        connect_timeout_s: float = 15.0,
        read_timeout_s: float = 3.0,
        threads: int | None = None,
        default_fps: float = 30.0,
        max_lag_s: float = MAX_LAG_S,
    ) -> None:
        from sarmission.threads import thread_plan

        if not (math.isfinite(max_lag_s) and max_lag_s > 0):
            raise ValueError(f"max_lag_s must be a positive number of seconds, got {max_lag_s}")
        self.url = check_stream_url(str(url))
        self.path = redact(self.url)  # the name in messages, as a file source's path
        self.read_timeout_s = max(0.5, float(read_timeout_s))
        self.threads = threads or thread_plan().decode
        self.fps = default_fps
        self.max_lag_s = float(max_lag_s)
        self.received = self.dropped = self.lost = self.skipped = self.reconnects = 0
        self.behind = 0
        self.lag_s = 0.0
        self.clock = StreamClock()
        self._cond = threading.Condition()
        self._latest: Frame | None = None  # the newest frame, until it is read
        self._lost_since: float | None = None  # the last frame's arrival, while lost
        self._last_frame_at: float | None = None  # arrival of the newest frame
        self._outages = RateLimitedLog(log, interval_s=OUTAGE_REPORT_S)
        self._loss_report: tuple[float | None, int] = (None, 0)  # when, and ``lost`` then
        self._ended = False
        self._why = "no connection yet"
        self._got_frames = False  # whether the current connection gave any frame
        self._stop = threading.Event()
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

    def _open(self) -> tuple[Any, Any] | None:
        """The container and its video stream, or None (``_why`` says why)."""
        import av

        options = {"rtsp_transport": "tcp"} if self.url.lower().startswith("rtsp") else {}
        try:
            container = av.open(
                with_udp_defaults(self.url),
                options=options,
                timeout=(max(self.read_timeout_s, 5.0), self.read_timeout_s),
                metadata_errors="replace",  # a title in another encoding is no lost stream
            )
        except (av.FFmpegError, OSError) as exc:
            self._why = f"cannot open the stream ({exc.__class__.__name__}: nothing sending, "
            self._why += "wrong address, or not video)"
            return None
        except Exception as exc:  # the sender's data broke the demuxer: try again later
            self._why = f"cannot open the stream ({_failure(exc)})"
            return None
        try:
            if not container.streams.video:
                container.close()
                self._why = "the stream carries no video"
                return None
            stream = container.streams.video[0]
            stream.thread_type = "AUTO"
            stream.codec_context.thread_count = self.threads
            rate = stream.average_rate or stream.guessed_rate
            if rate and math.isfinite(float(rate)) and 0 < float(rate) <= 1000:
                self.fps = float(rate)
        except Exception as exc:
            container.close()
            self._why = f"cannot read the stream's header ({_failure(exc)})"
            return None
        return container, stream

    def _read_loop(self) -> None:
        """Connect, decode until the stream stops, and again after a wait that grows with each
        connection in a row that ends or fails (a stream that ends, e.g. a file served over
        HTTP, is not replayed in a tight loop), until closed."""
        last_report = 0.0
        backoff = RECONNECT_MIN_S
        while not self._stop.is_set():
            opened = self._open()
            if opened is not None:
                self.clock.reset()
                self._got_frames = False
                connected_at = time.monotonic()
                try:
                    self._pump(*opened)
                except Exception as exc:  # anything the stream's data breaks: a lost stream
                    self._why = f"reading the stream failed ({_failure(exc)})"
                finally:
                    _close_quietly(opened[0])
                if self._got_frames and not self._stop.is_set():
                    last = self._last_frame_at
                    if last is not None and last - connected_at >= RECONNECT_RESET_S:
                        backoff = RECONNECT_MIN_S  # it streamed a while: a new loss
                    self._lost_since = last if last is not None else time.monotonic()
                    last_report = time.monotonic()
                    self._outages.event(
                        "lost", "%s: stream lost (%s); reconnecting", self.path, self._why
                    )
            now = time.monotonic()
            if self._lost_since is not None and now - last_report >= OUTAGE_REPORT_S:
                last_report = now
                log.warning(
                    "%s: stream still away after %.0f s; still trying",
                    self.path,
                    now - self._lost_since,
                )
            self._stop.wait(backoff)
            backoff = min(RECONNECT_MAX_S, 2.0 * backoff)
        with self._cond:
            self._ended = True
            self._cond.notify_all()

    def _pump(self, container: Any, stream: Any) -> None:
        """Decode frames until the stream stops or the source is closed (``_got_frames``: whether
        any came; ``_why``: why it stopped)."""
        import av

        from sarmission.data.yuv_video import picture_of

        last_pts: float | None = None
        periods = FramePeriod()
        base = float(stream.time_base or 0)
        catch_up = CatchUp(self.max_lag_s)
        thrown = 0  # packets thrown away since the last frame decoded
        setting = "DEFAULT"
        packets = container.demux(stream)
        while not self._stop.is_set():
            try:
                packet = next(packets)
            except StopIteration:
                self._why = "the stream ended"
                return
            except (av.FFmpegError, OSError) as exc:  # read timeout or a dead connection
                self._why = f"no frame for {self.read_timeout_s:.1f} s or connection lost"
                self._why += f" ({exc.__class__.__name__})"
                return
            if packet.size == 0:
                continue  # the demuxer's flush marker
            now = time.monotonic()
            due = self.clock.expected(packet.pts * base if packet.pts is not None else None)
            self.lag_s = max(0.0, now - due) if due is not None else 0.0
            wanted = catch_up.update(self.lag_s, now)
            if wanted != setting:
                stream.codec_context.skip_frame = setting = wanted
            if catch_up.skip(packet.is_keyframe, now):
                self.behind += 1
                thrown += 1
                continue
            try:
                pictures = packet.decode()
            except Exception:  # damaged (FFmpegError, or worse): its frame shows as missing
                continue
            for picture in pictures:
                arrival = time.monotonic()
                if self._lost_since is not None:
                    self.reconnects += 1
                    self._outages.event(
                        "back",
                        "%s: stream back after %.1f s",
                        self.path,
                        arrival - self._lost_since,
                    )
                    self._lost_since = None
                self._last_frame_at = arrival
                pts = picture.pts * base if picture.pts is not None and base > 0 else None
                if pts is not None and last_pts is not None:
                    complete = catch_up.decoding_all and not thrown
                    missing = periods.missing(pts - last_pts, learn=complete)
                    if complete and missing:
                        self.lost += missing
                        self._report_loss(arrival)
                    elif not catch_up.decoding_all:
                        self.behind += missing  # B-frames the decoder left out, as told
                last_pts, thrown = pts, 0
                self._got_frames = True
                stamp = self.clock.stamp(pts, arrival)
                yuv, bgr = picture_of(picture)  # upright, as the camera meant it shown
                frame = Frame(self.received, stamp, bgr, pts, yuv=yuv)
                with self._cond:
                    if self._latest is not None:
                        self.dropped += 1  # decoded, never read
                    self.received += 1
                    self._latest = frame
                    self._cond.notify_all()

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
            if frame.image is not None:
                yield frame

    def summary(self) -> str:
        """One line: frames received, dropped, left undecoded, lost, reconnections."""
        return (
            f"{self.path}: {self.received} frames received, {self.dropped} dropped while "
            f"busy, {self.behind} not decoded to keep up, {self.lost} lost on the way, "
            f"{self.reconnects} reconnection(s)"
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
