"""A small training set and run configuration that several training tests share."""

from __future__ import annotations

from pathlib import Path

from synthetic_video import write_dataset

from sarmission.training.dataset import CropSettings
from sarmission.training.train import TrainConfig


def write_small_training_data(root: Path) -> dict[str, Path]:
    """Two short training videos and one validation video of the synthetic sea under ``root``,
    and a crop cache folder beside them."""
    return {
        "train": write_dataset(root / "train", n_videos=2, n_frames=14, seed=1),
        "val": write_dataset(root / "val", n_videos=1, n_frames=14, seed=2),
        "cache": root / "cache",
    }


def small_config(data: dict[str, Path], out: Path, **kw) -> TrainConfig:
    """Four epochs of batch 32 on ``data``'s crops (every other frame, 3 jitters per GT box);
    ``kw`` overrides any setting."""
    base = {
        "epochs": 4,
        "batch_size": 32,
        "crops": CropSettings(frame_stride=2, jitters_per_gt=3),
        "cache_dir": data["cache"],
        "progress": False,
    }
    return TrainConfig(train=data["train"], val=data["val"], out=out, **(base | kw))
