"""Cached crop dataset for the MITE-Net head: every crop is cut once, the way inference cuts it.

For each annotated video, frames go in order through vSTMD (``ds = 1`` by default, as the paper
trains) and TTM-RPN; at every ``frame_stride``-th frame after ``warmup_frames`` (vSTMD needs a few
frames before it responds) the frame yields:

* **RPN samples**: every proposal (motion and colour, ``colour_share``), labelled by NWD
  assignment to the frame's target GT
  (:func:`~.sampling.assign_by_nwd`): positive (class of its best GT) when ``NWD >= pos_nwd``,
  otherwise negative. Crops come from
  :func:`~sarmission.perception.crops.motion_enhanced_crops` with the proposal boxes and
  polarities exactly as :class:`~sarmission.perception.mitenet.MiteNet` makes them.
* **Jittered GT samples** (training only, ``jitters_per_gt > 0``): squares of side
  ``box_size * (1 ± jitter_scale)`` around GT centres shifted by up to ``jitter_shift`` of the side
  (:func:`~.sampling.jitter_boxes`), labelled with the GT's class and cut with sampling ratio 1
  (a 16-px proposal's ratio at inference). Their polarity is the one the RPN would give: the sign
  of ``L`` at the strongest response ``R`` within a ``box_size`` square around the GT centre (the
  RPN's peak sits on the trailing edge, where a bright target leaves ``L < 0``), or at the GT centre
  when ``R`` is zero there. The default shift, half a side (±8 px for 16-px boxes), spans the
  offsets of the RPN's own boxes on targets (its peak on the trailing edge, the 0.3 S forward
  shift); with a quarter side the head learned centred targets only (docs/experiments.md).
* **Background negatives** (training only, ``background_negatives > 0``): that many squares of side
  ``box_size`` at uniformly drawn places of the frame, each further than NWD 0.1 from every target
  GT box (the first that qualify of four times as many drawn places), labelled negative and cut
  like the jittered GT, with the RPN-like polarity there. The RPN shows the head only the
  frame's 25 most salient spots; these show it the rest of the background (water, land,
  clutter) too.
* **Object negatives** (training only, ``object_negatives > 0``): that many jittered squares per
  annotated object that is not a search target (a category whose role is ``object`` in
  :mod:`sarmission.class_roles` and no head class: boats, debris, birds, sun glints, buoys), cut
  like the jittered GT and labelled negative, unless a square lies within NWD 0.1 of a target
  GT box (a person on a boat's deck stays a person). The RPN shows the head such clutter only
  when it is among the frame's most salient spots; these show it every annotated distractor,
  the false alarms a search meets most.
* **Context crops** (training only, ``object_context > 0``): that many wide squares per target GT
  box larger than S (:func:`~.sampling.context_boxes`: side 1.2-2.5 times the box's, 2-8 S,
  centred on part of it), labelled with its class, and that many wide squares of open
  background per frame (:func:`~.sampling.context_negative_boxes`), all cut like the jittered
  GT. Inference's wider crop scales (``crop_scales``) then see a boat whole where the 16-px
  crop sees its cabin; without these the head meets crops of 4 or 8 S only at inference.

Targets: annotations of the categories that map to a head class
(:func:`sarmission.evaluation.report.target_category_map`: normalised name equal to a class or an
alias such as ``floater``), crowd annotations excepted. Every other category (boats, buoys,
``ignored`` regions) is background: proposals on them are ordinary negatives, matching the
evaluation, where detections on them are false alarms.

Box targets are ``l, t, r, b``: distances from the crop centre to the GT edges in crop pixels
(one crop pixel = box side / crop size full-resolution pixels), the inverse of
:func:`~sarmission.perception.head.ltrb_to_boxes`.

The cache file is ``<cache_dir>/crops-<key>.pt`` with ``key`` a hash of the annotation file's
resolved path, size and modification time, :data:`CACHE_VERSION`, the source of the modules that
cut and label the crops (:func:`source_fingerprint`) and the settings; a second run with the same
inputs and code loads it instead of decoding the video again. Image files are not hashed.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import logging
import os
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from sarmission.boxes import xywh_to_xyxy
from sarmission.class_roles import role_of
from sarmission.data.coco_video import ImageRecord, VideoDataset, read_coco_video
from sarmission.data.sequence import iter_sequence, sequence_ids, sequence_images
from sarmission.evaluation.report import target_category_map
from sarmission.perception.chroma import chroma_if_wanted
from sarmission.perception.crops import CROP_SIZE, motion_enhanced_crops
from sarmission.perception.head import DEFAULT_CLASSES
from sarmission.perception.rpn import TTMRPN
from sarmission.perception.types import DEFAULT_COLOUR_SHARE, MotionMaps
from sarmission.perception.vstmd import VSTMD, full_to_map_index
from sarmission.training.sampling import (
    assign_by_nwd,
    context_boxes,
    context_negative_boxes,
    jitter_boxes,
)

log = logging.getLogger(__name__)

#: Version of the cache file's layout. The proposals and crops themselves are keyed by the source
#: of the modules that make them (:data:`RECIPE_MODULES`), so that a cache cut by older code is
#: never mistaken for the current recipe (a hand-bumped version once missed a change of the
#: chroma map; docs/experiments.md).
CACHE_VERSION = 2
CACHE_FORMAT = "sarmission.crop_cache"


@dataclass(frozen=True)
class CropSettings:
    """How crops are cut (part of the cache key).

    ``target_size`` ``None`` keeps the vSTMD default; ``topn``, ``box_size`` and
    ``colour_share`` are the RPN's N, S and share of colour proposals; ``jitters_per_gt`` 0
    disables GT jittering (validation), ``background_negatives`` 0 the background negatives and
    ``object_negatives`` 0 the object negatives (the defaults, and validation); ``crop_dtype`` is
    ``"float16"`` or ``"float32"``; ``object_parts`` labels RPN proposals on part of a larger
    object of a head class (see :func:`part_of_objects`); ``motion_floor`` the head's motion floor
    (:func:`~sarmission.perception.crops.enhanced_response`), recorded in the trained head.
    """

    classes: tuple[str, ...] = DEFAULT_CLASSES
    ds: int = 1
    target_size: float | None = None
    topn: int = 25
    box_size: float = 16.0
    colour_share: float = DEFAULT_COLOUR_SHARE
    frame_stride: int = 5
    warmup_frames: int = 3
    pos_nwd: float = 0.4
    jitters_per_gt: int = 4
    jitter_scale: float = 0.2
    jitter_shift: float = 0.5
    background_negatives: int = 0
    object_negatives: int = 0
    object_parts: bool = False
    object_context: int = 0
    seed: int = 0
    crop_dtype: str = "float16"
    motion_floor: float = 0.0

    def validate(self) -> None:
        """Raise ``ValueError`` for settings that cannot build a dataset."""
        if not self.classes:
            raise ValueError("at least one class is needed")
        if (
            self.frame_stride < 1
            or self.warmup_frames < 0
            or self.jitters_per_gt < 0
            or self.background_negatives < 0
            or self.object_negatives < 0
            or self.object_context < 0
        ):
            raise ValueError(
                "frame_stride must be >= 1, warmup_frames, jitters_per_gt, "
                "background_negatives, object_negatives and object_context >= 0"
            )
        if not 0.0 <= self.jitter_shift <= 4.0:  # NaN too: checked before any crop is cut
            raise ValueError(f"jitter_shift must be in [0, 4], got {self.jitter_shift}")
        if not 0.0 <= self.colour_share <= 1.0:
            raise ValueError(f"colour_share must be in [0, 1], got {self.colour_share}")
        if not 0.0 < self.pos_nwd <= 1.0:
            raise ValueError(f"pos_nwd must be in (0, 1], got {self.pos_nwd}")
        if not 0.0 <= self.motion_floor < 1.0:
            raise ValueError(f"motion_floor must be in [0, 1), got {self.motion_floor}")
        if self.crop_dtype not in ("float16", "float32"):
            raise ValueError(f"crop_dtype must be float16 or float32, got {self.crop_dtype!r}")

    def to_dict(self) -> dict:
        """JSON-friendly dict."""
        d = asdict(self)
        d["classes"] = list(self.classes)
        return d


@dataclass
class CropSet:
    """Crops of one annotation file and the GT of the frames they came from.

    Per crop (``N``): ``crops [N, 4, S, S]``, ``labels [N]`` (class index, -1 negative),
    ``target_ltrb [N, 4]`` (crop pixels; zeros for negatives), ``boxes [N, 4]`` (the cropped box,
    full-resolution xyxy), ``image_ids [N]``, ``jittered [N]`` (True for jittered GT samples).
    Per sampled frame: ``frame_ids [F]``; per target GT box of those frames (``M``):
    ``gt_boxes [M, 4]`` xyxy, ``gt_classes [M]``, ``gt_image_ids [M]``.
    """

    crops: Tensor
    labels: Tensor
    target_ltrb: Tensor
    boxes: Tensor
    image_ids: Tensor
    jittered: Tensor
    frame_ids: Tensor
    gt_boxes: Tensor
    gt_classes: Tensor
    gt_image_ids: Tensor
    settings: dict = field(default_factory=dict)
    #: Frames that could not be read when the set was cut (missing or broken images); such a
    #: set is not cached, so the frames are read again once they are there.
    frames_unread: int = 0

    def __len__(self) -> int:
        return int(self.labels.shape[0])

    @property
    def scale(self) -> Tensor:
        """``[N, 2]`` full-resolution pixels per crop pixel (box width, height / crop size)."""
        side = self.crops.shape[-1]
        return (
            torch.stack(
                [self.boxes[:, 2] - self.boxes[:, 0], self.boxes[:, 3] - self.boxes[:, 1]], dim=1
            )
            / side
        )

    def summary(self) -> str:
        """One line: crops, positives (RPN / jittered), negatives, frames, GT boxes."""
        pos = self.labels >= 0
        return (
            f"{len(self)} crops: {int((pos & ~self.jittered).sum())} RPN positives, "
            f"{int((pos & self.jittered).sum())} jittered GT, {int((~pos).sum())} negatives "
            f"from {len(self.frame_ids)} frames with {len(self.gt_boxes)} GT boxes"
        )

    def to_state(self) -> dict:
        """Plain dict for ``torch.save`` (loadable with ``weights_only=True``)."""
        state = {k: getattr(self, k) for k in _TENSOR_FIELDS}
        state.update(format=CACHE_FORMAT, version=CACHE_VERSION, settings=self.settings)
        return state

    @classmethod
    def from_state(cls, state: dict) -> CropSet:
        """Inverse of :meth:`to_state`; ``ValueError`` for another format or version."""
        if state.get("format") != CACHE_FORMAT or state.get("version") != CACHE_VERSION:
            raise ValueError("not a crop cache of this version")
        return cls(**{k: state[k] for k in _TENSOR_FIELDS}, settings=dict(state["settings"]))


_TENSOR_FIELDS = (
    "crops",
    "labels",
    "target_ltrb",
    "boxes",
    "image_ids",
    "jittered",
    "frame_ids",
    "gt_boxes",
    "gt_classes",
    "gt_image_ids",
)


def part_of_objects(
    boxes: np.ndarray, gt_boxes: np.ndarray, gt_is_object: np.ndarray
) -> np.ndarray:
    """For each proposal box ``[N, 4]``, the index of the object GT box it is part of, or -1.

    A proposal is part of a GT box of an object class (``gt_is_object [M]``: a boat, jetski,
    buoy or life-saving appliance a head names) when its centre lies inside that box and the
    box is larger than the proposal on both sides: NWD, made for tiny targets, gives a 16-px
    proposal on a 120-px boat about 0.03, so without this the crops the RPN cuts on boats,
    which are what inference classifies there, would all be negatives and the head would
    learn a boat only from its centre's jittered crops. The smallest such box wins (a buoy
    beside a boat's hull)."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    g = np.asarray(gt_boxes, dtype=np.float64).reshape(-1, 4)
    out = np.full(len(b), -1, np.int64)
    if not len(b) or not len(g) or not np.any(gt_is_object):
        return out
    cx = (b[:, 0] + b[:, 2])[:, None] / 2
    cy = (b[:, 1] + b[:, 3])[:, None] / 2
    inside = (cx >= g[None, :, 0]) & (cx < g[None, :, 2]) & (cy >= g[None, :, 1])
    inside &= cy < g[None, :, 3]
    larger = ((g[None, :, 2] - g[None, :, 0]) > (b[:, 2] - b[:, 0])[:, None]) & (
        (g[None, :, 3] - g[None, :, 1]) > (b[:, 3] - b[:, 1])[:, None]
    )
    ok = inside & larger & np.asarray(gt_is_object, bool)[None, :]
    area = (g[:, 2] - g[:, 0]) * (g[:, 3] - g[:, 1])
    masked = np.where(ok, area[None, :], np.inf)
    best = np.argmin(masked, axis=1)
    has = np.isfinite(masked[np.arange(len(b)), best])
    out[has] = best[has]
    return out


def ltrb_targets(
    crop_boxes: np.ndarray, gt_boxes: np.ndarray, crop_size: int = CROP_SIZE
) -> np.ndarray:
    """GT edges as ``l, t, r, b`` distances from each crop box's centre, in crop pixels ``[N, 4]``.

    ``l = (cx - gx1) / sx``, ``t = (cy - gy1) / sy``, ``r = (gx2 - cx) / sx``,
    ``b = (gy2 - cy) / sy`` with ``sx, sy`` = crop box width, height / ``crop_size``.
    """
    c = np.asarray(crop_boxes, dtype=np.float64).reshape(-1, 4)
    g = np.asarray(gt_boxes, dtype=np.float64).reshape(-1, 4)
    sx = (c[:, 2] - c[:, 0]) / crop_size
    sy = (c[:, 3] - c[:, 1]) / crop_size
    cx = (c[:, 0] + c[:, 2]) / 2
    cy = (c[:, 1] + c[:, 3]) / 2
    return np.stack(
        [(cx - g[:, 0]) / sx, (cy - g[:, 1]) / sy, (g[:, 2] - cx) / sx, (g[:, 3] - cy) / sy], axis=1
    )


def polarity_near(motion: MotionMaps, centres: np.ndarray, box_size: float) -> np.ndarray:
    """RPN-like polarity ``[K]`` (1 = ON) for full-resolution points ``[K, 2]`` (x, y).

    ``L > 0`` at the largest ``R`` within the ``box_size`` square around each point, or at the
    point itself when ``R`` is zero there.
    """
    h, w = motion.response.shape
    ds = motion.ds
    out = np.zeros(len(centres), np.float32)
    for k, (x, y) in enumerate(np.asarray(centres, dtype=np.float64).reshape(-1, 2)):
        col, row = int(full_to_map_index(x, ds, w)), int(full_to_map_index(y, ds, h))
        half = max(int(np.ceil(box_size / (2 * ds))), 0)
        r0, c0 = max(row - half, 0), max(col - half, 0)
        window = motion.response[r0 : row + half + 1, c0 : col + half + 1]
        if window.size and window.max() > 0:
            i, j = np.unravel_index(int(np.argmax(window)), window.shape)
            row, col = r0 + int(i), c0 + int(j)
        out[k] = float(motion.temporal_change[row, col] > 0)
    return out


def _target_gt(dataset: VideoDataset, mapping: dict[int, int]) -> dict[int, tuple]:
    """Image id -> (xyxy ``[M, 4]``, class ``[M]``) of its target, non-crowd annotations."""
    result = {}
    for image_id, anns in dataset.annotations_by_image().items():
        chosen = [a for a in anns if not a.iscrowd and a.category_id in mapping]
        boxes = xywh_to_xyxy(np.array([a.bbox for a in chosen], np.float64).reshape(-1, 4))
        result[image_id] = (boxes, np.array([mapping[a.category_id] for a in chosen], np.int64))
    return result


def _object_boxes(dataset: VideoDataset, mapping: dict[int, int]) -> dict[int, np.ndarray]:
    """Image id -> xyxy ``[K, 4]`` of its non-crowd annotations of objects that are no search
    target (role ``object``, no head class); categories of unknown role (``ignored``) excluded."""
    objects = {
        c.id for c in dataset.categories if c.id not in mapping and role_of(c.name) == "object"
    }
    result = {}
    for image_id, anns in dataset.annotations_by_image().items():
        chosen = [a.bbox for a in anns if not a.iscrowd and a.category_id in objects]
        if chosen:
            result[image_id] = xywh_to_xyxy(np.array(chosen, np.float64).reshape(-1, 4))
    return result


def object_negative_boxes(
    object_boxes: np.ndarray,
    gt_boxes: np.ndarray,
    copies: int,
    settings: CropSettings,
    rng: np.random.Generator,
) -> np.ndarray:
    """``copies`` jittered squares per box of ``object_boxes`` ``[K, 4]`` (the jitter of the GT
    samples), less those within :data:`BACKGROUND_MAX_NWD` of a target box of ``gt_boxes``;
    ``[J, 4]`` xyxy."""
    if copies <= 0 or not len(object_boxes):
        return np.zeros((0, 4))
    boxes, _ = jitter_boxes(
        object_boxes,
        rng,
        copies,
        settings.jitter_scale,
        settings.jitter_shift,
        side=settings.box_size,
    )
    if len(gt_boxes):
        boxes = boxes[~assign_by_nwd(boxes, gt_boxes, BACKGROUND_MAX_NWD).positive]
    return boxes


#: Background negatives lie further than this NWD from every target GT box.
BACKGROUND_MAX_NWD = 0.1


def background_boxes(
    shape: tuple[int, int],
    gt_boxes: np.ndarray,
    count: int,
    side: float,
    rng: np.random.Generator,
    tries: int = 4,
) -> np.ndarray:
    """Up to ``count`` squares of ``side`` inside a frame of ``shape`` (height, width), each
    further than :data:`BACKGROUND_MAX_NWD` from every box of ``gt_boxes`` ``[M, 4]`` (module
    docstring); ``[K, 4]`` xyxy float64, ``K <= count``."""
    height, width = shape
    half = side / 2
    if count <= 0 or width < side or height < side:
        return np.zeros((0, 4))
    n = count * tries
    centres = np.stack(
        [rng.uniform(half, width - half, n), rng.uniform(half, height - half, n)], axis=1
    )
    boxes = np.concatenate([centres - half, centres + half], axis=1)
    near = assign_by_nwd(boxes, gt_boxes, BACKGROUND_MAX_NWD).positive
    return boxes[~near][:count]


def frame_runs(images: list[ImageRecord]) -> dict[int, tuple[bool, int]]:
    """Image id -> (whether it starts a run, the run's length) for one sequence's images in
    order. A run is a stretch of consecutive frame indices: motion is only defined within
    one. Images without a frame index (image sets) are runs of one: stills."""
    out: dict[int, tuple[bool, int]] = {}
    run: list[int] = []
    previous: int | None = None

    def close() -> None:
        for k, image_id in enumerate(run):
            out[image_id] = (k == 0, len(run))

    for image in images:
        index = image.frame_index
        if not run or index is None or previous is None or index != previous + 1:
            close()
            run = []
        run.append(image.id)
        previous = index
    close()
    return out


def _frame_samples(
    frame: np.ndarray,
    motion: MotionMaps,
    rpn: TTMRPN,
    gt: tuple,
    objects: np.ndarray,
    settings: CropSettings,
    rng: np.random.Generator,
) -> dict[str, Tensor]:
    """Crops, labels, targets and boxes of one sampled frame (RPN samples, jittered GT,
    background negatives, then object negatives around ``objects`` ``[K, 4]``)."""
    gt_boxes, gt_classes = gt
    proposals = rpn.propose(motion, chroma_if_wanted(frame, rpn.colour_slots > 0))
    assignment = assign_by_nwd(proposals.boxes, gt_boxes, settings.pos_nwd)
    pos = assignment.positive
    labels = np.full(len(proposals), -1, np.int64)
    labels[pos] = gt_classes[assignment.gt_index[pos]]
    rpn_targets = np.zeros((len(proposals), 4))
    rpn_targets[pos] = ltrb_targets(proposals.boxes[pos], gt_boxes[assignment.gt_index[pos]])
    if settings.object_parts and len(gt_classes):
        is_object = np.array([role_of(settings.classes[c]) != "person" for c in gt_classes])
        part_gt = part_of_objects(proposals.boxes, gt_boxes, is_object)
        part = (part_gt >= 0) & ~pos
        labels[part] = gt_classes[part_gt[part]]
        rpn_targets[part] = ltrb_targets(proposals.boxes[part], gt_boxes[part_gt[part]])
    boxes = [proposals.boxes.astype(np.float64)]
    targets = [rpn_targets]
    floor = settings.motion_floor
    crops = [
        motion_enhanced_crops(
            frame, motion, proposals.boxes, proposals.polarity, motion_floor=floor
        )
    ]
    all_labels = [labels]
    jittered = [np.zeros(len(proposals), bool)]
    samples = []  # (boxes, source GT) labelled with their GT: jittered, then context crops
    if settings.jitters_per_gt and len(gt_classes):
        samples.append(
            jitter_boxes(
                gt_boxes,
                rng,
                settings.jitters_per_gt,
                settings.jitter_scale,
                settings.jitter_shift,
                side=settings.box_size,
            )
        )
    if settings.object_context:
        samples.append(context_boxes(gt_boxes, rng, settings.object_context, settings.box_size))
    gt_polarity = None  # the RPN-like polarity at each GT, looked up once for every group
    for sboxes, src in samples:
        if not len(src):
            continue
        if gt_polarity is None:
            centres = (gt_boxes[:, :2] + gt_boxes[:, 2:]) / 2
            gt_polarity = polarity_near(motion, centres, settings.box_size)
        polarity = gt_polarity[src]
        boxes.append(sboxes)
        targets.append(ltrb_targets(sboxes, gt_boxes[src]))
        crops.append(
            motion_enhanced_crops(
                frame, motion, sboxes, polarity, sampling_ratio=1, motion_floor=floor
            )
        )
        all_labels.append(gt_classes[src])
        jittered.append(np.ones(len(src), bool))
    negatives = []
    if settings.background_negatives:
        negatives.append(
            background_boxes(
                frame.shape[:2], gt_boxes, settings.background_negatives, settings.box_size, rng
            )
        )
    if settings.object_negatives:
        negatives.append(
            object_negative_boxes(objects, gt_boxes, settings.object_negatives, settings, rng)
        )
    if settings.object_context:
        negatives.append(
            context_negative_boxes(
                frame.shape[:2], gt_boxes, settings.object_context, settings.box_size, rng
            )
        )
    for nboxes in negatives:
        if len(nboxes):
            centres = (nboxes[:, :2] + nboxes[:, 2:]) / 2
            polarity = polarity_near(motion, centres, settings.box_size)
            boxes.append(nboxes)
            targets.append(np.zeros((len(nboxes), 4)))
            crops.append(
                motion_enhanced_crops(
                    frame, motion, nboxes, polarity, sampling_ratio=1, motion_floor=floor
                )
            )
            all_labels.append(np.full(len(nboxes), -1, np.int64))
            jittered.append(np.zeros(len(nboxes), bool))
    dtype = getattr(torch, settings.crop_dtype)
    return {
        "crops": torch.from_numpy(np.concatenate(crops)).to(dtype),
        "labels": torch.from_numpy(np.concatenate(all_labels).astype(np.int64)),
        "target_ltrb": torch.from_numpy(np.concatenate(targets).astype(np.float32)),
        "boxes": torch.from_numpy(np.concatenate(boxes).astype(np.float32)),
        "jittered": torch.from_numpy(np.concatenate(jittered)),
    }


def build_crop_set(
    dataset: VideoDataset, settings: CropSettings, progress: bool = True, desc: str = "crops"
) -> CropSet:
    """Run vSTMD + TTM-RPN over every video of ``dataset`` and cut the crops (module docstring).

    Raises ``ValueError`` when no category is a head class or no crop could be cut.
    """
    from tqdm import tqdm

    settings.validate()
    mapping = target_category_map(dataset.categories, settings.classes)
    gt_by_image = _target_gt(dataset, mapping)
    objects_by_image = _object_boxes(dataset, mapping) if settings.object_negatives else {}
    rng = np.random.default_rng(settings.seed)
    parts: list[dict[str, Tensor]] = []
    frame_ids: list[int] = []
    counters: dict[str, int] = {}
    total = sum(len(sequence_images(dataset, v)) for v in sequence_ids(dataset))
    vstmd_kwargs = {} if settings.target_size is None else {"target_size": settings.target_size}
    n_crops = 0
    with tqdm(total=total, unit="frame", desc=desc, file=sys.stderr, disable=not progress) as bar:
        for video_id in sequence_ids(dataset):
            runs = frame_runs(sequence_images(dataset, video_id))
            position = 0
            for item in iter_sequence(dataset, video_id, counters):
                bar.update(1)
                starts, length = runs[item.image.id]
                still = length <= settings.warmup_frames  # too short a run to warm up on
                if starts or still:
                    vstmd = VSTMD(ds=settings.ds, **vstmd_kwargs)
                    rpn = TTMRPN(
                        topn=settings.topn,
                        box_size=settings.box_size,
                        colour_share=settings.colour_share,
                    )
                    position = 0
                # a fresh vSTMD takes its first frame as its state: a still shows no motion,
                # as a person who does not move under a hovering camera
                motion = vstmd.step(item.frame_bgr)
                offset = position - settings.warmup_frames
                position += 1
                if not still and (offset < 0 or offset % settings.frame_stride):
                    continue
                gt = gt_by_image.get(item.image.id, (np.zeros((0, 4)), np.zeros(0, np.int64)))
                objects = objects_by_image.get(item.image.id, np.zeros((0, 4)))
                part = _frame_samples(item.frame_bgr, motion, rpn, gt, objects, settings, rng)
                part["image_ids"] = torch.full(
                    (len(part["labels"]),), item.image.id, dtype=torch.int64
                )
                parts.append(part)
                frame_ids.append(item.image.id)
                n_crops += len(part["labels"])
                bar.set_postfix(crops=n_crops)
    if counters.get("skipped"):
        log.warning("%d frames could not be read and were skipped", counters["skipped"])
    if not n_crops:
        raise ValueError(
            f"no crops could be cut from {dataset.source_path} (no readable frames "
            f"past the {settings.warmup_frames} warm-up frames, no proposals and no "
            "target GT)"
        )
    gt_boxes, gt_classes, gt_images = [], [], []
    for image_id in frame_ids:
        boxes, classes = gt_by_image.get(image_id, (np.zeros((0, 4)), np.zeros(0, np.int64)))
        gt_boxes.append(boxes)
        gt_classes.append(classes)
        gt_images.append(np.full(len(classes), image_id, np.int64))

    def cat(key: str) -> Tensor:
        return torch.cat([p[key] for p in parts])

    return CropSet(
        crops=cat("crops"),
        labels=cat("labels"),
        target_ltrb=cat("target_ltrb"),
        boxes=cat("boxes"),
        image_ids=cat("image_ids"),
        jittered=cat("jittered"),
        frame_ids=torch.tensor(frame_ids, dtype=torch.int64),
        gt_boxes=torch.from_numpy(np.concatenate(gt_boxes).astype(np.float32)),
        gt_classes=torch.from_numpy(np.concatenate(gt_classes)),
        gt_image_ids=torch.from_numpy(np.concatenate(gt_images)),
        settings=settings.to_dict(),
        frames_unread=int(counters.get("skipped", 0)),
    )


#: Modules whose code decides the cached crops and labels.
RECIPE_MODULES = (
    "sarmission.perception.pyramid",
    "sarmission.perception.vstmd",
    "sarmission.perception.vstmd_params",
    "sarmission.perception.vstmd_kernels",
    "sarmission.perception.kernels",
    "sarmission.perception.ego_motion",
    "sarmission.perception.chroma",
    "sarmission.perception.rpn",
    "sarmission.perception.crops",
    "sarmission.perception.crop_kernels",
    "sarmission.boxes",
    "sarmission.training.sampling",
    "sarmission.training.dataset",
)


def source_fingerprint(modules: tuple[str, ...] = RECIPE_MODULES) -> str:
    """Hex digest of the source files of ``modules`` (imported by name), in the given order."""
    digest = hashlib.sha256()
    for name in modules:
        digest.update(name.encode())
        digest.update(Path(importlib.import_module(name).__file__).read_bytes())
    return digest.hexdigest()


def cache_key(annotations: Path, settings: CropSettings) -> str:
    """Hex key of (resolved annotation path, its size and mtime, cache version, the recipe's
    source fingerprint, settings)."""
    stat = annotations.stat()
    doc = {
        "path": str(annotations.resolve()),
        "size": stat.st_size,
        "mtime_ns": stat.st_mtime_ns,
        "version": CACHE_VERSION,
        "code": source_fingerprint(),
        "settings": settings.to_dict(),
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:20]


def load_crop_set(
    annotations: str | Path,
    settings: CropSettings,
    cache_dir: str | Path,
    progress: bool = True,
    desc: str = "crops",
) -> tuple[CropSet, bool]:
    """The crop set of an annotation file, from the cache when present, else built and cached.

    Returns ``(crop_set, from_cache)``. Raises ``OSError`` for a missing annotation file and
    ``ValueError`` for malformed annotations (:func:`read_coco_video`) or unusable data.
    """
    annotations = Path(annotations)
    if not annotations.is_file():
        raise FileNotFoundError(f"annotation file not found: {annotations}")
    cache = Path(cache_dir) / f"crops-{cache_key(annotations, settings)}.pt"
    if cache.is_file():
        try:
            return CropSet.from_state(
                torch.load(cache, map_location="cpu", weights_only=True)
            ), True
        except Exception as exc:  # a damaged cache is rebuilt, not fatal
            log.warning("ignoring unreadable crop cache %s (%s)", cache, exc)
    crop_set = build_crop_set(read_coco_video(annotations), settings, progress, desc)
    if crop_set.frames_unread:  # cached, the set would stand for the file once they are there
        log.warning(
            "crops of %s not cached: %d frames could not be read",
            annotations,
            crop_set.frames_unread,
        )
        return crop_set, False
    cache.parent.mkdir(parents=True, exist_ok=True)
    tmp = cache.with_name(cache.name + f".{os.getpid()}.tmp")
    torch.save(crop_set.to_state(), tmp)
    os.replace(tmp, cache)
    return crop_set, False
