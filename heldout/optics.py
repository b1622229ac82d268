"""From scene radiance to the pixels a drone camera records.

Exposure and vignette, optical blur and motion blur along the image velocity (one kernel),
a tone curve, then Poisson-Gaussian sensor noise and 8-bit quantisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Sensor:
    """Camera effects of one clip."""

    blur_sigma_px: float
    exposure_s: float
    shot_noise: float
    read_noise: float
    vignette: float


def blur_kernel(sigma_px: float, streak_px: tuple[float, float]) -> np.ndarray:
    """Gaussian optics convolved with a line ``streak_px`` (dx, dy) long: one normalised kernel."""
    length = math.hypot(*streak_px)
    half = int(math.ceil(3 * sigma_px + length / 2)) + 1
    size = 2 * half + 1
    kernel = np.zeros((size, size), np.float32)
    steps = max(1, int(math.ceil(length * 2)))
    for i in range(steps + 1):
        f = i / steps - 0.5 if steps else 0.0
        x, y = half + f * streak_px[0], half + f * streak_px[1]
        x0, y0 = int(math.floor(x)), int(math.floor(y))
        fx, fy = x - x0, y - y0
        kernel[y0, x0] += (1 - fx) * (1 - fy)
        kernel[y0, x0 + 1] += fx * (1 - fy)
        kernel[y0 + 1, x0] += (1 - fx) * fy
        kernel[y0 + 1, x0 + 1] += fx * fy
    kernel = cv2.GaussianBlur(kernel, (0, 0), max(sigma_px, 0.3))
    return kernel / kernel.sum()


#: Tone curve and noise level are looked up on this many steps of exposed radiance in [0, 8].
_TONE_STEPS = 4096
_TONE_RANGE = 8.0


def vignette(width: int, height: int, strength: float) -> np.ndarray:
    """Relative illumination ``[H, W]``: 1 at the centre, ``1 - strength`` in the corners."""
    yy, xx = np.ogrid[:height, :width]
    r2 = ((xx + 0.5 - width / 2) ** 2 + (yy + 0.5 - height / 2) ** 2) / (
        (width / 2) ** 2 + (height / 2) ** 2
    )
    return (1.0 - strength * r2).astype(np.float32)


def develop(
    radiance: np.ndarray,
    gain: np.ndarray,
    sensor: Sensor,
    streak_px: tuple[float, float],
    rng: np.random.Generator,
) -> np.ndarray:
    """BGR ``uint8`` frame of a linear ``radiance`` image; ``gain`` is exposure x vignette per
    pixel ``[H, W]``."""
    exposed = cv2.filter2D(
        radiance * gain[..., None],
        -1,
        blur_kernel(sensor.blur_sigma_px, streak_px),
        borderType=cv2.BORDER_REFLECT,
    )
    levels = np.linspace(0.0, _TONE_RANGE, _TONE_STEPS + 1, dtype=np.float32)
    toned = np.power(levels / (1.0 + 0.35 * levels), 1 / 2.2)
    sigma = np.sqrt(sensor.shot_noise * toned + sensor.read_noise**2)
    index = (
        np.minimum(np.maximum(exposed, 0.0), _TONE_RANGE) * (_TONE_STEPS / _TONE_RANGE) + 0.5
    ).astype(np.int32)
    noisy = (toned * 255.0)[index] + sigma[index] * rng.standard_normal(
        index.shape, dtype=np.float32
    )
    return np.clip(noisy + 0.5, 0, 255).astype(np.uint8)
