"""vSTMD constants and the size rule of its lobula kernel.

The front-end (:mod:`~sarmission.perception.vstmd`) and the camera-shift estimate
(:mod:`~sarmission.perception.ego_motion`) share these constants; keeping them apart lets each
import them without importing the other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sarmission.perception.types import VALID_DS


@dataclass(frozen=True)
class VSTMDParams:
    """vSTMD constants: the vSTMD paper's and its public implementation's, except the lobula's
    surround strength ``dog_e`` (1.5 instead of 3: the reference suppresses swimmers on a
    textured sea, docs/experiments.md)."""

    retina_size: int = 3
    retina_sigma: float = 1.0
    alpha: float = 0.25
    lamina_width: int = 20
    g_leak: float = 0.35
    v_rest: float = 0.0
    v_exc: float = 1.0
    #: Lobula kernel ``W = A [D]^+ - B [D]^-``, ``D = G(s1) - e G(s2) - rho``. ``dog_e`` is the
    #: surround strength; it must stay below ``(s2/s1)^2`` for the kernel to have an excitatory
    #: centre. The default e departs from the reference e = 3 (docs/experiments.md).
    dog_a: float = 1.0
    dog_b: float = 3.0
    dog_e: float = 1.5
    dog_rho: float = 0.0
    #: Reference kernel at full resolution (sigmas, surround strength) and the target size
    #: (full-res px) it prefers. The size rule keeps its excitatory-lobe radius per target size,
    #: ``lobe_radius(s1_ref, s2_ref, e_ref) / size_ref``, for any ``dog_e``; ``s2 / s1`` stays
    #: ``sigma2_ref / sigma1_ref``.
    sigma1_ref: float = 5.0
    sigma2_ref: float = 10.0
    dog_e_ref: float = 3.0
    size_ref: float = 6.25
    #: Smallest centre sigma in map pixels (below this the Gaussian is a single tap).
    min_sigma: float = 0.5
    #: The lobula runs at 1/ds_L, ``ds_L = 2 ds`` clamped to this range (powers of two up to 8;
    #: ``(1, 1)`` = on the 1/ds map).
    lobula_ds_range: tuple[int, int] = (4, 8)
    #: ... and no coarser than where the centre sigma is at least this many pixels.
    lobula_min_sigma: float = 0.8
    #: Gaussian kernels are cut at this many sigmas.
    truncate: float = 3.0
    #: Ego-motion estimation: largest image (width, height) the shift is estimated on.
    ego_max_size: tuple[int, int] = (480, 270)
    #: Smallest drop of the mean absolute frame difference (intensity in [0, 1]) a shift must
    #: explain to be accepted (about half a grey level).
    ego_min_gain: float = 0.002
    #: Largest remaining share of the frame difference after the shift for it to be accepted.
    ego_max_ratio: float = 0.8
    #: Smallest share of the image whose frame difference exceeds ``ego_change_level`` for a
    #: shift to be accepted: the camera moves everything, a target only a small part.
    ego_min_changed: float = 0.2
    ego_change_level: float = 0.01
    #: Gauss-Newton refinement: most iterations and the step (estimation pixels) that stops it.
    ego_iterations: int = 5
    ego_tolerance: float = 0.005

    def __post_init__(self) -> None:
        ratio = self.sigma2_ref / self.sigma1_ref
        if not (self.sigma1_ref > 0 and ratio > 1):
            raise ValueError(
                f"need 0 < sigma1_ref < sigma2_ref, got {self.sigma1_ref}, {self.sigma2_ref}"
            )
        for name in ("dog_e", "dog_e_ref"):
            e = getattr(self, name)
            if not 0 < e < ratio * ratio:
                raise ValueError(
                    f"{name} must be in (0, (sigma2/sigma1)^2 = {ratio * ratio:g}) "
                    f"for the kernel to have an excitatory centre, got {e}"
                )
        low, high = self.lobula_ds_range
        if low not in VALID_DS or high not in VALID_DS or low > high:
            raise ValueError(
                f"lobula_ds_range must be two of {VALID_DS} in order, got {self.lobula_ds_range}"
            )
        if not (self.dog_a > 0 and self.dog_b >= 0):
            raise ValueError(f"need dog_a > 0 and dog_b >= 0, got {self.dog_a}, {self.dog_b}")

    def lobe_per_size(self) -> float:
        """Excitatory-lobe radius per preferred target size of the reference kernel
        (``lobe_radius(s1_ref, s2_ref, e_ref) / size_ref``, about 0.70)."""
        return lobe_radius(self.sigma1_ref, self.sigma2_ref, self.dog_e_ref) / self.size_ref

    def lamina_coefficients(self) -> tuple[float, float]:
        """``(a0, decay)`` of the lamina recursion ``L_t = a0 * D_t + decay * L_{t-1}``."""
        rate = self.alpha / (1.0 - self.alpha)
        a0 = 1.0 / sum(math.exp(-rate * j) for j in range(self.lamina_width))
        return a0, math.exp(-rate)


def lobe_radius(sigma1: float, sigma2: float, e: float) -> float:
    """Radius where ``G(s1) - e * G(s2)`` (2-D Gaussians, unit integral, ``rho = 0``) crosses zero.

    ``exp(-r^2 / 2 s1^2) / s1^2 = e * exp(-r^2 / 2 s2^2) / s2^2`` gives, with ``k = s2 / s1``::

        r = s1 * sqrt(2 k^2 ln(k^2 / e) / (k^2 - 1))       (k = 2: s1 * sqrt(8/3 * ln(4 / e)))

    defined for ``0 < e < k^2``: 0.88 s1 for e = 3, 1.62 s1 for e = 1.5, 1.92 s1 for e = 1.
    """
    k2 = (sigma2 / sigma1) ** 2
    if not (k2 > 1 and 0 < e < k2):
        raise ValueError(
            f"need sigma2 > sigma1 and 0 < e < (sigma2/sigma1)^2, got {sigma1}, {sigma2}, {e}"
        )
    return sigma1 * math.sqrt(2.0 * k2 * math.log(k2 / e) / (k2 - 1.0))


def gaussian_1d(sigma: float, radius: int) -> np.ndarray:
    """Sampled Gaussian ``exp(-x^2 / (2 sigma^2))`` on ``x = -radius..radius``, unit sum."""
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    g = np.exp(-(x * x) / (2.0 * sigma * sigma))
    return g / g.sum()


def check_ds(ds: int) -> int:
    """``ds`` as an int, or a ValueError naming the valid pooling factors."""
    if isinstance(ds, bool) or int(ds) != ds or int(ds) not in VALID_DS:
        raise ValueError(f"ds must be one of {VALID_DS} (average-pooling factor), got {ds!r}")
    return int(ds)
