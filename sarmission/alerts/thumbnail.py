"""Alert thumbnails: a JPEG crop of the raw frame around the target."""

from __future__ import annotations

import cv2
import numpy as np

from sarmission.yuv import YuvImage


def crop_thumbnail(
    frame: np.ndarray | YuvImage,
    center: tuple[float, float],
    side: int = 96,
    out_size: int = 192,
    quality: int = 90,
) -> bytes:
    """JPEG bytes of a ``side`` x ``side`` crop of ``frame`` (BGR or gray uint8, full resolution,
    or a :class:`~sarmission.yuv.YuvImage`, of which only the crop is converted to BGR) centred
    on pixel ``center`` ``(x, y)``, enlarged to ``out_size`` with nearest-neighbour so the
    operator sees the real pixels. Parts outside the frame are black."""
    if isinstance(frame, YuvImage):
        h, w, channels = frame.height, frame.width, (3,)
    elif frame.ndim not in (2, 3) or frame.dtype != np.uint8:
        raise ValueError(f"expected a uint8 image, got {frame.dtype} with shape {frame.shape}")
    else:
        h, w, channels = *frame.shape[:2], frame.shape[2:]
    x0 = int(round(center[0] - side / 2))
    y0 = int(round(center[1] - side / 2))
    crop = np.zeros((side, side) + channels, dtype=np.uint8)
    sx0, sy0 = max(x0, 0), max(y0, 0)
    sx1, sy1 = min(x0 + side, w), min(y0 + side, h)
    if sx1 > sx0 and sy1 > sy0:
        crop[sy0 - y0 : sy1 - y0, sx0 - x0 : sx1 - x0] = (
            frame.bgr_at(np.arange(sy0, sy1)[:, None], np.arange(sx0, sx1)[None, :])
            if isinstance(frame, YuvImage)
            else frame[sy0:sy1, sx0:sx1]
        )
    if out_size != side:
        crop = cv2.resize(crop, (out_size, out_size), interpolation=cv2.INTER_NEAREST)
    ok, buf = cv2.imencode(".jpg", crop, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError("JPEG encoding of the thumbnail failed")
    return buf.tobytes()
