"""The camera's own marks on a frame: exposure, white balance, vignetting, defocus, colour
fringes and sensor noise, drawn once per clip (:class:`Optics`) and applied per frame."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np


@dataclass(frozen=True)
class Optics:
    """One clip's camera response."""

    gain: float
    balance: tuple[float, float, float]
    gamma: float
    vignette: float
    defocus: float
    fringe: float
    noise: float

    @classmethod
    def draw(cls, rng: np.random.Generator) -> Optics:
        return cls(
            gain=float(rng.uniform(0.8, 1.2)),
            balance=tuple(float(x) for x in rng.uniform(0.92, 1.08, 3)),
            gamma=float(rng.uniform(0.85, 1.15)),
            vignette=float(rng.uniform(0.0, 0.35)),
            defocus=float(rng.uniform(0.0, 0.8)),
            fringe=float(rng.uniform(0.0, 0.6)),
            noise=float(rng.uniform(1.0, 5.0)),
        )

    def apply(self, frame: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """``frame`` (float32 BGR 0-255) as this camera records it, uint8."""
        height, width = frame.shape[:2]
        out = frame * (self.gain * np.asarray(self.balance, np.float32))[None, None, :]
        if self.vignette > 0:
            out *= (1.0 - self.vignette * _radius2(width, height)).astype(np.float32)[..., None]
        out = 255.0 * (np.clip(out, 0, 255) / 255.0) ** self.gamma
        if self.defocus > 0.2:
            out = cv2.GaussianBlur(out, (0, 0), self.defocus)
        if self.fringe > 0.1:
            shift = np.float32([[1, 0, self.fringe], [0, 1, 0]])
            out[..., 2] = cv2.warpAffine(
                out[..., 2], shift, (width, height), borderMode=cv2.BORDER_REFLECT
            )
            shift[0, 2] = -self.fringe
            out[..., 0] = cv2.warpAffine(
                out[..., 0], shift, (width, height), borderMode=cv2.BORDER_REFLECT
            )
        out += rng.standard_normal(out.shape, dtype=np.float32) * np.float32(self.noise)
        return np.clip(out, 0, 255).astype(np.uint8)


@lru_cache(maxsize=4)
def _radius2(width: int, height: int) -> np.ndarray:
    """Squared distance of every pixel from the frame's centre, in half-widths (the same for
    every frame of a clip, so computed once)."""
    y, x = np.ogrid[:height, :width]
    return ((x - width / 2) / (width / 2)) ** 2 + ((y - height / 2) / (width / 2)) ** 2
