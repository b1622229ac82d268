"""Mission-level SAR metrics (paper section 5.1): search success rate, search time, false alarms.

Every frame of every sequence is matched with :func:`~sarmission.evaluation.matching.match_frame`
(one-to-one Hungarian on NWD, score > 0.5, NWD > 0.5). A ground-truth *trajectory* is one
``track_id`` within one sequence; its frames are the frames where it is annotated, in frame-index
order, and each is a hit when that GT box was matched. See :data:`DEFINITIONS` for the metrics.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from sarmission.data.coco_video import VideoDataset
from sarmission.evaluation.matching import FrameBoxes, ground_truth_by_image, match_frame
from sarmission.tracking.lock import first_lock_index

DEFINITIONS: dict[str, str] = {
    "search_success_rate": (
        "100 * locked trajectories / GT trajectories. A trajectory (one track_id within one "
        "sequence) is locked when it is matched in at least m of some k consecutive frames of "
        "its own annotated frames (ordered by frame index). GT boxes without a track id are "
        "matched but belong to no trajectory. n_lockable counts the trajectories annotated in at "
        "least m frames: a shorter one (e.g. entering the view in a clip's last frames) can "
        "never be locked, yet counts in the denominator."
    ),
    "search_time_frames": (
        "Per locked trajectory: frame_index(lock frame) - frame_index(first annotated frame); "
        "the lock frame is the frame of the m-th hit inside the first qualifying k-window, so "
        "the minimum is m - 1 for consecutive frame indices. avg and max over locked "
        "trajectories; None when none is locked."
    ),
    "false_alarm_rate_per_frame": (
        "100 * (unmatched detections with score > score_thr, summed over all frames) / "
        "(number of evaluated frames, with or without GT). Can exceed 100."
    ),
    "false_alarm_rate_detections": (
        "100 * (unmatched detections with score > score_thr) / (all detections with "
        "score > score_thr), over all frames; 0 when there are no such detections."
    ),
    "matching": (
        "Per frame, class-agnostic one-to-one Hungarian assignment on cost 1 - NWD "
        "(C = 12.8) among pairs with score > score_thr and NWD > nwd_thr, maximising the number "
        "of matches, then total NWD."
    ),
}


@dataclass(frozen=True)
class SequenceFrame:
    """One evaluated frame: its index in the video, GT (``ids`` = track ids) and detections."""

    frame_index: int
    ground_truth: FrameBoxes
    detections: FrameBoxes


@dataclass
class TrajectoryResult:
    """Outcome for one GT trajectory (``lock_frame`` / ``search_time`` are ``None`` if unlocked)."""

    sequence: str
    track_id: int
    first_frame: int
    last_frame: int
    n_frames: int
    n_hits: int
    lock_frame: int | None
    search_time: int | None


@dataclass
class SarMetrics:
    """Search success rate (%), search time (frames) and both false alarm rates (%)."""

    search_success_rate: float | None
    avg_search_time_frames: float | None
    max_search_time_frames: int | None
    false_alarm_rate_per_frame: float | None
    false_alarm_rate_detections: float
    n_trajectories: int
    n_locked: int
    n_lockable: int
    n_frames: int
    n_detections: int
    n_false_alarms: int
    n_matched: int
    m: int
    k: int
    score_thr: float
    nwd_thr: float
    trajectories: list[TrajectoryResult] = field(default_factory=list)
    definitions: dict[str, str] = field(default_factory=lambda: dict(DEFINITIONS))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-serialisable dict (trajectories as dicts, definitions included)."""
        return asdict(self)


def evaluate_sar(
    sequences: Mapping[Hashable, Sequence[SequenceFrame]],
    m: int = 3,
    k: int = 5,
    score_thr: float = 0.5,
    nwd_thr: float = 0.5,
) -> SarMetrics:
    """SSR, search time and false alarm rates over several sequences (see :data:`DEFINITIONS`).

    ``sequences`` maps a sequence name to its frames (any order; sorted by ``frame_index``).
    Rates are ``None`` where their denominator is zero, except the detection-level FAR (0).
    """
    hits: dict[tuple[str, int], list[tuple[int, bool]]] = {}
    n_frames = n_detections = n_false_alarms = n_matched = 0
    for name, frames in sequences.items():
        for frame in sorted(frames, key=lambda f: f.frame_index):
            match = match_frame(frame.detections, frame.ground_truth, score_thr, nwd_thr)
            n_frames += 1
            n_detections += match.n_candidates
            n_false_alarms += int(match.unmatched_detections.size)
            n_matched += int(match.det_indices.size)
            matched_gt = set(match.gt_indices.tolist())
            frame_hits: dict[int, bool] = {}
            for j, track_id in enumerate(frame.ground_truth.ids.tolist()):
                if track_id >= 0:
                    frame_hits[track_id] = frame_hits.get(track_id, False) or j in matched_gt
            for track_id, hit in frame_hits.items():
                hits.setdefault((str(name), track_id), []).append((frame.frame_index, hit))

    trajectories = []
    for (name, track_id), seq in hits.items():
        lock = first_lock_index([hit for _, hit in seq], m, k)
        lock_frame = None if lock is None else seq[lock][0]
        trajectories.append(
            TrajectoryResult(
                sequence=name,
                track_id=track_id,
                first_frame=seq[0][0],
                last_frame=seq[-1][0],
                n_frames=len(seq),
                n_hits=sum(hit for _, hit in seq),
                lock_frame=lock_frame,
                search_time=None if lock_frame is None else lock_frame - seq[0][0],
            )
        )

    times = [t.search_time for t in trajectories if t.search_time is not None]
    return SarMetrics(
        search_success_rate=100.0 * len(times) / len(trajectories) if trajectories else None,
        avg_search_time_frames=sum(times) / len(times) if times else None,
        max_search_time_frames=max(times) if times else None,
        false_alarm_rate_per_frame=100.0 * n_false_alarms / n_frames if n_frames else None,
        false_alarm_rate_detections=100.0 * n_false_alarms / n_detections if n_detections else 0.0,
        n_trajectories=len(trajectories),
        n_locked=len(times),
        n_lockable=sum(t.n_frames >= m for t in trajectories),
        n_frames=n_frames,
        n_detections=n_detections,
        n_false_alarms=n_false_alarms,
        n_matched=n_matched,
        m=m,
        k=k,
        score_thr=score_thr,
        nwd_thr=nwd_thr,
        trajectories=trajectories,
    )


def sequences_from_dataset(
    dataset: VideoDataset,
    detections: Mapping[int, FrameBoxes],
    category_ids: Sequence[int] | None = None,
) -> dict[str, list[SequenceFrame]]:
    """Build :func:`evaluate_sar` input from a COCO video dataset and detections by image id.

    Sequences are the dataset's videos by name (images without a video go to ``""``); frame
    index is the image's ``frame_index`` (else its position by image id). Images without an
    entry in ``detections`` have no detections. ``category_ids`` restricts the GT categories.
    """
    gt = ground_truth_by_image(dataset, category_ids)
    names = {v.id: v.name for v in dataset.videos}
    result: dict[str, list[SequenceFrame]] = {}
    for position, image in enumerate(sorted(dataset.images, key=lambda im: im.id)):
        name = "" if image.video_id is None else names.get(image.video_id, str(image.video_id))
        index = position if image.frame_index is None else image.frame_index
        result.setdefault(name, []).append(
            SequenceFrame(index, gt[image.id], detections.get(image.id, FrameBoxes.empty()))
        )
    return result
