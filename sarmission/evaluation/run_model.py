"""Run MITE-Net over every video of an annotated dataset, and the (ds, N) scalability sweep.

Frames come from :func:`sarmission.data.sequence.iter_sequence` in frame order; the detector is
reset between videos, so every video starts with a fresh motion state. Frames that cannot be read
are skipped (and counted); they get no entry in the results.
"""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sarmission.data.coco_video import VideoDataset
from sarmission.data.sequence import iter_sequence, sequence_ids, sequence_images
from sarmission.evaluation.matching import FrameBoxes
from sarmission.evaluation.report import evaluate_detections
from sarmission.perception.mitenet import MiteNet
from sarmission.perception.runtime import HeadRuntime

#: Nominal frame rate for the timestamps passed to the detector (they do not change its output).
NOMINAL_FPS = 30.0


@dataclass
class ModelRun:
    """What the detector produced, per image id.

    ``detections`` carry the head's class index and score; ``proposals`` the RPN boxes and
    scores (class 0). ``frame_ms`` is the wall time of every processed frame, ``stage_ms`` each
    stage's (``MiteNet.per_stage_ms``) per processed frame, ``frame_size``
    the ``(height, width)`` of the first one (``None`` when none was read) and ``skipped`` the
    number of frames that could not be read.
    """

    detections: dict[int, FrameBoxes] = field(default_factory=dict)
    proposals: dict[int, FrameBoxes] = field(default_factory=dict)
    frame_ms: list[float] = field(default_factory=list)
    stage_ms: dict[str, list[float]] = field(default_factory=dict)
    frame_size: tuple[int, int] | None = None
    skipped: int = 0

    @property
    def image_ids(self) -> list[int]:
        """Ids of the processed images."""
        return list(self.detections)

    @property
    def median_ms(self) -> float | None:
        """Median wall time per frame (ms), ``None`` when no frame was processed."""
        return float(statistics.median(self.frame_ms)) if self.frame_ms else None


def count_frames(dataset: VideoDataset, max_frames: int | None = None) -> int:
    """Frames :func:`run_mitenet` will try to read (``max_frames`` per video)."""
    counts = [len(sequence_images(dataset, vid)) for vid in sequence_ids(dataset)]
    return sum(counts if max_frames is None else (min(c, max_frames) for c in counts))


def run_mitenet(
    net: MiteNet,
    dataset: VideoDataset,
    max_frames: int | None = None,
    progress: bool = True,
    desc: str = "eval",
    person_px_of: Callable[[Any], Callable[[np.ndarray], np.ndarray] | None] | None = None,
) -> ModelRun:
    """Run ``net`` over every video of ``dataset`` (at most ``max_frames`` frames per video);
    ``person_px_of`` gives, per image record, the pixels a person spans at its points (crops
    sized to the person: :meth:`MiteNet.process`), or None.

    The net is reset before each video. A tqdm bar on stderr shows progress unless
    ``progress`` is false.
    """
    from tqdm import tqdm

    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames must be at least 1, got {max_frames}")
    run = ModelRun()
    counters: dict[str, int] = {}
    with tqdm(
        total=count_frames(dataset, max_frames),
        unit="frame",
        desc=desc,
        file=sys.stderr,
        disable=not progress,
    ) as bar:
        for video_id in sequence_ids(dataset):
            net.reset()
            for position, item in enumerate(iter_sequence(dataset, video_id, counters)):
                if max_frames is not None and position >= max_frames:
                    break
                frame = item.frame_bgr
                start = time.perf_counter()
                person_px = None if person_px_of is None else person_px_of(item.image)
                result = net.process(frame, position / NOMINAL_FPS, person_px=person_px)
                run.frame_ms.append((time.perf_counter() - start) * 1e3)
                for stage, ms in net.per_stage_ms.items():
                    run.stage_ms.setdefault(stage, []).append(ms)
                if run.frame_size is None:
                    run.frame_size = (int(frame.shape[0]), int(frame.shape[1]))
                det, prop = result.detections, result.proposals
                run.detections[item.image.id] = FrameBoxes.of(det.boxes, det.scores, det.class_ids)
                run.proposals[item.image.id] = FrameBoxes.of(prop.boxes, prop.scores)
                bar.update(1)
    run.skipped = counters.get("skipped", 0)
    return run


def run_sweep(
    head: HeadRuntime,
    dataset: VideoDataset,
    ds_values: Sequence[int],
    topn_values: Sequence[int],
    *,
    m: int = 3,
    k: int = 5,
    score_thr: float = 0.5,
    nwd_thr: float = 0.5,
    max_frames: int | None = None,
    progress: bool = True,
    **detector: Any,
) -> list[dict[str, Any]]:
    """Evaluate every (ds, N) configuration on ``dataset`` (paper Table 4), one row each;
    ``detector`` holds MiteNet's other keyword options (score threshold, crop scales, ...).

    Row keys: ``ds``, ``topn``, ``ssr`` and ``far_per_frame`` (%), ``far_detections`` (%),
    ``avg_search_time_frames``, ``median_ms`` and ``fps`` (measured in this run), ``frames``,
    ``gflops`` per stage (``vstmd``, ``rpn_other``, ``head``, ``total``; ``MiteNet.complexity``
    at the dataset's frame size) and ``rpn_recall`` / ``head_recall`` (R@0.1, R@0.5).
    """
    rows = []
    for ds in ds_values:
        for topn in topn_values:
            net = MiteNet(head, ds=ds, topn=topn, **detector)
            run = run_mitenet(net, dataset, max_frames, progress, desc=f"ds={ds} N={topn}")
            if run.frame_size is None or run.median_ms is None:
                raise ValueError("no frame of the dataset could be read")
            report = evaluate_detections(
                dataset,
                run.detections,
                net.classes,
                run.proposals,
                m=m,
                k=k,
                score_thr=score_thr,
                nwd_thr=nwd_thr,
                image_ids=run.image_ids,
            )
            flops = net.complexity(*run.frame_size)["flops"]
            sar = report["sar"]
            rows.append(
                {
                    "ds": ds,
                    "topn": topn,
                    "ssr": sar["search_success_rate"],
                    "far_per_frame": sar["false_alarm_rate_per_frame"],
                    "far_detections": sar["false_alarm_rate_detections"],
                    "avg_search_time_frames": sar["avg_search_time_frames"],
                    "median_ms": run.median_ms,
                    "fps": 1e3 / run.median_ms,
                    "frames": len(run.frame_ms),
                    "gflops": {stage: value / 1e9 for stage, value in flops.items()},
                    "rpn_recall": report["module_recall"]["rpn"],
                    "head_recall": report["module_recall"]["head"],
                }
            )
    return rows
