"""Box conversions, size bands and the Normalized Wasserstein Distance (NWD) for tiny boxes.

All boxes are float arrays in pixels. ``xyxy`` is ``[x1, y1, x2, y2]``, ``xywh`` is the COCO
``[x, y, w, h]`` (top-left corner), ``cxcywh`` is ``[cx, cy, w, h]``.

NWD models each box as a 2-D Gaussian and compares them with the Wasserstein-2 distance::

    W = sqrt((cxa - cxb)^2 + (cya - cyb)^2 + ((wa - wb)^2 + (ha - hb)^2) / 4)
    NWD = exp(-W / C),   C = 12.8 by default
"""

from __future__ import annotations

import numpy as np

NWD_CONSTANT = 12.8

#: Size bands by box area in px^2 (paper section 5.1): name -> (lower exclusive, upper inclusive).
SIZE_BANDS: dict[str, tuple[float, float]] = {
    "extremely_tiny": (0.0, 64.0),
    "tiny": (64.0, 256.0),
    "small": (256.0, 1024.0),
    "all": (0.0, float("inf")),
}


def xyxy_to_cxcywh(boxes: np.ndarray) -> np.ndarray:
    """Convert ``[..., 4]`` corner boxes to centre-size boxes."""
    b = np.asarray(boxes, dtype=np.float64)
    w = b[..., 2] - b[..., 0]
    h = b[..., 3] - b[..., 1]
    return np.stack([b[..., 0] + w / 2, b[..., 1] + h / 2, w, h], axis=-1)


def cxcywh_to_xyxy(boxes: np.ndarray) -> np.ndarray:
    """Convert ``[..., 4]`` centre-size boxes to corner boxes."""
    b = np.asarray(boxes, dtype=np.float64)
    half_w, half_h = b[..., 2] / 2, b[..., 3] / 2
    return np.stack(
        [b[..., 0] - half_w, b[..., 1] - half_h, b[..., 0] + half_w, b[..., 1] + half_h], axis=-1
    )


def xywh_to_xyxy(boxes: np.ndarray) -> np.ndarray:
    """Convert COCO ``[x, y, w, h]`` boxes to corner boxes."""
    b = np.asarray(boxes, dtype=np.float64)
    return np.concatenate([b[..., :2], b[..., :2] + b[..., 2:4]], axis=-1)


def xyxy_to_xywh(boxes: np.ndarray) -> np.ndarray:
    """Convert corner boxes to COCO ``[x, y, w, h]`` boxes."""
    b = np.asarray(boxes, dtype=np.float64)
    return np.concatenate([b[..., :2], b[..., 2:4] - b[..., :2]], axis=-1)


def box_area(boxes_xyxy: np.ndarray) -> np.ndarray:
    """Area of corner boxes (zero for degenerate boxes)."""
    b = np.asarray(boxes_xyxy, dtype=np.float64)
    return np.clip(b[..., 2] - b[..., 0], 0, None) * np.clip(b[..., 3] - b[..., 1], 0, None)


def size_band(area: float) -> str:
    """Size band (not ``all``) of an area in px^2; ``larger`` above 1024."""
    for name, (low, high) in SIZE_BANDS.items():
        if name != "all" and low < area <= high:
            return name
    return "larger"


def centres_inside(a_xyxy: np.ndarray, b_xyxy: np.ndarray) -> np.ndarray:
    """``[M, N]``: the centre of box ``m`` of ``a`` lies inside box ``n`` of ``b`` (edges
    included). Matches a small box on part of a large one, which NWD cannot."""
    a = np.asarray(a_xyxy, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(b_xyxy, dtype=np.float64).reshape(-1, 4)
    cx = (a[:, 0, None] + a[:, 2, None]) / 2
    cy = (a[:, 1, None] + a[:, 3, None]) / 2
    return (
        (cx >= b[None, :, 0])
        & (cx <= b[None, :, 2])
        & (cy >= b[None, :, 1])
        & (cy <= b[None, :, 3])
    )


def nwd_matrix(
    a_xyxy: np.ndarray, b_xyxy: np.ndarray, constant: float = NWD_CONSTANT
) -> np.ndarray:
    """Pairwise NWD similarity in [0, 1] between ``M`` boxes and ``N`` boxes → ``[M, N]``."""
    a = xyxy_to_cxcywh(np.asarray(a_xyxy, dtype=np.float64).reshape(-1, 4))
    b = xyxy_to_cxcywh(np.asarray(b_xyxy, dtype=np.float64).reshape(-1, 4))
    d2 = (
        (a[:, None, 0] - b[None, :, 0]) ** 2
        + (a[:, None, 1] - b[None, :, 1]) ** 2
        + ((a[:, None, 2] - b[None, :, 2]) ** 2 + (a[:, None, 3] - b[None, :, 3]) ** 2) / 4.0
    )
    return np.exp(-np.sqrt(d2) / constant)


def nwd_pairwise(
    a_xyxy: np.ndarray, b_xyxy: np.ndarray, constant: float = NWD_CONSTANT
) -> np.ndarray:
    """Element-wise NWD between two aligned ``[N, 4]`` box arrays → ``[N]``."""
    a = xyxy_to_cxcywh(np.asarray(a_xyxy, dtype=np.float64).reshape(-1, 4))
    b = xyxy_to_cxcywh(np.asarray(b_xyxy, dtype=np.float64).reshape(-1, 4))
    d2 = (
        (a[:, 0] - b[:, 0]) ** 2
        + (a[:, 1] - b[:, 1]) ** 2
        + ((a[:, 2] - b[:, 2]) ** 2 + (a[:, 3] - b[:, 3]) ** 2) / 4.0
    )
    return np.exp(-np.sqrt(d2) / constant)
