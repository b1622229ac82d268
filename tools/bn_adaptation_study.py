"""A head whose batch-norm statistics are re-estimated on unlabelled footage (a study).

Under a shift of domain (another sea, another camera) the statistics a head's batch-norm layers
learnt in training no longer describe what its layers see; re-estimating them on the target
footage, labels unneeded, is a common way to adapt a network to it. This tool runs the
detector over annotated clips (their annotations are not read, only their frames), keeps the
crops it cuts of every proposal in every ``--every``-th frame, and writes the shipped head with
its batch-norm statistics replaced by those crops' (weights unchanged), as ``.pt`` and ONNX::

    python tools/bn_adaptation_study.py --out /tmp/bn/adapted.pt \
        --clips '/tmp/sarmission-heldout-alerts/heldout_*/heldout_*_15?/heldout_*.json'
    python tools/heldout_alerts.py fly LABEL --split validation --model /tmp/bn/adapted.onnx

Measured in docs/experiments.md ("batch-norm statistics of the footage").
"""

from __future__ import annotations

import argparse
import glob
import sys
from pathlib import Path

import numpy as np
import torch

from sarmission.cli import main as sarmission
from sarmission.data.coco_video import read_coco_video
from sarmission.data.sequence import iter_sequence, sequence_ids
from sarmission.models import DEFAULT_TORCH_MODEL
from sarmission.perception.crops import motion_enhanced_crops
from sarmission.perception.head import MiteHead
from sarmission.perception.mitenet import MiteNet
from sarmission.perception.runtime import (
    TorchHeadRuntime,
    load_head_checkpoint,
    save_head_checkpoint,
)

#: Frames skipped at the start of each clip while the motion front-end settles.
WARM_UP_FRAMES = 3
BATCH = 256


def proposal_crops(annotation_files: list[Path], every: int, model: Path) -> np.ndarray:
    """The head's input crops ``[N, C, S, S]`` of every proposal in every ``every``-th frame."""
    net = MiteNet(TorchHeadRuntime(load_head_checkpoint(model)))
    kept: list[np.ndarray] = []
    for path in annotation_files:
        dataset = read_coco_video(path)
        for video_id in sequence_ids(dataset):
            net.reset()
            for i, frame in enumerate(iter_sequence(dataset, video_id)):
                result = net.process(frame.frame_bgr, i / 30.0)
                if i < WARM_UP_FRAMES or i % every or len(result.proposals.boxes) == 0:
                    continue
                kept.append(
                    motion_enhanced_crops(
                        frame.frame_bgr,
                        result.motion,
                        result.proposals.boxes,
                        result.proposals.polarity,
                        motion_floor=net.motion_floor,
                    )
                )
        print(f"{path}: {sum(len(c) for c in kept)} crops so far", flush=True)
    if not kept:
        raise SystemExit("no proposal in any frame of those clips")
    return np.concatenate(kept)


@torch.no_grad()
def with_statistics_of(model: MiteHead, crops: np.ndarray) -> MiteHead:
    """``model`` with every batch-norm layer's running mean and variance the average of their
    values over batches of :data:`BATCH` of ``crops`` (in a fixed shuffled order: torch's
    cumulative average); weights untouched."""
    for layer in model.modules():
        if isinstance(layer, torch.nn.modules.batchnorm._BatchNorm):
            layer.reset_running_stats()
            layer.momentum = None  # a cumulative average over every batch
            layer.train()
    x = torch.from_numpy(crops)
    order = torch.randperm(len(x), generator=torch.Generator().manual_seed(0))
    for start in range(0, len(x), BATCH):
        model(x[order[start : start + BATCH]])
    return model.eval()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--clips", required=True, help="glob of COCO-video annotation files")
    parser.add_argument("--out", type=Path, required=True, help="the adapted head (.pt)")
    parser.add_argument("--every", type=int, default=3, help="every N-th frame (default 3)")
    parser.add_argument("--model", type=Path, default=DEFAULT_TORCH_MODEL)
    args = parser.parse_args(argv)
    files = [Path(p) for p in sorted(glob.glob(args.clips))]
    if not files:
        raise SystemExit(f"no file matches {args.clips!r}")
    crops = proposal_crops(files, max(1, args.every), args.model)
    save_head_checkpoint(with_statistics_of(load_head_checkpoint(args.model), crops), args.out)
    print(f"wrote {args.out} ({len(crops)} crops of {len(files)} files)")
    return sarmission(
        ["export", "--model", str(args.out), "--out", str(args.out.with_suffix(".onnx"))]
    )


if __name__ == "__main__":
    sys.exit(main())
