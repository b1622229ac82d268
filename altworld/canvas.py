"""Figures drawn in metres on a fine canvas, then placed in a frame through the camera.

A :class:`Canvas` holds premultiplied colour, total alpha and the alpha of the *body* (the part a
box is drawn around) in the figure's own frame: x to its right, y (canvas up) along its heading,
origin at its centre. :func:`place` maps it into the image with the homography's local affine at
the figure's ground position, composites it and returns the body's box.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

#: Body alpha at or above which an image pixel belongs to the box.
BOX_ALPHA = 0.25


class Canvas:
    """A square canvas ``extent`` metres across at ``scale`` canvas pixels per metre."""

    def __init__(self, extent: float, scale: float) -> None:
        self.scale = scale
        self.size = max(8, int(math.ceil(extent * scale)) | 1)
        self.colour = np.zeros((self.size, self.size, 3), np.float32)
        self.alpha = np.zeros((self.size, self.size), np.float32)
        self.body = np.zeros((self.size, self.size), np.float32)

    def px(self, x: float, y: float) -> tuple[int, int]:
        """Canvas pixel (fixed point, 4 fractional bits) of a point in metres."""
        c = self.size / 2.0
        return int(round((c + x * self.scale) * 16)), int(round((c - y * self.scale) * 16))

    def _paint(
        self, mask: np.ndarray, colour: tuple[float, float, float], a: float, body: bool
    ) -> None:
        m = mask * a
        self.colour *= (1.0 - m)[..., None]
        self.colour += m[..., None] * np.asarray(colour, np.float32)
        self.alpha = m + self.alpha * (1.0 - m)
        if body:
            self.body = m + self.body * (1.0 - m)

    def _mask(self) -> np.ndarray:
        return np.zeros((self.size, self.size), np.float32)

    def ellipse(self, x, y, rx, ry, angle_deg, colour, a=1.0, body=True) -> None:
        """A filled ellipse centred at ``(x, y)`` m with semi-axes ``rx``, ``ry`` m."""
        mask = self._mask()
        axes = (max(1, int(rx * self.scale * 16)), max(1, int(ry * self.scale * 16)))
        cv2.ellipse(mask, self.px(x, y), axes, -angle_deg, 0, 360, 1.0, -1, cv2.LINE_AA, 4)
        self._paint(mask, colour, a, body)

    def limb(self, x0, y0, x1, y1, width, colour, a=1.0, body=True) -> None:
        """A rounded stroke ``width`` m thick from ``(x0, y0)`` to ``(x1, y1)``."""
        mask = self._mask()
        thick = max(1, int(round(width * self.scale)))
        cv2.line(mask, self.px(x0, y0), self.px(x1, y1), 1.0, thick, cv2.LINE_AA, 4)
        self._paint(mask, colour, a, body)

    def polygon(self, points, colour, a=1.0, body=True) -> None:
        """A filled polygon through ``points`` (metres)."""
        mask = self._mask()
        pts = np.array([self.px(x, y) for x, y in points], np.int32)
        cv2.fillPoly(mask, [pts], 1.0, cv2.LINE_AA, 4)
        self._paint(mask, colour, a, body)

    def speckle(self, rng, x, y, radius, count, dot, colour, a=1.0) -> None:
        """``count`` small dots (``dot`` m) scattered within ``radius`` m of ``(x, y)``: splash,
        foam, reflective tape. Never part of the body."""
        mask = self._mask()
        for _ in range(count):
            r, t = radius * math.sqrt(rng.random()), rng.random() * 2 * math.pi
            c = self.px(x + r * math.cos(t), y + r * math.sin(t))
            cv2.circle(
                mask,
                c,
                max(1, int(dot * self.scale * 16 * (0.5 + rng.random()))),
                1.0,
                -1,
                cv2.LINE_AA,
                4,
            )
        self._paint(mask, colour, a, False)


def place(
    frame: np.ndarray,
    canvas: Canvas,
    jacobian: np.ndarray,
    centre: tuple[float, float],
    heading_deg: float,
) -> tuple[float, float, float, float] | None:
    """Composite ``canvas`` into ``frame`` (float32 BGR, in place) at image point ``centre``,
    oriented ``heading_deg`` clockwise from north; the body's box ``(x, y, w, h)`` or ``None``
    when no body pixel lands in the frame."""
    psi = math.radians(heading_deg)
    # canvas pixel -> metres in the figure's frame -> ground east/north -> image pixels
    to_metres = np.array([[1.0 / canvas.scale, 0.0], [0.0, -1.0 / canvas.scale]])
    rotate = np.array([[math.cos(psi), math.sin(psi)], [-math.sin(psi), math.cos(psi)]])
    linear = jacobian @ rotate @ to_metres
    half = canvas.size / 2.0
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]]) @ linear.T
    x0 = int(math.floor(centre[0] + corners[:, 0].min())) - 1
    y0 = int(math.floor(centre[1] + corners[:, 1].min())) - 1
    x1 = int(math.ceil(centre[0] + corners[:, 0].max())) + 2
    y1 = int(math.ceil(centre[1] + corners[:, 1].max())) + 2
    height, width = frame.shape[:2]
    cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, width), min(y1, height)
    if cx0 >= cx1 or cy0 >= cy1:
        return None
    shrink = 1.0 / max(float(np.abs(np.linalg.svd(linear, compute_uv=False)).max()), 1e-6)
    sigma = 0.45 * shrink if shrink > 1.0 else 0.0
    layers = np.dstack([canvas.colour, canvas.alpha, canvas.body])
    if sigma > 0:
        layers = cv2.GaussianBlur(layers, (0, 0), sigma)
    offset = np.array([centre[0] - cx0, centre[1] - cy0]) - linear @ np.array([half, half])
    matrix = np.hstack([linear, offset[:, None]]).astype(np.float64)
    warped = cv2.warpAffine(layers, matrix, (cx1 - cx0, cy1 - cy0), flags=cv2.INTER_LINEAR)
    colour, alpha, body = warped[..., :3], warped[..., 3], warped[..., 4]
    region = frame[cy0:cy1, cx0:cx1]
    region *= (1.0 - alpha)[..., None]
    region += colour
    ys, xs = np.nonzero(body >= BOX_ALPHA)
    if len(xs) == 0:
        return None
    return (
        float(cx0 + xs.min()),
        float(cy0 + ys.min()),
        float(xs.max() - xs.min() + 1),
        float(ys.max() - ys.min() + 1),
    )
