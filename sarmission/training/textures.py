"""Procedural texture crops: hard negatives unlike any world the simulator renders.

A head trained on one renderer's backgrounds has never been told that bark, gravel, a tiled
roof or a furrowed field is nobody, and scores such ground as confidently as a person
(docs/background_only.md). These crops carry the statistics of natural images without any
renderer's look, and are fed to training as negatives (``TrainConfig.texture_negatives``).

Families (:data:`FAMILIES`), drawn in equal shares, each crop ``[3, S, S]`` RGB in [0, 1]:

* ``dead_leaves``: occluding discs with radii of density ``r^-3`` between 1 px and twice the
  crop (the dead-leaves model, whose scale invariance and ``1/f`` spectrum are those of natural
  images): gravel, foliage, rubble.
* ``fractal``: ``1/f^beta`` noise (``beta ~ U(1.2, 2.6)``) shaded between two colours, with
  a little colour noise per channel: grass, sand, snow, haze, water.
* ``grating``: oriented stripes (period 2-12 px, sine or square, two colours): furrows, fences,
  roof tiles, rows of crops, waves.
* ``edges``: one to three straight edges between flat colours: roofs, roads, field borders,
  shadows.

Colours are drawn from muted ground tones most of the time and from any colour otherwise.
Everything comes from one seeded ``numpy.random.Generator``: the same seed gives the same bank.

Negatives alone teach "textures are nobody", which may cost people seen on unfamiliar ground;
:func:`paste_on_textures` puts a positive crop's person on a texture
(``TrainConfig.texture_positives``) so that the head also learns the converse.
"""

from __future__ import annotations

import numpy as np

FAMILIES: tuple[str, ...] = ("dead_leaves", "fractal", "grating", "edges")
#: Share of colours drawn from any colour instead of muted ground tones.
VIVID_SHARE = 0.25
#: Discs painted per dead-leaves crop (later discs occlude earlier ones).
DEAD_LEAVES_DISCS = 48


def _colours(rng: np.random.Generator, n: int) -> np.ndarray:
    """``[n, 3]`` RGB: muted ground tones (grey to brown to green, low saturation) or, for a
    share :data:`VIVID_SHARE`, any colour."""
    grey = rng.uniform(0.05, 0.9, size=(n, 1))
    tint = rng.normal(0.0, 0.06, size=(n, 3))
    muted = np.clip(grey + tint, 0.0, 1.0)
    vivid = rng.uniform(0.0, 1.0, size=(n, 3))
    pick = rng.random(n) < VIVID_SHARE
    return np.where(pick[:, None], vivid, muted)


def _grid(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-centre coordinates ``(y, x)``, each ``[S, S]``, origin at the crop centre."""
    c = np.arange(size, dtype=np.float64) - (size - 1) / 2
    return np.meshgrid(c, c, indexing="ij")


def _shade(level: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``[n, S, S]`` levels in [0, 1] -> ``[n, 3, S, S]`` blended between two colours each."""
    n = level.shape[0]
    a, b = _colours(rng, n), _colours(rng, n)
    t = level[:, None]
    return a[:, :, None, None] * (1 - t) + b[:, :, None, None] * t


def dead_leaves(rng: np.random.Generator, n: int, size: int) -> np.ndarray:
    """Occluding discs (module docstring)."""
    y, x = _grid(size)
    out = np.repeat(_colours(rng, n)[:, :, None, None], size, axis=2).repeat(size, axis=3)
    r_min, r_max = 1.0, 2.0 * size
    for _ in range(DEAD_LEAVES_DISCS):
        # inverse CDF of density r^-3 on [r_min, r_max]
        u = rng.random(n)
        r = 1.0 / np.sqrt(u / r_max**2 + (1 - u) / r_min**2)
        cy, cx = rng.uniform(-size, size, size=(2, n))
        inside = (y[None] - cy[:, None, None]) ** 2 + (x[None] - cx[:, None, None]) ** 2 <= (
            r[:, None, None] ** 2
        )
        colour = _colours(rng, n)[:, :, None, None]
        out = np.where(inside[:, None], colour, out)
    return out


def fractal(rng: np.random.Generator, n: int, size: int) -> np.ndarray:
    """``1/f^beta`` noise shaded between two colours (module docstring)."""
    big = 2 * size
    fy = np.fft.fftfreq(big)[:, None]
    fx = np.fft.fftfreq(big)[None, :]
    f = np.sqrt(fy**2 + fx**2)
    f[0, 0] = 1.0
    beta = rng.uniform(1.2, 2.6, size=(n, 1, 1))
    spectrum = (rng.normal(size=(n, big, big)) + 1j * rng.normal(size=(n, big, big))) / f ** (
        beta / 2
    )
    spectrum[:, 0, 0] = 0.0
    field = np.fft.ifft2(spectrum).real[:, :size, :size]
    lo = field.min(axis=(1, 2), keepdims=True)
    hi = field.max(axis=(1, 2), keepdims=True)
    level = (field - lo) / np.maximum(hi - lo, 1e-9)
    out = _shade(level, rng)
    out += rng.normal(0.0, 1.0, size=out.shape) * rng.uniform(0.0, 0.03, size=(n, 1, 1, 1))
    return np.clip(out, 0.0, 1.0)


def grating(rng: np.random.Generator, n: int, size: int) -> np.ndarray:
    """Oriented stripes (module docstring)."""
    y, x = _grid(size)
    theta = rng.uniform(0.0, np.pi, size=(n, 1, 1))
    period = rng.uniform(2.0, 12.0, size=(n, 1, 1))
    phase = rng.uniform(0.0, 2 * np.pi, size=(n, 1, 1))
    wave = np.sin(2 * np.pi * (x * np.cos(theta) + y * np.sin(theta)) / period + phase)
    square = rng.random((n, 1, 1)) < 0.5
    level = np.where(square, (wave > 0).astype(np.float64), (wave + 1) / 2)
    return _shade(level, rng)


def edges(rng: np.random.Generator, n: int, size: int) -> np.ndarray:
    """One to three straight edges between flat colours (module docstring)."""
    y, x = _grid(size)
    out = np.repeat(_colours(rng, n)[:, :, None, None], size, axis=2).repeat(size, axis=3)
    count = rng.integers(1, 4, size=n)
    for k in range(3):
        theta = rng.uniform(0.0, 2 * np.pi, size=(n, 1, 1))
        offset = rng.uniform(-0.5 * size, 0.5 * size, size=(n, 1, 1))
        side = (x * np.cos(theta) + y * np.sin(theta)) > offset
        paint = side & (k < count)[:, None, None]
        out = np.where(paint[:, None], _colours(rng, n)[:, :, None, None], out)
    return out


_MAKERS = {"dead_leaves": dead_leaves, "fractal": fractal, "grating": grating, "edges": edges}


def texture_bank(count: int, size: int, seed: int) -> np.ndarray:
    """``count`` texture crops ``[count, 3, size, size]`` float32, the families in equal shares
    (in :data:`FAMILIES` order, then shuffled), deterministic from ``seed``."""
    if count < 0 or size < 1:
        raise ValueError(f"need count >= 0 and size >= 1, got {count} and {size}")
    rng = np.random.default_rng([seed, 0x7E7])
    shares = np.full(len(FAMILIES), count // len(FAMILIES))
    shares[: count % len(FAMILIES)] += 1
    parts = [_MAKERS[name](rng, int(k), size) for name, k in zip(FAMILIES, shares, strict=True)]
    bank = np.concatenate(parts, axis=0) if count else np.zeros((0, 3, size, size))
    return bank[rng.permutation(count)].astype(np.float32)


def person_mask(rgb: np.ndarray, low: float = 0.06, high: float = 0.15) -> np.ndarray:
    """Soft mask ``[n, S, S]`` of what stands out from a crop's surroundings: each pixel's
    largest channel difference from the median colour of the crop's border, ramped from
    ``low`` (0) to ``high`` (1). A person on smooth ground keeps body and shadow; the ground
    around goes."""
    border = np.concatenate(
        [rgb[:, :, 0, :], rgb[:, :, -1, :], rgb[:, :, 1:-1, 0], rgb[:, :, 1:-1, -1]], axis=2
    )
    ground = np.median(border, axis=2)[:, :, None, None]
    distance = np.abs(rgb - ground).max(axis=1)
    return np.clip((distance - low) / (high - low), 0.0, 1.0)


def paste_on_textures(rgb: np.ndarray, textures: np.ndarray) -> np.ndarray:
    """Crops ``[n, 3, S, S]`` with their surroundings (:func:`person_mask`) replaced by
    ``textures`` of the same shape: a person is a person on any ground."""
    mask = person_mask(rgb)[:, None]
    return mask * rgb + (1.0 - mask) * textures
