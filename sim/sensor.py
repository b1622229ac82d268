"""Full-resolution fine detail and sensor noise, added to an upsampled background.

Backgrounds are rendered at reduced resolution (fast) and upsampled; this adds back what an
upsampled image lacks, cheaply, as two saturating ``cv2.add`` of windows into precomputed
periodic tiles (no per-frame noise generation):

- ``grain``: spatially correlated fine texture (capillary ripples on water, surface grain on land),
  locked to the ground by integer pixel offsets that follow the ground's image motion, drifting
  slowly when ``drift_px_s`` is set (water ripples move by themselves);
- ``noise``: white sensor noise, a window at a new pseudo-random offset every frame.

Both tiles are non-negative with known means (:attr:`DetailOverlay.mean`); callers subtract that
mean from the background before adding, so the result is unbiased.
"""

from __future__ import annotations

import cv2
import numpy as np

TILE = 256


def _periodic_noise(
    rng: np.random.Generator, sigma_px: float, channels_gain: np.ndarray
) -> np.ndarray:
    """A TILE x TILE x 3 periodic float32 field, zero mean, unit std, smoothed by ``sigma_px``."""
    white = rng.standard_normal((TILE, TILE)).astype(np.float32)
    if sigma_px > 0:
        fy = np.fft.fftfreq(TILE)[:, None]
        fx = np.fft.fftfreq(TILE)[None, :]
        gauss = np.exp(-2 * (np.pi * sigma_px) ** 2 * (fx * fx + fy * fy))
        white = np.real(np.fft.ifft2(np.fft.fft2(white) * gauss)).astype(np.float32)
    white /= max(float(white.std()), 1e-6)
    return white[..., None] * channels_gain[None, None, :].astype(np.float32)


class DetailOverlay:
    """Adds ground-locked grain and fresh sensor noise to frames of one size."""

    def __init__(
        self,
        width: int,
        height: int,
        seed: int,
        grain_std: float,
        noise_std: float,
        grain_sigma_px: float = 0.8,
        grain_tint: tuple[float, float, float] = (1, 1, 1),
        drift_px_s: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        rng = np.random.default_rng([seed, 11])
        self.width, self.height = width, height
        self.drift_px_s = drift_px_s
        self.seed = seed
        grain = _periodic_noise(rng, grain_sigma_px, np.asarray(grain_tint, dtype=np.float32))
        noise = _periodic_noise(rng, 0.0, np.ones(3, dtype=np.float32))
        self._grain_mean = 2.5 * grain_std
        self._noise_mean = 2.5 * noise_std
        self._grain = self._tiled(grain * grain_std + self._grain_mean)
        self._noise = self._tiled(noise * noise_std + self._noise_mean)

    @property
    def mean(self) -> float:
        """Mean value the two additions put on every pixel (subtract it beforehand)."""
        return self._grain_mean + self._noise_mean

    def _tiled(self, tile: np.ndarray) -> np.ndarray:
        tile8 = np.clip(tile + 0.5, 0, 255).astype(np.uint8)
        reps = ((self.height + TILE) // TILE + 1, (self.width + TILE) // TILE + 1, 1)
        return np.ascontiguousarray(np.tile(tile8, reps)[: self.height + TILE, : self.width + TILE])

    def apply(self, frame: np.ndarray, ground_origin_px: tuple[float, float], t: float) -> None:
        """Add grain (anchored at the image position of a fixed ground point) and noise."""
        du, dv = self.drift_px_s
        ou = int(round(-(ground_origin_px[0] + du * t))) % TILE
        ov = int(round(-(ground_origin_px[1] + dv * t))) % TILE
        cv2.add(frame, self._grain[ov : ov + self.height, ou : ou + self.width], dst=frame)
        rng = np.random.default_rng([self.seed, 12, int(round(t * 1e6))])
        nu, nv = (int(k) for k in rng.integers(0, TILE, 2))
        cv2.add(frame, self._noise[nv : nv + self.height, nu : nu + self.width], dst=frame)
