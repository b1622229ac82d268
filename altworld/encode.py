"""Clips to MP4: H.264 through ``ffmpeg`` at a drone-like quality, or OpenCV's MPEG-4 writer
when ``ffmpeg`` is not installed."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np


class ClipWriter:
    """Write BGR frames of one size to ``path`` at ``fps``; ``crf`` is x264's quality (lower is
    better)."""

    def __init__(self, path: Path, width: int, height: int, fps: float, crf: int) -> None:
        self.path = path
        self._ffmpeg = shutil.which("ffmpeg")
        if self._ffmpeg:
            command = [
                self._ffmpeg, "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24",
                "-s", f"{width}x{height}", "-r", str(fps), "-i", "-", "-c:v", "libx264",
                "-preset", "veryfast", "-crf", str(crf), "-pix_fmt", "yuv420p", str(path),
            ]  # fmt: skip
            self._process = subprocess.Popen(command, stdin=subprocess.PIPE)
        else:
            self._writer = cv2.VideoWriter(
                str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height)
            )

    def write(self, frame: np.ndarray) -> None:
        if self._ffmpeg:
            self._process.stdin.write(np.ascontiguousarray(frame).tobytes())
        else:
            self._writer.write(frame)

    def close(self) -> None:
        if self._ffmpeg:
            self._process.stdin.close()
            if self._process.wait() != 0:
                raise RuntimeError(f"ffmpeg failed writing {self.path}")
        else:
            self._writer.release()
