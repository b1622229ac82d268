"""A tiny annotated COCO-video dataset for training tests: short 320x240 sequences of small
moving blobs (bright swimmers, dark swimmers with an orange life jacket), a larger grey boat and
flickering sun glints over a textured sea, written as PNG frames plus a COCO video JSON.
Deterministic from a seed.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from sarmission.data.coco_video import (
    Annotation,
    Category,
    ImageRecord,
    Video,
    VideoDataset,
    write_coco_video,
)

CATEGORIES = (Category(1, "swimmer"), Category(2, "swimmer with life jacket"), Category(3, "boat"))


def _background(height: int, width: int, rng: np.random.Generator) -> np.ndarray:
    noise = rng.random((height, width)).astype(np.float32)
    tex = cv2.GaussianBlur(noise, (0, 0), 5.0)
    tex = (tex - tex.mean()) / max(float(tex.std()), 1e-6)
    sea = np.stack([0.45 + 0.05 * tex, 0.35 + 0.05 * tex, 0.15 + 0.04 * tex], axis=-1)
    return np.clip(sea, 0.0, 1.0)


def _paint(frame: np.ndarray, cx: float, cy: float, size: float, colour: tuple) -> None:
    yy, xx = np.mgrid[0 : frame.shape[0], 0 : frame.shape[1]].astype(np.float32)
    cover = np.clip(size / 2.0 + 0.5 - np.hypot(xx - cx, yy - cy), 0.0, 1.0)[..., None]
    frame[:] = frame * (1.0 - cover) + np.asarray(colour, np.float32) * cover


def write_dataset(
    folder: Path,
    n_videos: int = 2,
    n_frames: int = 16,
    seed: int = 0,
    height: int = 240,
    width: int = 320,
    targets: int = 4,
    glints: int = 6,
    boat_size: float = 14.0,
) -> Path:
    """Write the dataset under ``folder`` (``images/`` and ``annotations.json``); returns the
    JSON path. Each video has ``targets`` moving swimmers (alternating classes), one boat and
    ``glints`` sun glints per frame, each shown for one frame only (false motion); the boat
    is a disc ``boat_size`` pixels across.
    """
    rng = np.random.default_rng(seed)
    (folder / "images").mkdir(parents=True, exist_ok=True)
    videos, images, annotations = [], [], []
    for v in range(n_videos):
        videos.append(Video(v + 1, f"seq{v + 1}"))
        bg = _background(height, width, rng)
        # (category, size, colour BGR in [0,1], start, velocity)
        movers = []
        for k in range(targets):
            cat = 1 if k % 2 == 0 else 2
            colour = (0.95, 0.95, 0.95) if cat == 1 else (0.05, 0.35, 0.95)
            start = rng.uniform([40, 40], [width - 40, height - 40])
            velocity = rng.uniform(0.8, 1.6, 2) * rng.choice([-1, 1], 2)
            movers.append((cat, rng.uniform(4.0, 7.0), colour, start, velocity))
        movers.append(
            (
                3,
                boat_size,
                (0.6, 0.6, 0.6),
                rng.uniform([60, 60], [width - 60, height - 60]),
                rng.uniform(0.5, 1.0, 2),
            )
        )
        for f in range(n_frames):
            frame = bg.copy()
            image_id = v * 1000 + f + 1
            for cat, size, colour, start, velocity in movers:
                cx, cy = start + f * velocity
                _paint(frame, cx, cy, size, colour)
                if cat == 2:  # the dark swimmer's head in the orange jacket
                    _paint(frame, cx, cy, size * 0.4, (0.1, 0.1, 0.1))
                annotations.append(
                    Annotation(
                        len(annotations) + 1,
                        image_id,
                        cat,
                        (float(cx - size / 2), float(cy - size / 2), float(size), float(size)),
                        track_id=v * 100 + len(movers),
                        video_id=v + 1,
                    )
                )
            for gx, gy in rng.uniform([0, 0], [width, height], size=(glints, 2)):
                _paint(frame, gx, gy, rng.uniform(2.0, 4.0), (0.9, 0.9, 0.9))  # sun glint
            noisy = frame + rng.normal(0.0, 0.004, frame.shape)
            name = f"seq{v + 1}_{f:04d}.png"
            cv2.imwrite(
                str(folder / "images" / name),
                np.clip(np.rint(noisy * 255), 0, 255).astype(np.uint8),
            )
            images.append(ImageRecord(image_id, name, height, width, v + 1, f))
    path = folder / "annotations.json"
    write_coco_video(VideoDataset(videos, images, annotations, list(CATEGORIES)), path)
    return path
