"""Synthetic motion scenes for the vSTMD / TTM-RPN tests: a smooth textured background with a
small square or disc target moving over it. Deterministic from a seed; images are float32 in
[0, 1] (``to_bgr`` turns them into uint8 BGR frames).
"""

from __future__ import annotations

import cv2
import numpy as np


def textured_background(
    height: int,
    width: int,
    seed: int = 0,
    mean: float = 0.4,
    amplitude: float = 0.15,
    grain: float = 6.0,
) -> np.ndarray:
    """Smooth random texture: uniform noise blurred with sigma ``grain`` px, rescaled to
    ``mean +- amplitude``.
    """
    rng = np.random.default_rng(seed)
    noise = rng.random((height, width)).astype(np.float32)
    tex = cv2.GaussianBlur(noise, (0, 0), grain)
    tex = (tex - tex.mean()) / max(float(tex.std()), 1e-6)
    return np.clip(mean + amplitude * tex / 2.0, 0.0, 1.0).astype(np.float32)


def target_mask(
    height: int, width: int, cx: float, cy: float, size: float, shape: str = "square"
) -> np.ndarray:
    """Anti-aliased coverage in [0, 1] of a ``size``-px square (side) or disc (diameter) centred
    at ``(cx, cy)`` in pixel coordinates (pixel ``(i, j)`` has its centre at ``x = j, y = i``).
    """
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    if shape == "disc":
        dist = np.hypot(xx - cx, yy - cy)
        return np.clip(size / 2.0 + 0.5 - dist, 0.0, 1.0)
    if shape != "square":
        raise ValueError(f"shape must be 'square' or 'disc', got {shape!r}")
    half = size / 2.0
    mx = np.clip(np.minimum(xx + 0.5, cx + half) - np.maximum(xx - 0.5, cx - half), 0.0, 1.0)
    my = np.clip(np.minimum(yy + 0.5, cy + half) - np.maximum(yy - 0.5, cy - half), 0.0, 1.0)
    return mx * my


def render(
    background: np.ndarray,
    cx: float,
    cy: float,
    size: float,
    value: float = 0.95,
    shape: str = "square",
) -> np.ndarray:
    """Background with a target of intensity ``value`` pasted at ``(cx, cy)``."""
    m = target_mask(*background.shape, cx, cy, size, shape)
    return (background * (1.0 - m) + value * m).astype(np.float32)


def moving_target(
    height: int,
    width: int,
    n_frames: int,
    start: tuple[float, float],
    velocity: tuple[float, float],
    size: float,
    value: float = 0.95,
    shape: str = "square",
    seed: int = 0,
    background: np.ndarray | None = None,
) -> tuple[list[np.ndarray], np.ndarray]:
    """Frames of a target moving at constant ``velocity`` (px/frame, y down) from ``start``.

    Returns the frames and the ``[n_frames, 2]`` true centres ``(x, y)``.
    """
    bg = textured_background(height, width, seed) if background is None else background
    centres = np.asarray(start, np.float64) + np.arange(n_frames)[:, None] * np.asarray(velocity)
    frames = [render(bg, float(x), float(y), size, value, shape) for x, y in centres]
    return frames, centres


def to_bgr(image: np.ndarray) -> np.ndarray:
    """Float gray image in [0, 1] → uint8 BGR frame."""
    gray = np.clip(np.rint(image * 255.0), 0, 255).astype(np.uint8)
    return cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)


def periodic_texture(height: int, width: int, rng: np.random.Generator, grain: float) -> np.ndarray:
    """Spectrum of a periodic band-limited texture: uniform noise Gaussian-filtered with sigma
    ``grain`` px, zero mean (translate it with :func:`translated`).
    """
    spectrum = np.fft.fft2(rng.random((height, width)))
    fy = np.fft.fftfreq(height)[:, None]
    fx = np.fft.fftfreq(width)[None, :]
    spectrum *= np.exp(-2.0 * (np.pi * grain) ** 2 * (fx * fx + fy * fy))
    spectrum[0, 0] = 0.0
    return spectrum


def translated(spectrum: np.ndarray, dx: float, dy: float, amplitude: float) -> np.ndarray:
    """The texture of ``spectrum`` moved exactly by ``(dx, dy)`` px (Fourier phase ramp), scaled
    to a standard deviation of ``amplitude / 2``.
    """
    height, width = spectrum.shape
    fy = np.fft.fftfreq(height)[:, None]
    fx = np.fft.fftfreq(width)[None, :]
    scale = amplitude / (2.0 * np.sqrt(np.mean(np.abs(spectrum) ** 2)) / np.sqrt(spectrum.size))
    return scale * np.real(np.fft.ifft2(spectrum * np.exp(-2j * np.pi * (fx * dx + fy * dy))))


def drifting_scene(
    height: int,
    width: int,
    n_frames: int,
    camera_velocity: tuple[float, float],
    start: tuple[float, float],
    relative_velocity: tuple[float, float],
    size: float,
    value: float = 0.95,
    seed: int = 0,
    grain: float = 2.0,
    amplitude: float = 0.3,
) -> tuple[list[np.ndarray], np.ndarray]:
    """Frames seen from a translating camera: a periodic band-limited texture (Gaussian-filtered
    noise, sigma ``grain`` px) moves by ``camera_velocity`` px/frame, translated exactly by a
    Fourier phase ramp, and a target drifts over it at ``camera_velocity + relative_velocity``.

    Returns the frames (float32 in [0, 1]) and the ``[n_frames, 2]`` true target centres.
    """
    rng = np.random.default_rng(seed)
    spectrum = periodic_texture(height, width, rng, grain)
    cam = np.asarray(camera_velocity, np.float64)
    centres = np.asarray(start, np.float64) + np.arange(n_frames)[:, None] * (
        cam + np.asarray(relative_velocity)
    )
    frames = []
    for t, (cx, cy) in enumerate(centres):
        dx, dy = cam * t
        bg = np.clip(0.4 + translated(spectrum, dx, dy, amplitude), 0.0, 1.0).astype(np.float32)
        frames.append(render(bg, float(cx), float(cy), size, value))
    return frames, centres


def sea_scene(
    height: int,
    width: int,
    n_frames: int,
    camera_velocity: tuple[float, float],
    start: tuple[float, float],
    relative_velocity: tuple[float, float],
    size: float,
    value: float = 0.95,
    seed: int = 0,
    grain: float = 2.0,
    amplitude: float = 0.3,
    wave_velocity: tuple[float, float] = (1.0, -0.5),
    wave_grain: float = 3.0,
    wave_amplitude: float = 0.15,
    sparkles: int = 4,
    sparkle_size: float = 2.0,
) -> tuple[list[np.ndarray], np.ndarray]:
    """:func:`drifting_scene` with sea-like clutter: a second texture layer (waves, sigma
    ``wave_grain``) moving at ``camera_velocity + wave_velocity``, so that no single shift
    explains all the change, and ``sparkles`` bright ``sparkle_size``-px glints at random places,
    each lasting one frame. The target is drawn over both.
    """
    rng = np.random.default_rng(seed)
    ground = periodic_texture(height, width, rng, grain)
    waves = periodic_texture(height, width, rng, wave_grain)
    cam = np.asarray(camera_velocity, np.float64)
    wave = cam + np.asarray(wave_velocity, np.float64)
    centres = np.asarray(start, np.float64) + np.arange(n_frames)[:, None] * (
        cam + np.asarray(relative_velocity)
    )
    frames = []
    for t, (cx, cy) in enumerate(centres):
        bg = (
            0.4
            + translated(ground, *(cam * t), amplitude)
            + translated(waves, *(wave * t), wave_amplitude)
        )
        bg = np.clip(bg, 0.0, 1.0).astype(np.float32)
        for _ in range(sparkles):
            x, y = rng.uniform(4, width - 4), rng.uniform(4, height - 4)
            bg = render(bg, float(x), float(y), sparkle_size, 0.95, "disc")
        frames.append(render(bg, float(cx), float(cy), size, value))
    return frames, centres
