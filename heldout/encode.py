"""Writing frames the way a drone's camera stores them: H.264 through FFmpeg at a drone's
bitrate, or JPEG images."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np


def ffmpeg_path() -> str:
    """The ``ffmpeg`` executable H.264 clips are written with; OSError, saying so, if none."""
    ffmpeg = shutil.which("ffmpeg")
    if ffmpeg is None:
        raise OSError(
            "ffmpeg is not installed: it is needed to write H.264 video "
            "(or write JPEG images instead)"
        )
    return ffmpeg


class H264Writer:
    """MP4 (H.264, yuv420p) through an ``ffmpeg`` process fed raw BGR frames on its stdin.

    ``bits_per_pixel`` sets the bitrate: 0.08-0.25 spans consumer drones at 4K30
    (20-60 Mbit/s).
    """

    def __init__(
        self, path: Path, width: int, height: int, fps: float, bits_per_pixel: float
    ) -> None:
        ffmpeg = ffmpeg_path()
        self.path = path
        self.size = (width, height)
        bitrate = int(bits_per_pixel * width * height * fps)
        self._proc = subprocess.Popen(
            [
                ffmpeg,
                "-loglevel",
                "error",
                "-y",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "bgr24",
                "-s",
                f"{width}x{height}",
                "-r",
                f"{fps:g}",
                "-i",
                "-",
                "-c:v",
                "libx264",
                "-preset",
                "veryfast",
                "-b:v",
                str(bitrate),
                "-maxrate",
                str(bitrate),
                "-bufsize",
                str(bitrate),
                "-g",
                str(max(1, int(round(fps)))),
                "-pix_fmt",
                "yuv420p",
                "-threads",
                "1",
                str(path),
            ],
            stdin=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )

    def write(self, frame: np.ndarray) -> None:
        if frame.shape[:2] != self.size[::-1]:
            raise ValueError(
                f"frame {frame.shape[1]}x{frame.shape[0]} does not match the "
                f"video's {self.size[0]}x{self.size[1]}"
            )
        assert self._proc.stdin is not None
        self._proc.stdin.write(np.ascontiguousarray(frame).tobytes())

    def close(self) -> None:
        assert self._proc.stdin is not None
        self._proc.stdin.close()
        err = self._proc.stderr.read().decode(errors="replace") if self._proc.stderr else ""
        if self._proc.wait() != 0:
            raise OSError(f"ffmpeg failed writing {self.path}: {err.strip()[-300:]}")


class JpegWriter:
    """One JPEG per frame, ``<folder>/NNNNNN.jpg``, at a fixed quality."""

    def __init__(self, folder: Path, quality: int) -> None:
        self.folder = folder
        self.quality = quality
        folder.mkdir(parents=True, exist_ok=True)
        self.count = 0

    def write(self, frame: np.ndarray) -> None:
        path = self.folder / f"{self.count:06d}.jpg"
        if not cv2.imwrite(str(path), frame, [cv2.IMWRITE_JPEG_QUALITY, self.quality]):
            raise OSError(f"cannot write {path}")
        self.count += 1

    def close(self) -> None:
        pass
