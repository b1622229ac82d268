"""Area pyramids: the frame at half resolution (the one full-resolution pass the motion and
colour maps share) and the exact 2x halvings every coarser map is pooled with.

A 4K BGR frame is 25 MB; reading it costs more than most of what follows. vSTMD (ds >= 2) and
the chromatic anomaly map both start from :func:`half_resolution`, computed once per frame by
:class:`~sarmission.perception.mitenet.MiteNet` and handed to both.
"""

from __future__ import annotations

import cv2
import numpy as np


def halve(img: np.ndarray, levels: int) -> np.ndarray:
    """Area-average ``img`` by ``2**levels`` (exact 2x ``INTER_AREA`` halvings; the image must be
    cropped to a multiple of ``2**levels``)."""
    for _ in range(levels):
        img = cv2.resize(img, (img.shape[1] // 2, img.shape[0] // 2), interpolation=cv2.INTER_AREA)
    return img


def half_resolution(frame: np.ndarray) -> np.ndarray:
    """``frame`` (``[H, W]`` or ``[H, W, C]``) area-averaged by 2: each output pixel is the mean
    of a 2 x 2 block (OpenCV's exact 2x ``INTER_AREA``); an odd last row or column is ignored.
    Raises ``ValueError`` for frames smaller than 2 x 2."""
    h, w = frame.shape[0] // 2, frame.shape[1] // 2
    if h < 1 or w < 1:
        raise ValueError(f"frame {frame.shape[1]}x{frame.shape[0]} is too small to halve")
    return halve(frame[: 2 * h, : 2 * w], 1)
