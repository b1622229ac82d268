"""Video files decoded to their YUV 4:2:0 planes, without the conversion to BGR.

OpenCV's video reader converts every frame to BGR (about 10 ms and 25 MB for a 4K frame) and
keeps a BGR buffer of its own; detection needs the Y, U and V planes themselves
(:class:`~sarmission.yuv.YuvImage`). :class:`YuvVideoSource` decodes with FFmpeg's libraries
through PyAV and hands the decoder's planes over as they are (no copy). Frames of another pixel
format (10-bit, 4:2:2, ...) come as BGR, converted by FFmpeg. A video tagged to be shown
rotated (a phone held upright) is turned as displayed, as OpenCV's reader does (a copy).

It behaves as :class:`~sarmission.data.frames.VideoFileSource`: frames in order with their
presentation times in the file, a packet the decoder rejects skipped with a warning and counted
in ``skipped``, a new decoder for each iteration.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Iterator
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from sarmission.data.frames import Frame, FrameSource, FrameSourceError, _PresentationTimes
from sarmission.yuv import YuvImage

log = logging.getLogger(__name__)

#: Pixel formats handed over as planes, and whether each is full range.
PLANAR_FORMATS = {"yuv420p": False, "yuvj420p": True}
#: Packets refused before the first picture after which a file is taken as unreadable (the
#: end of the file ends the search too).
MAX_LEADING_REJECTS = 25
#: Demuxer failures in a row after which the rest of a file is taken as unreadable.
MAX_DEMUX_FAILURES = 25
#: FFmpeg's ``AVCOL_RANGE_JPEG``: a stream tagged full range.
_RANGE_JPEG = 2


def _failure(exc: BaseException) -> str:
    """An unexpected exception as a short reason: its class and first line."""
    text = str(exc).splitlines()[0][:200] if str(exc) else ""
    return f"{exc.__class__.__name__}: {text}" if text else exc.__class__.__name__


def yuv_decoding_available() -> bool:
    """Whether PyAV can be imported (else videos are read by OpenCV, as BGR)."""
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


def planes_of(picture: Any) -> YuvImage | None:
    """The Y, U and V planes of a decoded PyAV ``VideoFrame`` as views on its buffers (no copy),
    or None when its pixel format is not 8-bit 4:2:0."""
    name = picture.format.name
    if name not in PLANAR_FORMATS:
        return None
    h, w = picture.height, picture.width
    sizes = ((h, w), ((h + 1) // 2, (w + 1) // 2), ((h + 1) // 2, (w + 1) // 2))
    y, u, v = (
        np.frombuffer(plane, np.uint8).reshape(-1, plane.line_size)[:rows, :cols]
        for plane, (rows, cols) in zip(picture.planes, sizes, strict=True)
    )
    full = PLANAR_FORMATS[name] or int(picture.color_range) == _RANGE_JPEG
    return YuvImage(y, u, v, full_range=full)


def quarter_turns(picture: Any) -> int:
    """Counter-clockwise quarter turns that show a decoded PyAV picture as it is meant to be
    displayed (its display matrix, e.g. ``rotate=90`` of a phone held upright; OpenCV's reader
    applies it too), nearest to its angle; 0 without one."""
    try:
        angle = float(getattr(picture, "rotation", 0) or 0)
    except (TypeError, ValueError):
        return 0
    return round(angle / 90.0) % 4 if math.isfinite(angle) else 0


def picture_of(picture: Any) -> tuple[YuvImage | None, np.ndarray | None]:
    """A decoded PyAV picture as :attr:`Frame.yuv` planes (8-bit 4:2:0) or else BGR, turned
    upright (:func:`quarter_turns`; the planes are then copied)."""
    yuv = planes_of(picture)
    bgr = picture.to_ndarray(format="bgr24") if yuv is None else None
    turns = quarter_turns(picture)
    if not turns:
        return yuv, bgr
    if yuv is not None:
        y, u, v = (np.ascontiguousarray(np.rot90(p, turns)) for p in (yuv.y, yuv.u, yuv.v))
        return YuvImage(y, u, v, full_range=yuv.full_range), None
    assert bgr is not None
    return None, np.ascontiguousarray(np.rot90(bgr, turns))


class YuvVideoSource(FrameSource):
    """Frames of a video file as :class:`~sarmission.yuv.YuvImage` planes (``Frame.yuv``).

    ``fps`` is the stream's average rate (``default_fps`` when it has none); ``threads`` the
    number of FFmpeg decoding threads (default: the thread plan's).
    """

    def __init__(self, path: Path, default_fps: float = 30.0, threads: int | None = None) -> None:
        self.threads = threads
        container, stream = self._open(path, threads)
        try:
            rate = stream.average_rate or stream.guessed_rate
            count = int(stream.frames or 0)
            pictures = self._pictures(container, stream)
            rejected = 0  # packets before the first picture that the decoder refused
            first = next(pictures, None)
            while first is None and rejected < MAX_LEADING_REJECTS:
                rejected += 1
                first = next(pictures, None)
        except BaseException:
            container.close()
            raise
        if first is None:
            container.close()
            raise FrameSourceError(f"{path}: unsupported or unreadable video (no frame decodes)")
        fps = float(rate) if rate else 0.0
        super().__init__(path, fps if fps > 0 and math.isfinite(fps) else default_fps)
        self._count = count if count > 0 else None
        # The first iteration goes on with this decoder: a 4K key frame takes a third of a
        # second to decode, and a second decoder would hold its own buffers meanwhile.
        self._opened: tuple[Any, Any, Iterator[Any]] | None = (
            container,
            stream,
            itertools.chain([None] * rejected, [first], pictures),
        )

    def close(self) -> None:
        """Release the decoder opened to check the file, if no iteration has taken it over."""
        opened, self._opened = self._opened, None
        if opened is not None:
            opened[0].close()

    @staticmethod
    def _open(path: Path, threads: int | None) -> tuple[Any, Any]:
        import av

        from sarmission.threads import thread_plan

        try:
            # a title or tag in another encoding than UTF-8 is no reason to refuse the video
            container = av.open(str(path), metadata_errors="replace")
        except (av.FFmpegError, OSError) as exc:
            raise FrameSourceError(f"{path}: FFmpeg cannot open this file as a video") from exc
        except Exception as exc:  # the file's data broke the reader itself
            raise FrameSourceError(
                f"{path}: FFmpeg cannot open this file as a video ({_failure(exc)})"
            ) from exc
        try:
            if not container.streams.video:
                raise FrameSourceError(f"{path}: no video stream in this file")
            stream = container.streams.video[0]
            stream.thread_type = "AUTO"
            stream.codec_context.thread_count = threads or thread_plan().decode
        except FrameSourceError:
            container.close()
            raise
        except Exception as exc:
            container.close()
            raise FrameSourceError(
                f"{path}: cannot read this file's video stream ({_failure(exc)})"
            ) from exc
        return container, stream

    @staticmethod
    def _pictures(container: Any, stream: Any) -> Iterator[Any]:
        """Decoded pictures, None in place of each packet the decoder or demuxer rejects.

        A damaged packet can make PyAV's demuxer itself raise (e.g. IndexError for a packet
        whose stream appeared after the file was opened); reading then goes on after it with
        a new demuxer, up to :data:`MAX_DEMUX_FAILURES` failures in a row (then the file is
        taken to end there)."""
        failures = 0
        while failures < MAX_DEMUX_FAILURES:
            packets = container.demux(stream)
            while True:
                try:
                    packet = next(packets)
                except StopIteration:
                    return
                except Exception:  # the packet read is lost; the next read goes on after it
                    failures += 1
                    yield None
                    break
                failures = 0
                try:
                    decoded = packet.decode()
                except Exception:  # FFmpegError, or worse: a damaged packet
                    yield None
                    continue
                yield from decoded

    @property
    def length(self) -> int | None:
        return self._count

    def __iter__(self) -> Iterator[Frame]:
        opened, self._opened = self._opened, None
        if opened is None:
            container, stream = self._open(self.path, self.threads)
            pictures = self._pictures(container, stream)
        else:
            container, stream, pictures = opened
        try:
            base = Fraction(stream.time_base or 0)
            start = stream.start_time or 0
            clock = _PresentationTimes(self.fps, self.path)
            index = -1
            for index, picture in enumerate(pictures):
                if picture is None:
                    self._skip(index, "decoder rejected a packet")
                    continue
                try:
                    yuv, bgr = picture_of(picture)
                except Exception as exc:  # a picture FFmpeg cannot convert
                    self._skip(index, f"picture unreadable ({_failure(exc)})", "unreadable")
                    continue
                ms = float((picture.pts - start) * base * 1000) if picture.pts is not None else -1
                yield Frame(index, clock.time(index, ms), bgr, yuv=yuv)
            if self._count is not None and index + 1 < self._count:
                # a file cut short (or a header's estimate): where it ended, in one line
                log.info(
                    "%s: the video ends at frame %d of the %d its header announces",
                    self.path,
                    index + 1,
                    self._count,
                )
        finally:
            container.close()
