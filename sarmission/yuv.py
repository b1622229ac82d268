"""8-bit YUV 4:2:0 pictures as a video decoder gives them, and their BGR equivalents.

A 4K H.264 frame is 12 MB as Y, U and V planes and 25 MB as BGR; converting it costs the decoder
about 10 ms a frame. Detection needs little of the BGR: its grayscale input is the Y plane and its
chroma map the U and V planes (already at half resolution), and its head reads a few hundred small
windows. :class:`YuvImage` holds the planes and converts only what is asked for.

The conversion is ITU-R BT.601 (what FFmpeg's scaler uses for untagged video, and so what OpenCV
has been decoding to BGR), limited range (Y 16-235, U and V 16-240) unless ``full_range``
(``yuvj420p``). Values are truncated to integers as the scaler's fixed-point arithmetic does: on
the simulator's 4K clip they differ from FFmpeg's BGR by 0.5 on average and 2 at most, and the
gray by 0.7 on average and 4 at most.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

#: Limited-range scale of Y (255 / 219) and of U, V (255 / 224) to full-range 8-bit units.
LUMA_SCALE = 255.0 / 219.0
CHROMA_SCALE = 255.0 / 224.0
#: BT.601: Cr to R, Cb to G, Cr to G and Cb to B, for full-range chroma.
_CR_R, _CB_G, _CR_G, _CB_B = 1.402, 0.344136, 0.714136, 1.772


def _gray_table(full_range: bool) -> np.ndarray:
    """Y to gray (OpenCV's ``BGR2GRAY`` of the BGR picture, to within rounding) per 8-bit value."""
    y = np.arange(256, dtype=np.float64)
    if not full_range:
        y = np.floor((y - 16.0) * LUMA_SCALE)
    return np.clip(y, 0, 255).astype(np.uint8)


_GRAY_TABLES = {False: _gray_table(False), True: _gray_table(True)}


@dataclass(frozen=True, eq=False)
class YuvImage:
    """One 8-bit 4:2:0 picture: ``y`` ``[H, W]``, ``u`` (Cb) and ``v`` (Cr) ``[ceil(H/2),
    ceil(W/2)]``, all uint8 (views on the decoder's buffers may have padded rows)."""

    y: np.ndarray
    u: np.ndarray
    v: np.ndarray
    full_range: bool = False

    def __post_init__(self) -> None:
        planes = (self.y, self.u, self.v)
        if any(not isinstance(p, np.ndarray) or p.dtype != np.uint8 or p.ndim != 2 for p in planes):
            raise ValueError("Y, U and V must be 2-D uint8 arrays")
        h, w = self.y.shape
        chroma = ((h + 1) // 2, (w + 1) // 2)
        if self.u.shape != chroma or self.v.shape != chroma:
            raise ValueError(
                f"4:2:0 chroma of a {w}x{h} picture is {chroma[1]}x{chroma[0]}, got U "
                f"{self.u.shape[1]}x{self.u.shape[0]} and V {self.v.shape[1]}x{self.v.shape[0]}"
            )

    @property
    def height(self) -> int:
        return int(self.y.shape[0])

    @property
    def width(self) -> int:
        return int(self.y.shape[1])

    def to_gray(self, luma: np.ndarray) -> np.ndarray:
        """``luma`` (this picture's Y plane, or a part or an area average of it) as the gray of
        the BGR picture: limited range stretched to 0-255 (a table look-up, uint8)."""
        return cv2.LUT(luma, _GRAY_TABLES[self.full_range])

    def to_crcb(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(Cr, Cb)`` in the 8-bit units of OpenCV's ``BGR2YCrCb`` (float32) from (area averages
        of) this picture's ``u`` and ``v``."""
        cr, cb = v.astype(np.float32), u.astype(np.float32)
        if not self.full_range:
            k = np.float32(CHROMA_SCALE)
            cr = (cr - 128) * k + 128
            cb = (cb - 128) * k + 128
        return cr, cb

    def bgr_at(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """BGR values (uint8, ``[..., 3]``) of the pixels at ``rows`` and ``cols`` (integer arrays
        that broadcast together, inside the picture): what :meth:`bgr` holds there, without
        converting the rest."""
        crow, ccol = rows // 2, cols // 2
        yuv = np.stack([self.y[rows, cols], self.u[crow, ccol], self.v[crow, ccol]], axis=-1)
        flat = yuv.reshape(-1, 1, 3)
        return cv2.transform(flat, _MATRICES[self.full_range]).reshape(yuv.shape)

    @cached_property
    def bgr(self) -> np.ndarray:
        """The whole picture as BGR uint8 ``[H, W, 3]``, converted on first use, then kept
        (each chroma sample stands for its 2 x 2 luma block, as in FFmpeg's scaler)."""
        h, w = self.height, self.width
        u = cv2.resize(self.u, (w, h), interpolation=cv2.INTER_NEAREST)
        v = cv2.resize(self.v, (w, h), interpolation=cv2.INTER_NEAREST)
        return cv2.transform(cv2.merge([self.y, u, v]), _MATRICES[self.full_range])


def _matrix(full_range: bool) -> np.ndarray:
    """The affine map of ``(Y, U, V)`` to ``(B, G, R)`` for ``cv2.transform``, less 0.5 so that
    its rounding truncates."""
    ky, kc, y0 = (1.0, 1.0, 0.0) if full_range else (LUMA_SCALE, CHROMA_SCALE, 16.0)
    rows = [(ky, _CB_B * kc, 0.0), (ky, -_CB_G * kc, -_CR_G * kc), (ky, 0.0, _CR_R * kc)]
    m = np.array([[*r, -y0 * r[0] - 128.0 * (r[1] + r[2]) - 0.5] for r in rows])
    return m.astype(np.float32)


_MATRICES = {False: _matrix(False), True: _matrix(True)}


def picture_size(picture: np.ndarray | YuvImage) -> tuple[int, int]:
    """``(height, width)`` of a BGR or gray array or of a :class:`YuvImage`."""
    if isinstance(picture, YuvImage):
        return picture.height, picture.width
    return int(picture.shape[0]), int(picture.shape[1])
